"""Sparse encoding tables of the torch encoder (:mod:`~lenticalib.render.encoders.torch_encoder`).

    tables = build_tables(profile, (H_v, W_v), device="cuda")   # TorchTables, built once on the device
    encoder = TorchEncoder(profile, (H_v, W_v), device="cuda", tables=tables)

Tables (:class:`TorchTables`, built by :func:`build_tables` with numpy on the host, then moved to
the device), per panel subpixel in output order ``[y, 3 x + c]`` (``c`` the colour channel; the
routing of a subpixel layout, reversed views and the image flips come with ``view_map`` and the
sample points of :mod:`lenticalib.render.compose.sampling`):

* ``primary_view`` uint8: the view the canonical routing (:func:`lenticalib.core.routing.view_map`)
  gives it, 255 where none (dark);
* ``primary_index`` int32: flat index, into the view tensor ``(N, H_v, W_v, 3)``, of the top-left
  bilinear tap of that view (0 where dark).  The four bilinear sample indices are
  ``primary_index + taps[k]`` with ``taps = (0, dx, dy, dx + dy)``: the sampling keeps the left /
  top tap at most ``W_v - 2`` / ``H_v - 2``, so the right / bottom tap is always one pixel further
  (``dx = 3``, ``dy = 3 W_v``; 0 for a view one pixel wide / tall).  One int32 per subpixel thus
  holds all four indices; :meth:`TorchTables.sample_indices` spells them out;
* ``secondary_view``, ``secondary_index``, ``secondary_weight`` (float32): a second view blended
  as ``(1 - w) V_primary + w V_secondary``, as in the LentiAvatar runtime's sparse tables.  The
  canonical routing lights at most one view per subpixel (docs/routing.md, the lattice argument),
  so for a profile the secondary weight is 0 everywhere and these tables are ``None`` (elided:
  nothing to read per frame).  They are filled only from an explicit two-view routing given to
  :func:`build_tables` (``lit=``, e.g. a crosstalk-compensating routing); a routing that puts more
  than two views on a subpixel is refused with a :class:`~lenticalib.core.errors.ConfigurationError`;
* bilinear weights, separable and exact: ``fx`` and ``1 - fx`` per output column (``3 W``
  float64), ``fy`` and ``1 - fy`` per row (float64), the values of
  :mod:`lenticalib.render.compose.sampling`.

Table memory for a 3840 x 2160 panel (24.9 M subpixels): 5 bytes per subpixel (int32 index +
uint8 view), 124.4 MB, plus 0.2 MB of weights; a two-view table adds 9 bytes per subpixel.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from ...core.errors import BackendUnavailableError, ConfigurationError, ImageError
from ...core.profile import PanelProfile
from ..compose.sampling import NO_VIEW, sampling_tables
from ..gpu.torch_devices import device_unavailable

try:
    import torch
except ImportError as exc:  # the registry passes this on as is
    raise BackendUnavailableError(f"the 'torch' encoder needs PyTorch, which does not import ({exc})",
                                  source="encoder", hint="pip install torch") from None

@dataclasses.dataclass(frozen=True, eq=False)
class TorchTables:
    """Sparse encoding tables of one profile and view size, on one device (module docstring).

    Per subpixel, shape ``(height, 3 * width)`` in output order ``[y, 3 x + c]``:
    ``primary_view`` uint8 (255 = dark), ``primary_index`` int32 (int64 for a view stack of 2**31
    values or more), and, only for a two-view routing, ``secondary_view`` uint8,
    ``secondary_index`` and ``secondary_weight`` float32 (0 where the subpixel has one view).
    ``taps``: offsets of the four bilinear taps from an index.  ``col_weight`` / ``col_weight0``:
    ``fx`` / ``1 - fx`` float64 ``(3 * width,)``; ``row_weight`` / ``row_weight0``: ``fy`` /
    ``1 - fy`` float64 ``(height, 1)``.
    """

    routing_key: tuple
    view_shape: tuple[int, int]
    views: int
    device: torch.device
    primary_view: torch.Tensor
    primary_index: torch.Tensor
    secondary_view: torch.Tensor | None
    secondary_index: torch.Tensor | None
    secondary_weight: torch.Tensor | None
    taps: tuple[int, int, int, int]
    col_weight: torch.Tensor
    col_weight0: torch.Tensor
    row_weight: torch.Tensor
    row_weight0: torch.Tensor
    has_dark: bool

    @property
    def nbytes(self) -> int:
        """Device memory the tables take, in bytes."""
        tensors = (self.primary_view, self.primary_index, self.secondary_view, self.secondary_index,
                   self.secondary_weight, self.col_weight, self.col_weight0, self.row_weight, self.row_weight0)
        return sum(t.numel() * t.element_size() for t in tensors if t is not None)

    def sample_indices(self, rows: slice = slice(None), secondary: bool = False) -> torch.Tensor:
        """The four bilinear sample indices (top-left, top-right, bottom-left, bottom-right) of the
        primary (or secondary) view, flat into the view tensor: shape ``(4, rows, 3 * width)``."""
        index = (self.secondary_index if secondary else self.primary_index)[rows]
        return torch.stack([index + tap for tap in self.taps])


def _single_step(hi: np.ndarray, lo: np.ndarray, axis: str) -> int:
    steps = np.unique(hi.astype(np.int64) - lo)
    if steps.size != 1:  # the sampling keeps lo <= n - 2: never happens
        raise ConfigurationError(f"bilinear taps along {axis} are not a constant step apart: {steps.tolist()}",
                                 source="sampling")
    return int(steps[0])


def _routing_tables(profile: PanelProfile, lit, secondary_weight):
    """``(primary, secondary, weight)`` in subpixel order ``[y, x_s]`` from an explicit routing."""
    shape = (profile.height, profile.subpixels_per_row)
    count, views = lit
    count, views = np.asarray(count), np.asarray(views)
    if count.shape != shape or views.ndim != 3 or views.shape[1:] != shape or views.shape[0] < 1:
        raise ConfigurationError(f"routing tables must be count {shape} and views (K, *{shape}), got "
                                 f"{count.shape} and {views.shape}", source="routing")
    over = count > 2
    if over.any():
        y, x_s = np.unravel_index(int(np.argmax(over)), shape)
        raise ConfigurationError(
            f"subpixel x_s={x_s}, y={y} is lit by {int(count[y, x_s])} views; the torch encoder's tables "
            "hold at most two per subpixel (a primary and a secondary)", source="routing")
    two = count == 2
    if two.any() and views.shape[0] < 2:
        raise ConfigurationError("the routing lights two views on a subpixel but lists one view per subpixel",
                                 source="routing")
    used = [(count >= 1, views[0])] + ([(two, views[1])] if two.any() else [])
    for mask, v in used:
        if mask.any() and int(v[mask].max()) >= profile.views:
            raise ConfigurationError(f"the routing names view {int(v[mask].max())}, the profile has "
                                     f"{profile.views}", source="routing")
    primary = np.where(count >= 1, views[0], NO_VIEW).astype(np.uint8)
    if not two.any():
        return primary, None, None
    if secondary_weight is None:
        y, x_s = np.unravel_index(int(np.argmax(two)), shape)
        raise ConfigurationError(f"subpixel x_s={x_s}, y={y} is lit by two views but no secondary_weight "
                                 "was given", source="routing")
    weight = np.broadcast_to(np.asarray(secondary_weight, dtype=np.float64), shape)
    weight = np.where(two, weight, 0.0).astype(np.float32)
    if not (np.all(weight >= 0.0) and np.all(weight <= 1.0)):
        raise ConfigurationError("secondary weights must lie in [0, 1]", source="routing")
    secondary = np.where(two, views[1], NO_VIEW).astype(np.uint8)
    return primary, secondary, weight


def _flat_index(view: np.ndarray, view_stride: int, row_off: np.ndarray, col_off: np.ndarray, dtype) -> np.ndarray:
    index = view.astype(dtype)
    index[view == NO_VIEW] = 0
    index *= view_stride
    index += row_off[:, None]
    index += col_off[None, :]
    return index


def build_tables(profile: PanelProfile, view_shape: tuple[int, int], device="cpu", *,
                 lit: tuple[np.ndarray, np.ndarray] | None = None,
                 secondary_weight: np.ndarray | float | None = None) -> TorchTables:
    """Build the encoding tables of ``profile`` for views of ``view_shape = (H_v, W_v)`` on ``device``.

    ARGUMENTS
    ``lit``: the routing, default the canonical one (:func:`~lenticalib.core.routing.view_map`,
    one view or none per subpixel).  Otherwise ``(count, views)`` in subpixel order ``[y, x_s]``,
    the form :func:`lenticalib.core.routing.rule_views` returns: ``count`` ``(height, 3 width)``
    how many views light each subpixel, ``views`` ``(K, height, 3 width)`` which, first one first.
    The first becomes the primary, the second (if any) the secondary, blended with
    ``secondary_weight`` (array ``(height, 3 width)`` or a scalar, in [0, 1]; required when a
    subpixel has two views).

    Raises ConfigurationError (one line, naming the first such subpixel) when ``lit`` puts more
    than two views on a subpixel.
    """
    hv, wv = int(view_shape[0]), int(view_shape[1])
    if hv < 1 or wv < 1:
        raise ImageError(f"views are empty: {hv}x{wv}", source="views")
    device = resolve_device(device)
    base = sampling_tables(profile, hv, wv)
    if lit is None:
        primary, secondary, weight = base.view, None, None
    else:
        primary, secondary, weight = _routing_tables(profile, lit, secondary_weight)
    width = profile.width
    xs = (3 * np.arange(width)[:, None] + np.asarray(profile.rho)[None, :]).reshape(-1)  # output order -> x_s
    chan = np.tile(np.arange(3), width)
    cols, rows = base.columns, base.rows
    view_stride = hv * wv * 3
    index_dtype = np.int32 if profile.views * view_stride < 2**31 else np.int64
    col_off = (cols.lo[xs].astype(index_dtype) * 3 + chan).astype(index_dtype)
    row_off = rows.lo.astype(index_dtype) * (wv * 3)
    dx = 3 * _single_step(cols.hi, cols.lo, "x")
    dy = wv * 3 * _single_step(rows.hi, rows.lo, "y")

    def put(array):
        return torch.from_numpy(np.ascontiguousarray(array)).to(device)

    primary = primary[:, xs]
    sec_view = sec_index = sec_weight = None
    if secondary is not None:
        secondary = secondary[:, xs]
        sec_view = put(secondary)
        sec_index = put(_flat_index(secondary, view_stride, row_off, col_off, index_dtype))
        sec_weight = put(weight[:, xs])
    fx, fy = cols.weight[xs], rows.weight[:, None]
    return TorchTables(
        routing_key=profile.routing_key(), view_shape=(hv, wv), views=profile.views, device=device,
        primary_view=put(primary), primary_index=put(_flat_index(primary, view_stride, row_off, col_off, index_dtype)),
        secondary_view=sec_view, secondary_index=sec_index, secondary_weight=sec_weight,
        taps=(0, dx, dy, dx + dy),
        col_weight=put(fx), col_weight0=put(1.0 - fx), row_weight=put(fy), row_weight0=put(1.0 - fy),
        has_dark=bool((primary == NO_VIEW).any()))

def resolve_device(device) -> torch.device:
    reason = device_unavailable(device)
    if reason is not None:
        raise ConfigurationError(reason, source="device",
                                 hint="use device='cpu', or a CUDA build of torch on a machine with a GPU")
    device = torch.device(device)
    if device.type == "cuda" and device.index is None:
        device = torch.device("cuda", torch.cuda.current_device())
    return device

