"""Table encoder: the seed system's precomputed masks (primary + secondary view per subpixel)."""

from __future__ import annotations

import numpy as np

from ..profile import PanelProfile
from ..sampling import NO_VIEW, sampling_tables
from .common import finish


def encode_tables(views: np.ndarray, profile: PanelProfile) -> np.ndarray:
    """Encode ``views`` ``(N, H_v, W_v, 3)`` with cached :class:`~lenticalib.sampling.SamplingTables`.

    Vectorized numpy over the whole raster; memory is about 60 bytes per subpixel.
    """
    n, hv, wv, _ = views.shape
    tables = sampling_tables(profile, hv, wv)
    width, height = profile.width, profile.height
    # panel subpixel x_s = 3x + rho(c) holds channel c of pixel x
    x = np.arange(width)[:, None]
    rho = np.asarray(profile.rho)[None, :]
    xs = (3 * x + rho).reshape(-1)  # per (x, c) in output order
    chan = np.broadcast_to(np.arange(3)[None, :], (width, 3)).reshape(-1)
    cols, rows = tables.columns, tables.rows
    x0, x1, fx = cols.lo[xs], cols.hi[xs], cols.weight[xs]
    out = np.zeros((height, width * 3), dtype=np.float64)
    for table in (tables.primary, tables.secondary):
        view = table[:, xs].astype(np.int64)  # (H, 3W) in output order
        lit = view != NO_VIEW
        if not lit.any():
            continue
        v = np.where(lit, view, 0)
        y0 = rows.lo[:, None]
        y1 = rows.hi[:, None]
        fy = rows.weight[:, None]
        top = views[v, y0, x0, chan].astype(np.float64) * (1.0 - fx) + views[v, y0, x1, chan] * fx
        bottom = views[v, y1, x0, chan].astype(np.float64) * (1.0 - fx) + views[v, y1, x1, chan] * fx
        out += np.where(lit, top * (1.0 - fy) + bottom * fy, 0.0)
    return finish(out.reshape(height, width, 3), views.dtype)
