"""Torch encoder: the table-driven encoder of the LentiAvatar runtime on a torch device (CPU or CUDA).

    enc = TorchEncoder(profile, (H_v, W_v), device="cuda")   # tables built once, kept on the device
    raster = enc.encode(views)       # views: tensor (N, H_v, W_v, 3) already on that device
                                     # raster: tensor (height, width, 3) on the same device

The tables (:class:`~lenticalib.render.encoders.torch_tables.TorchTables`, built by
:func:`~lenticalib.render.encoders.torch_tables.build_tables`; both re-exported here) live in
:mod:`~lenticalib.render.encoders.torch_tables`, whose docstring gives their layout and memory.
This module holds the per-frame encoder, which only reads them.

Arithmetic.  With the default ``dtype=torch.float64`` the bilinear blend is the reference encoder's
float64 expression in the same order of operations (``top = a (1 - fx) + b fx``, likewise
``bottom``, then ``top (1 - fy) + bottom fy``, then half up), one elementwise torch op per
operation, so every intermediate is one IEEE-754 correctly rounded float64 operation and the result
equals :func:`~lenticalib.render.encoders.reference.encode_reference` bit for bit, for uint8,
uint16, float32 and float64 views (tested on CPU).  The same ops on CUDA are the same IEEE
operations (no op here is a fused multiply-add, a reduction or a transcendental), so the CUDA
result is identical by construction (not tested here: no GPU).  ``dtype=torch.float32`` (uint8,
uint16, float32 views) and ``dtype=torch.float16`` (uint8 views) trade that for speed: integer
results are within one level of the reference (tested).

``encode`` runs only torch operations on the views' device (gathers with ``index_select`` on the
flattened view tensor, elementwise ops with ``out=`` into a per-call workspace): no ``.cpu()``, no
``.item()``, no numpy, no host synchronisation.  It processes ``rows_per_chunk`` panel rows at a time
(the whole panel on CUDA, :data:`CPU_ROWS_PER_CHUNK` on CPU, where small chunks stay in cache).

:func:`encode_torch` is the registry's ``(views, profile) -> raster`` form for numpy views: it
wraps a CPU :class:`TorchEncoder` kept in a small LRU cache per (routing key, view size, device).
"""

from __future__ import annotations

import collections
import threading
import types
import warnings

import numpy as np

from ...core.errors import BackendUnavailableError, ConfigurationError, ImageError
from ...core.profile import PanelProfile
from ..compose.sampling import NO_VIEW

try:
    import torch
except ImportError as exc:  # the registry passes this on as is
    raise BackendUnavailableError(f"the 'torch' encoder needs PyTorch, which does not import ({exc})",
                                  source="encoder", hint="pip install torch") from None

from ..gpu.torch_devices import device_unavailable  # noqa: E402  (after the torch check)
from .torch_tables import TorchTables, build_tables, resolve_device  # noqa: E402

__all__ = ["CACHE_SIZE", "CPU_ROWS_PER_CHUNK", "TorchEncoder", "TorchTables", "build_tables", "cached_encoder",
           "clear_cache", "encode_torch"]

CPU_ROWS_PER_CHUNK = 16
CACHE_SIZE = 2  # encode_torch keeps the encoders (tables) of this many (profile, view size, device)

_COMPUTE_DTYPES = (torch.float64, torch.float32, torch.float16)
_VIEW_DTYPES = (torch.uint8, torch.uint16, torch.float32, torch.float64)
# views each reduced compute precision accepts (within one level of the reference)
_REDUCED_OK = {torch.float32: (torch.uint8, torch.uint16, torch.float32), torch.float16: (torch.uint8,)}


class TorchEncoder:
    """Encode views that are torch tensors on ``device`` into the panel raster, on that device.

    ARGUMENTS
    ``profile``; ``view_shape`` ``(H_v, W_v)`` of the views it will encode; ``device`` ``"cpu"``,
    ``"cuda"`` or ``"cuda:K"``; ``dtype`` the precision of the bilinear arithmetic:
    ``torch.float64`` (default, equals the reference encoder bit for bit), ``torch.float32`` or
    ``torch.float16`` (faster, integer results within one level); ``rows_per_chunk`` panel rows per
    pass (default: all on CUDA, :data:`CPU_ROWS_PER_CHUNK` on CPU); ``tables`` prebuilt
    :class:`TorchTables` (e.g. a two-view routing from :func:`build_tables`).

    The tables are built once, here.  ``encode`` allocates its workspace per call, so one encoder
    may be used from several threads.
    """

    def __init__(self, profile: PanelProfile, view_shape: tuple[int, int], device="cpu",
                 dtype: torch.dtype = torch.float64, *, rows_per_chunk: int | None = None,
                 tables: TorchTables | None = None):
        if dtype not in _COMPUTE_DTYPES:
            raise ConfigurationError(f"unsupported compute dtype {dtype}", source="dtype",
                                     hint="use torch.float64 (exact), torch.float32 or torch.float16")
        self.profile = profile
        self.view_shape = (int(view_shape[0]), int(view_shape[1]))
        if tables is None:
            tables = build_tables(profile, self.view_shape, device)
        elif tables.routing_key != profile.routing_key() or tables.view_shape != self.view_shape:
            raise ConfigurationError("the tables were built for another profile or view size", source="tables")
        self.tables = tables
        self.device = tables.device
        if resolve_device(device) != self.device:
            raise ConfigurationError(f"the tables are on {self.device}, the encoder was asked for {device}",
                                     source="tables")
        self.dtype = dtype
        height = profile.height
        self.rows_per_chunk = max(1, int(rows_per_chunk or (height if self.device.type == "cuda"
                                                            else CPU_ROWS_PER_CHUNK)))
        t = tables
        self._wx = (t.col_weight0.to(dtype), t.col_weight.to(dtype))
        self._wy = (t.row_weight0.to(dtype), t.row_weight.to(dtype))
        self._scale = _scale_fused if self.device.type == "cuda" else _scale_split

    @property
    def table_bytes(self) -> int:
        """Device memory of the tables (:attr:`TorchTables.nbytes`)."""
        return self.tables.nbytes

    def _check(self, views) -> None:
        n, (hv, wv) = self.profile.views, self.view_shape
        if not isinstance(views, torch.Tensor):
            raise ImageError(f"expected a torch tensor on {self.device}, got {type(views).__name__}", source="views",
                             hint="numpy views go through encode_torch or lenticalib.render.encoders.encode")
        if views.ndim != 4 or tuple(views.shape) != (n, hv, wv, 3):
            raise ImageError(f"expected shape ({n}, {hv}, {wv}, 3), got {tuple(views.shape)}", source="views",
                             hint="the encoder's tables are for this profile and view size")
        if views.dtype not in _VIEW_DTYPES:
            raise ImageError(f"unsupported pixel type {views.dtype}", source="views",
                             hint="use uint8, uint16, float32 or float64")
        if views.device != self.device:
            raise ImageError(f"views are on {views.device}, the encoder's tables on {self.device}", source="views",
                             hint="move the views to the encoder's device once, or build the encoder there")
        if self.dtype != torch.float64 and views.dtype not in _REDUCED_OK[self.dtype]:
            raise ConfigurationError(f"compute dtype {self.dtype} is not allowed for {views.dtype} views",
                                     source="dtype", hint="use torch.float64")

    def _output(self, views: torch.Tensor, out: torch.Tensor | None) -> torch.Tensor:
        shape = (self.profile.height, self.profile.width, 3)
        if out is None:
            return torch.empty(shape, dtype=views.dtype, device=self.device)
        if (tuple(out.shape) != shape or out.dtype != views.dtype or out.device != self.device
                or not out.is_contiguous()):
            raise ImageError(f"output buffer must be a contiguous {views.dtype} tensor {shape} on {self.device}, "
                             f"got {out.dtype} {tuple(out.shape)} on {out.device}", source="out")
        return out

    def encode(self, views: torch.Tensor, out: torch.Tensor | None = None) -> torch.Tensor:
        """Encode ``views`` ``(N, H_v, W_v, 3)`` (uint8, uint16, float32 or float64, on the encoder's
        device) into the raster ``(height, width, 3)``, views' dtype, same device (``out`` reused
        when given).  Torch operations on the device only (module docstring)."""
        self._check(views)
        raster = self._output(views, out)
        t, dtype = self.tables, self.dtype
        height, nsub = self.profile.height, self.profile.subpixels_per_row
        flat = views.reshape(-1)
        wide = views.dtype == torch.uint16
        if wide:  # gather the 16-bit values as int16 (every op supports it), widen to int32 below
            flat = flat.view(torch.int16)
        sources = [flat[tap:] for tap in t.taps]  # the four taps: one index table, shifted sources
        integer = not views.dtype.is_floating_point
        top = float(torch.iinfo(views.dtype).max) if integer else 0.0
        target = raster.view(height, nsub)
        if wide:
            target = target.view(torch.int16)
        rows = min(self.rows_per_chunk, height)
        work = _Workspace(rows, nsub, flat.dtype, dtype, self.device, t.secondary_index is not None)
        for start in range(0, height, rows):
            stop = min(height, start + rows)
            w = work.rows(stop - start)
            value = self._bilinear(sources, t.primary_index[start:stop], start, stop, w, w.acc, wide)
            if t.secondary_index is not None:
                second = self._bilinear(sources, t.secondary_index[start:stop], start, stop, w, w.acc2, wide)
                weight = t.secondary_weight[start:stop].to(dtype)
                value.mul_(1.0 - weight)
                second.mul_(weight)
                value.add_(second)
            if t.has_dark:
                value.masked_fill_(t.primary_view[start:stop] == NO_VIEW, 0.0)
            if integer:
                # half up: the value is >= 0, so the truncating cast of value + 0.5 is floor(value + 0.5);
                # in float64 the blend of values <= top stays below top + 0.5 (a few ulp above top at
                # most), so only the reduced precisions need the clip
                value.add_(0.5)
                if dtype != torch.float64:
                    value.clamp_(0.0, top)
                if wide:  # 0..65535 through int32 into the raster's int16 view (two's complement)
                    target[start:stop].copy_(value.to(torch.int32))
                    continue
            target[start:stop].copy_(value)
        return raster

    def _bilinear(self, sources, index, start, stop, w, acc, wide) -> torch.Tensor:
        """Bilinear samples at ``index`` (rows ``start:stop``), in the compute dtype, into ``acc``."""
        flat_index = index.reshape(-1)
        taps = []
        for source, buffer in zip(sources, w.taps):
            torch.index_select(source, 0, flat_index, out=buffer)
            if wide:
                taps.append(buffer.to(torch.int32).bitwise_and_(0xFFFF).view(index.shape))
            else:
                taps.append(buffer.view(index.shape))
        (wx0, wx1), (wy0, wy1) = self._wx, self._wy
        wy0, wy1 = wy0[start:stop], wy1[start:stop]
        upper, tmp, lower = acc, w.tmp, w.lower
        # reference: top = a (1 - fx) + b fx ; bottom = c (1 - fx) + d fx ; top (1 - fy) + bottom fy
        self._scale(taps[0], wx0, upper)
        self._scale(taps[1], wx1, tmp)
        upper.add_(tmp)
        self._scale(taps[2], wx0, lower)
        self._scale(taps[3], wx1, tmp)
        lower.add_(tmp)
        upper.mul_(wy0)
        lower.mul_(wy1)
        upper.add_(lower)
        return upper


def _scale_fused(tap, weight, out):
    """``out = tap * weight``: one kernel that converts ``tap`` on load (CUDA's mixed-dtype ops)."""
    torch.mul(tap, weight, out=out)


def _scale_split(tap, weight, out):
    """``out = tap * weight`` as an exact conversion, then the multiply: on CPU the mixed-dtype
    ``mul`` is several times slower than the two passes.  Same value either way."""
    out.copy_(tap)
    out.mul_(weight)


class _Workspace:
    """Per-call buffers for ``rows`` panel rows: four tap buffers and the blend's accumulators."""

    def __init__(self, rows, nsub, tap_dtype, dtype, device, two_views):
        self._rows, self._nsub = rows, nsub
        self._taps = [torch.empty(rows * nsub, dtype=tap_dtype, device=device) for _ in range(4)]
        self._acc = [torch.empty((rows, nsub), dtype=dtype, device=device) for _ in range(4 if two_views else 3)]

    def rows(self, rows: int) -> types.SimpleNamespace:
        """The buffers cut to ``rows`` rows (the last chunk may be shorter)."""
        acc = [b[:rows] for b in self._acc]
        return types.SimpleNamespace(taps=[b[:rows * self._nsub] for b in self._taps], acc=acc[0], tmp=acc[1],
                                     lower=acc[2], acc2=acc[3] if len(acc) > 3 else None)


# --- the registry's numpy form ----------------------------------------------------------------

_cache: collections.OrderedDict = collections.OrderedDict()
_cache_lock = threading.Lock()


def cached_encoder(profile: PanelProfile, view_shape: tuple[int, int], device="cpu") -> TorchEncoder:
    """A float64 (exact) :class:`TorchEncoder` from an LRU cache of :data:`CACHE_SIZE` entries
    keyed by ``(profile.routing_key(), view_shape, device)``."""
    key = (profile.routing_key(), int(view_shape[0]), int(view_shape[1]), str(resolve_device(device)))
    with _cache_lock:
        encoder = _cache.get(key)
        if encoder is not None:
            _cache.move_to_end(key)
            return encoder
    encoder = TorchEncoder(profile, view_shape, device)  # built outside the lock (seconds for 4K)
    with _cache_lock:
        _cache[key] = encoder
        _cache.move_to_end(key)
        while len(_cache) > CACHE_SIZE:
            _cache.popitem(last=False)
    return encoder


def clear_cache() -> None:
    """Drop the cached encoders (and their tables)."""
    with _cache_lock:
        _cache.clear()


def encode_torch(views: np.ndarray, profile: PanelProfile) -> np.ndarray:
    """Encode numpy ``views`` ``(N, H_v, W_v, 3)`` with a cached CPU :class:`TorchEncoder`.

    Returns the raster ``(height, width, 3)`` in the views' dtype, equal to the reference encoder's
    bit for bit.  The views are shared with torch, not copied.
    """
    views = np.ascontiguousarray(views)
    encoder = cached_encoder(profile, views.shape[1:3], "cpu")
    with warnings.catch_warnings():  # read-only views (broadcast, memory-mapped) are only read
        warnings.filterwarnings("ignore", message="The given NumPy array is not writable")
        tensor = torch.from_numpy(views)
    return encoder.encode(tensor).numpy()


def _unavailable(device=None) -> str | None:
    """What the registry asks (:mod:`lenticalib.core.plugins`): None, or why torch cannot use ``device`` here."""
    return None if device is None else device_unavailable(device)


encode_torch.unavailable = _unavailable
