"""Reference encoder: routing and sampling written out plainly, row by row.  The golden model.

    E(p) = V_{v(p)}(u_p)        (0 where no view lights p)

``v(p)`` is the view of subpixel ``p`` by the canonical routing,
:func:`lenticalib.core.routing.view_map` (the LentiAvatar routing rule in exact-tie-safe fixed point; the tests check
it against exact rational arithmetic), which routes a subpixel layout's slots by their true
positions and reverses the views where the profile says so; ``V_v(u_p)`` is view ``v`` bilinearly
sampled in float64 at the subpixel's sample point (see :mod:`lenticalib.render.compose.sampling`; mirrored
by the profile's image flips), in the subpixel's colour channel (slot ``s`` is channel ``s`` with a
subpixel layout), then rounded half up (integer views).  Slow (a few seconds for a 4K panel).
"""

from __future__ import annotations

import numpy as np

from ...core.profile import PanelProfile
from ...core.routing import view_map
from ..compose.sampling import column_sampling, row_sampling
from .common import finish


def encode_reference(views: np.ndarray, profile: PanelProfile) -> np.ndarray:
    """Encode ``views`` ``(N, H_v, W_v, 3)`` into the panel raster ``(height, width, 3)``, views' dtype."""
    n, hv, wv, _ = views.shape
    width, height = profile.width, profile.height
    cols = column_sampling(profile, wv)
    rows = row_sampling(profile, hv)
    channel_at = np.empty(3, dtype=np.int64)  # colour channel at slot 0, 1, 2 (R, G, B with a layout)
    for channel, position in enumerate(profile.rho):
        channel_at[position] = channel
    x_all, position = np.divmod(np.arange(3 * width), 3)  # pixel and position of every x_s
    c_all = channel_at[position]
    out = np.zeros((height, width, 3), dtype=np.float64)
    for y in range(height):
        v = view_map(profile, rows=slice(y, y + 1))[0].astype(np.int64)  # view per x_s, -1 = none
        lit = v >= 0
        x_s = np.nonzero(lit)[0]
        v, x, c = v[lit], x_all[lit], c_all[lit]
        y0, y1, fy = rows.lo[y], rows.hi[y], rows.weight[y]
        x0, x1, fx = cols.lo[x_s], cols.hi[x_s], cols.weight[x_s]
        top = views[v, y0, x0, c].astype(np.float64) * (1.0 - fx) + views[v, y0, x1, c] * fx
        bottom = views[v, y1, x0, c].astype(np.float64) * (1.0 - fx) + views[v, y1, x1, c] * fx
        out[y, x, c] = top * (1.0 - fy) + bottom * fy
    return finish(out, views.dtype)
