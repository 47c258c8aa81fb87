"""Reference encoder: the seed's formula, written out plainly.  The golden model for tests.

    E(p) = sum_i M_i(p) V_i(u_p)

``M_i(p)`` is 1 where view ``i`` lights subpixel ``p`` by the seed's rule (``x_s = floor(b)``,
``frac(b) < Delta/N``, ``b = 3 C_r y + s_i + m Delta``), evaluated in float64 for every view and
every ``m``; ``V_i(u_p)`` is view ``i`` bilinearly sampled at the subpixel's sample point (see
:mod:`lenticalib.sampling`), in the subpixel's colour channel.  Slow (seconds for a 4K panel).
"""

from __future__ import annotations

import numpy as np

from ..profile import PanelProfile
from ..sampling import column_sampling, row_sampling
from .common import finish


def encode_reference(views: np.ndarray, profile: PanelProfile) -> np.ndarray:
    """Encode ``views`` ``(N, H_v, W_v, 3)`` into the panel raster ``(height, width, 3)``."""
    n, hv, wv, _ = views.shape
    width, height = profile.width, profile.height
    nsub = 3 * width
    cols = column_sampling(profile, wv)
    rows = row_sampling(profile, hv)
    channel_at = np.empty(3, dtype=np.int64)  # colour channel at subpixel position 0, 1, 2
    for channel, position in enumerate(profile.rho):
        channel_at[position] = channel
    out = np.zeros((height, width, 3), dtype=np.float64)
    delta = profile.period
    ys = np.arange(height)
    for i in range(n):
        view = views[i].astype(np.float64)
        s_i = profile.offset - (delta / n) * (i - profile.reference_view)
        for y in ys:
            start = 3.0 * profile.slant * y + s_i
            m = np.arange(np.floor(-start / delta) - 1, np.ceil((nsub - start) / delta) + 2)
            b = start + m * delta
            x_s = np.floor(b)
            lit = ((b - x_s) < delta / n) & (x_s >= 0) & (x_s < nsub)
            x_s = x_s[lit].astype(np.int64)
            x, position = np.divmod(x_s, 3)
            c = channel_at[position]
            y0, y1, fy = rows.lo[y], rows.hi[y], rows.weight[y]
            x0, x1, fx = cols.lo[x_s], cols.hi[x_s], cols.weight[x_s]
            top = view[y0, x0, c] * (1.0 - fx) + view[y0, x1, c] * fx
            bottom = view[y1, x0, c] * (1.0 - fx) + view[y1, x1, c] * fx
            out[y, x, c] += top * (1.0 - fy) + bottom * fy
    return finish(out, views.dtype)
