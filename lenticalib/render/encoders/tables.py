"""Table encoder: a precomputed view table per subpixel (canonical routing) plus sample points."""

from __future__ import annotations

import numpy as np

from ...core.profile import PanelProfile
from ..compose.sampling import NO_VIEW, sampling_tables
from .common import finish

ROWS_PER_CHUNK = 64


def encode_tables(views: np.ndarray, profile: PanelProfile) -> np.ndarray:
    """Encode ``views`` ``(N, H_v, W_v, 3)`` with cached :class:`~lenticalib.render.compose.sampling.SamplingTables`.

    Returns the raster ``(height, width, 3)`` in the views' dtype.  Routing is the table's view
    (the canonical :func:`lenticalib.core.routing.view_map`); sampling is the reference encoder's
    float64 bilinear blend in the same order of operations, so the result equals
    :func:`~lenticalib.render.encoders.reference.encode_reference` bit for bit.  Vectorized numpy over
    chunks of ``ROWS_PER_CHUNK`` rows, so temporaries stay bounded.
    """
    n, hv, wv, _ = views.shape
    tables = sampling_tables(profile, hv, wv)
    width, height = profile.width, profile.height
    # panel subpixel x_s = 3x + rho(c) holds channel c of pixel x (rho = (0, 1, 2) with a subpixel layout)
    x = np.arange(width)[:, None]
    rho = np.asarray(profile.rho)[None, :]
    xs = (3 * x + rho).reshape(-1)  # per (x, c) in output order
    chan = np.broadcast_to(np.arange(3)[None, :], (width, 3)).reshape(-1)
    cols, rows = tables.columns, tables.rows
    x0, x1, fx = cols.lo[xs], cols.hi[xs], cols.weight[xs]
    out = np.empty((height, width, 3), dtype=views.dtype)
    for y_start in range(0, height, ROWS_PER_CHUNK):  # bounded temporaries: ~60 bytes per subpixel of a chunk
        rows_now = slice(y_start, min(height, y_start + ROWS_PER_CHUNK))
        y0 = rows.lo[rows_now, None]
        y1 = rows.hi[rows_now, None]
        fy = rows.weight[rows_now, None]
        view = tables.view[rows_now][:, xs].astype(np.int64)  # (rows, 3W) in output order
        lit = view != NO_VIEW
        v = np.where(lit, view, 0)
        top = views[v, y0, x0, chan].astype(np.float64) * (1.0 - fx) + views[v, y0, x1, chan] * fx
        bottom = views[v, y1, x0, chan].astype(np.float64) * (1.0 - fx) + views[v, y1, x1, chan] * fx
        acc = np.where(lit, top * (1.0 - fy) + bottom * fy, 0.0)
        out[rows_now] = finish(acc, views.dtype).reshape(-1, width, 3)
    return out
