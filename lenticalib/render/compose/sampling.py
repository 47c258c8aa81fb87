"""Sampling tables: where each panel subpixel samples its view, and which view(s) it shows.

Sample point ``u_p``.  Subpixel ``(x_s, y)`` covers ``[x_s, x_s + 1)`` in subpixel units; its
centre is at panel pixel coordinate ``((x_s + 0.5) / 3, y + 0.5)``.  With half-pixel-centre
convention (pixel ``k`` of the view covers ``[k, k + 1)``), the bilinear sample point in a view
of ``W_v x H_v`` pixels is

    u = (x_s + 0.5) / 3 * W_v / W - 0.5,      v = (y + 0.5) * H_v / H - 0.5,

clamped to the view (edge pixels are repeated).  The view is sampled between pixels
``x0, x0 + 1`` with weight ``fx = u - x0`` (and likewise in y); ``x0`` is kept at most
``W_v - 2`` so that ``x0 + 1`` is always a valid pixel.

Flips.  A profile with ``flip_image_x`` shows every view mirrored left-right: subpixel ``x_s``
samples the view where subpixel ``3 W - 1 - x_s`` samples it without the flip, the mirrored point
``u' = W_v - 1 - u``; with ``flip_image_y`` row ``y`` samples where row ``H - 1 - y`` does
(``v' = H_v - 1 - v``).  The flips change where a subpixel samples its view, never which view it
shows (the routing).

Subpixel layouts.  With a cell layout (``profile.subpixel_layout``) slot ``s`` of pixel ``x`` is
the channel R, G or B and samples at its nominal stripe point ``x_s = 3 x + s`` above, on the
row's centre, not at the channel's position inside its cell: the two differ by the channel's
offset from its stripe position (``|dx - (s - 1)/3|`` pixels across, ``|dy|`` down; a fraction of a
pixel on real panels), and one sample point per subpixel column and one per row keep the
sampling separable, as every encoder's tables are.  The routing does use the true position
(:func:`lenticalib.core.routing.view_map`).

Tables.  :class:`SamplingTables` holds, per subpixel, the view the canonical routing of
:mod:`lenticalib.core.routing` gives it (255 = none) and the bilinear geometry; built once per
(profile, view size) and cached.  The canonical routing lights at most one view per subpixel, so
one view table replaces the LentiAvatar system's primary/secondary pair (its second view only ever
came from float64 ties).
"""

from __future__ import annotations

import dataclasses
import functools

import numpy as np

from ...core.profile import PanelProfile
from ...core.routing import view_map

NO_VIEW = 255


@dataclasses.dataclass(frozen=True)
class AxisSampling:
    """Bilinear geometry along one axis: output index -> (lo, hi, weight of hi).

    ``lo``, ``hi`` int32 arrays of source pixel indices; ``weight`` float64 in [0, 1].
    """

    lo: np.ndarray
    hi: np.ndarray
    weight: np.ndarray


def axis_sampling(n_out: int, n_src: int, scale_num: float, scale_den: float, offset: float,
                  mirror: bool = False) -> AxisSampling:
    """Geometry for sample points ``u_k = (k + offset) * scale_num / scale_den - 0.5``, k < n_out.

    With ``mirror`` output index ``k`` takes the sample point of ``n_out - 1 - k`` (the source
    shown mirrored; ``u`` becomes ``n_src - 1 - u`` when ``scale_num / scale_den = n_src / n_out``
    and ``offset = 0.5``)."""
    k = np.arange(n_out, dtype=np.float64)
    if mirror:
        k = k[::-1]
    u = (k + offset) * (scale_num / scale_den) - 0.5
    u = np.clip(u, 0.0, n_src - 1.0)
    lo = np.floor(u).astype(np.int64)
    if n_src >= 2:
        lo = np.minimum(lo, n_src - 2)
        hi = lo + 1
    else:
        hi = lo
    weight = u - lo
    return AxisSampling(lo.astype(np.int32), hi.astype(np.int32), weight)


def column_sampling(profile: PanelProfile, view_width: int) -> AxisSampling:
    """Per subpixel column ``x_s`` (length ``3 * width``): its sample point in a view ``view_width`` wide
    (mirrored with ``profile.flip_image_x``; module docstring)."""
    # u = (x_s + 0.5) / 3 * W_v / W - 0.5
    return axis_sampling(profile.subpixels_per_row, view_width, view_width, 3.0 * profile.width, 0.5,
                         mirror=profile.flip_image_x)


def row_sampling(profile: PanelProfile, view_height: int) -> AxisSampling:
    """Per panel row ``y`` (length ``height``): its sample point in a view ``view_height`` tall
    (mirrored with ``profile.flip_image_y``; module docstring)."""
    return axis_sampling(profile.height, view_height, view_height, float(profile.height), 0.5,
                         mirror=profile.flip_image_y)


@dataclasses.dataclass(frozen=True)
class SamplingTables:
    """Precomputed view table and sample points for one profile and one view size.

    ``view``: uint8 ``(height, 3 * width)`` indexed ``[y, x_s]`` (panel subpixel order), the view
    :func:`lenticalib.core.routing.view_map` gives the subpixel, ``NO_VIEW`` (255) where none.
    ``columns`` has ``3 * width`` entries (per ``x_s``), ``rows`` has ``height`` entries.
    """

    profile: PanelProfile
    view_size: tuple[int, int]  # (H_v, W_v)
    view: np.ndarray
    columns: AxisSampling
    rows: AxisSampling


@functools.lru_cache(maxsize=4)
def _build(profile: PanelProfile, view_height: int, view_width: int) -> SamplingTables:
    canonical = view_map(profile)  # int16, -1 where dark; N <= 254 fits uint8 beside NO_VIEW
    view = np.where(canonical < 0, NO_VIEW, canonical).astype(np.uint8)
    view.setflags(write=False)
    return SamplingTables(profile, (view_height, view_width), view,
                          column_sampling(profile, view_width), row_sampling(profile, view_height))


def sampling_tables(profile: PanelProfile, view_height: int, view_width: int) -> SamplingTables:
    """View table (canonical routing) and bilinear geometry for ``profile`` and views of
    ``view_height x view_width`` pixels.  Built once per profile and view size, then cached."""
    return _build(profile, int(view_height), int(view_width))
