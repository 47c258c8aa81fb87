"""Fast CPU encoder: canonical routing, vectorized numba kernels; three kernels, the fastest that applies.

* ``permute`` (uint8 views on CPUs with AVX-512 VBMI, up to 64 views, views at least 22 pixels
  wide, and at most ``_permute.MAX_WINDOWS`` permute windows per block: views up to the panel's
  width for 16 views or fewer, up to half of it for 32, up to a sixth of it for 33 to 64):
  :mod:`._permute`.  Per profile it stores the view of every output value (one byte each, from
  :func:`lenticalib.core.routing.view_map`:
  25 MiB at 3840x2160) and small block tables; per frame each thread transposes the source rows
  it needs (view-minor) and reads the four bilinear taps with byte permutes, no gather.
* ``gather`` (other uint8 cases the block kernel can address): :mod:`._simd`, routing computed on
  the fly from the start phase ``Z0[y]`` and a per-profile lane table (:func:`_lane_table`), one
  64-bit gather per output value from a per-thread row-pair buffer.  No per-subpixel map.
* ``scalar`` (uint16 and float views, and what the others cannot address: a view 1 pixel wide, a
  panel row under 64 values): float64 weights and the reference's operations in the same order,
  so its values equal the reference's (tested).

Both uint8 kernels use fixed-point weights and are within 1 LSB of the float64 reference; threads
run over bands of rows.  Routing (which view) is identical to
:func:`lenticalib.core.routing.view_map` in every kernel: stripe panels, subpixel layouts (cell
patterns), reversed views and dark bands (``period > N``).

What a subpixel layout costs.  ``permute`` reads the view of each value from its per-profile map,
so a layout costs nothing.  ``gather`` keeps the slot shifts in the lane table, whose phase
offsets it subtracts anyway: a cell pattern of ``rows x columns`` makes the table ``rows x 3
columns`` blocks of ``LANES`` uint64 (at most 12 KiB, against 1.5 KiB for a stripe panel), and
the kernel runs the same instructions.  ``tools/bench_encode.py --layout cells [--kernel K]``;
numbers in the README.
"""

from __future__ import annotations

import functools

import numba as nb
import numpy as np
from numba import prange

from ...core.jit import cached_njit
from ...core.profile import PanelProfile
from ...core.routing import RoutingPlan, routing_plan, view_map
from ..compose.sampling import column_sampling, row_sampling
from . import _permute, _simd

_U64 = np.uint64
_MASK32 = np.uint64(0xFFFFFFFF)
_ONE = 1 << _simd.WEIGHT_BITS
_CHUNKS_PER_THREAD = 8  # row bands per thread (each starts with one extra row-pair build)


@cached_njit(parallel=True, boundscheck=False)
def _encode_scalar(views, out, z0, k, shift, n_views, has_dark, threshold, rho, x_lo, x_hi, x_w,
                   y_lo, y_hi, y_w, is_int, top):  # pragma: no cover - compiled
    height, width = out.shape[0], out.shape[1]
    nv = _U64(n_views)
    shift_rows, shift_cols = shift.shape[0], shift.shape[1] // 3
    for y in prange(height):
        ya, yb, fy = y_lo[y], y_hi[y], y_w[y]
        srow = y % shift_rows
        for x in range(width):
            scol = 3 * (x % shift_cols)
            for c in range(3):
                xs = 3 * x + rho[c]
                z = z0[y] - _U64(xs) * k - shift[srow, scol + rho[c]]
                hi = (z >> _U64(32)) * nv
                lo = (z & _MASK32) * nv
                v = np.int64((hi + (lo >> _U64(32))) >> _U64(32))
                if has_dark and z * nv >= threshold:
                    out[y, x, c] = 0
                    continue
                xa, xb, fx = x_lo[xs], x_hi[xs], x_w[xs]
                upper = views[v, ya, xa, c] * (1.0 - fx) + views[v, ya, xb, c] * fx
                lower = views[v, yb, xa, c] * (1.0 - fx) + views[v, yb, xb, c] * fx
                value = upper * (1.0 - fy) + lower * fy
                if is_int:
                    value = min(np.floor(value + 0.5), top)
                out[y, x, c] = value


def _lane_table(plan: RoutingPlan, rho: tuple[int, int, int]) -> np.ndarray:
    """Per-lane phase offsets of the block kernel, uint64 ``(rows, 3 * columns, LANES)``.

    For a block of output values ``o0 .. o0 + LANES - 1`` of row ``y`` (output value ``o = 3 x + c``
    shows slot ``rho[c]``, at ``x_s = 3 x + rho[c]``), entry ``[y % rows, o0 % (3 * columns), lane]``
    is ``(x_s - o0) * K + shift[y % rows, 3 (x % columns) + rho[c]]`` (mod 2**64), so the kernel's
    ``(Z0[y] - o0 * K) - entry`` is the plan's phase ``Z0[y] - x_s * K - shift`` bit for bit.
    ``rows``, ``columns``: the plan's cell pattern (1 and 1 on a stripe panel).
    """
    rows, starts = plan.shift.shape
    lanes = _simd.LANES
    o = np.arange(starts)[:, None] + np.arange(lanes)[None, :]  # (start, lane) -> o - o0 + start
    chan = o % 3
    slot = np.asarray(rho, dtype=np.int64)[chan]
    offset = (o - chan + slot - np.arange(starts)[:, None]).astype(np.uint64)  # x_s - o0, >= 0
    column = 3 * ((o // 3) % (starts // 3)) + slot
    with np.errstate(over="ignore"):
        table = offset[None] * _U64(plan.k) + plan.shift[:, column]
    return np.ascontiguousarray(table, dtype=np.uint64)


def _output_slots(profile: PanelProfile) -> tuple[np.ndarray, np.ndarray]:
    """``(channel, slot)`` int arrays ``(3 W,)``: output value ``o = 3 x + c`` of a panel row is
    channel ``c`` and shows subpixel slot ``x_s = 3 x + rho[c]``."""
    o = np.arange(profile.subpixels_per_row)
    chan = o % 3
    return chan, 3 * (o // 3) + np.asarray(profile.rho)[chan]


@functools.lru_cache(maxsize=8)
def _u8_plan(profile: PanelProfile, view_height: int, view_width: int):
    """Per-profile constants of the block kernel (cached): per output value the left tap's byte in
    the row pair and its x weight (packed int32), the lane table, the row taps and y weights."""
    cols = column_sampling(profile, view_width)
    rows = row_sampling(profile, view_height)
    chan, xs = _output_slots(profile)
    fxq = np.rint(cols.weight[xs] * _ONE).astype(np.uint32)
    pair_col = 2 * (cols.lo[xs].astype(np.uint32) * 3 + chan.astype(np.uint32))  # byte in the row pair
    tab = (pair_col | (fxq << _simd.COLUMN_BITS)).view(np.int32)
    lanes = _lane_table(routing_plan(profile), profile.rho)
    fyq = np.rint(rows.weight * _ONE).astype(np.int64)
    return tab, lanes, rows.lo.astype(np.int64), rows.hi.astype(np.int64), fyq


@functools.lru_cache(maxsize=2)
def _permute_plan(profile: PanelProfile, view_height: int, view_width: int):
    """Per-profile constants of the permute kernel (cached; None when it cannot address them):
    the view of every output value (uint8 ``(height, 3 width)``, ``_permute.DARK`` where none),
    the row taps and y weights, and the block tables (:func:`._permute.block_tables`)."""
    vs = _permute.view_slots(profile.views)
    cols = column_sampling(profile, view_width)
    rows = row_sampling(profile, view_height)
    chan, xs = _output_slots(profile)
    s_left = 3 * cols.lo[xs].astype(np.int64) + chan
    s_right = 3 * cols.hi[xs].astype(np.int64) + chan
    starts, s_min_bytes, tables, windows = _permute.block_tables(s_left, s_right, cols.weight[xs], vs)
    if tables is None:
        return None
    views_u8 = np.empty((profile.height, xs.shape[0]), dtype=np.uint8)
    for start in range(0, profile.height, 128):  # bounded int16 temporaries
        chosen = view_map(profile, slice(start, start + 128))[:, xs]
        views_u8[start:start + 128] = np.where(chosen < 0, _permute.DARK, chosen)
    fyq = np.rint(rows.weight * (1 << _permute.Y_BITS)).astype(np.int64)
    t_bytes = max(3 * view_width * vs, int(s_min_bytes.max()) + _permute.WINDOW * windows) + 64
    return (views_u8, rows.lo.astype(np.int64), rows.hi.astype(np.int64), fyq, starts, s_min_bytes, tables,
            windows, vs, t_bytes)


def _permute_kernel_fits(views: np.ndarray, nsub: int) -> bool:
    n, _, wv, _ = views.shape
    return (views.dtype == np.uint8 and _permute.available() and _permute.view_slots(n) is not None
            and 3 * wv >= _permute.LANES and nsub >= _permute.LANES)


def _pair_stride(view_width: int) -> int:
    """Bytes per view in a thread's row-pair buffer: ``6 W_v`` rounded up to an odd number of
    64-byte lines, so that the same column of the N views falls in different cache sets."""
    lines = -(-6 * view_width // 64)
    return 64 * (lines | 1)


def _block_kernel_fits(views: np.ndarray, nsub: int) -> bool:
    n, _, wv, _ = views.shape
    return (views.dtype == np.uint8 and wv >= 2 and n * _pair_stride(wv) < 2**31
            and 6 * wv < (1 << _simd.COLUMN_BITS) and nsub >= _simd.LANES)


KERNELS = ("permute", "gather", "scalar")  # fastest first; the scalar kernel takes every case


def usable_kernels(views: np.ndarray, profile: PanelProfile) -> list[str]:
    """Names of the kernels (:data:`KERNELS`) that can encode ``views`` for ``profile`` here, fastest first."""
    names = []
    if _permute_kernel_fits(views, profile.subpixels_per_row) and _permute_plan(profile, *views.shape[1:3]):
        names.append("permute")
    if _block_kernel_fits(views, profile.subpixels_per_row):
        names.append("gather")
    return names + ["scalar"]


def encode_fast(views: np.ndarray, profile: PanelProfile, out: np.ndarray | None = None, *,
                kernel: str | None = None) -> np.ndarray:
    """Encode ``views`` ``(N, H_v, W_v, 3)`` into ``out`` ``(height, width, 3)`` (allocated if None).

    ``kernel``: None runs the fastest kernel that applies (:func:`usable_kernels`); a name from
    :data:`KERNELS` forces that one (ValueError when it cannot encode these views: for tests and
    benchmarks)."""
    n, hv, wv, _ = views.shape
    if out is None:
        out = np.empty((profile.height, profile.width, 3), dtype=views.dtype)
    usable = usable_kernels(views, profile)
    if kernel is not None and kernel not in usable:
        raise ValueError(f"kernel {kernel!r} cannot encode these views here (usable: {', '.join(usable)})")
    kernel = kernel or usable[0]
    chunks = _CHUNKS_PER_THREAD * max(1, nb.get_num_threads())
    if kernel == "permute":
        views_u8, row_lo, row_hi, fyq, starts, s_min_bytes, tables, windows, vs, t_bytes = _permute_plan(profile, hv, wv)
        with nb.parallel_chunksize(1):  # chunks handed out one at a time: a busy core takes fewer
            _permute.encode_u8_permute(views.reshape(-1), out.reshape(profile.height, -1), views_u8, row_lo, row_hi,
                                       fyq, starts, s_min_bytes, tables, windows, hv * wv * 3, wv * 3, n, vs,
                                       t_bytes, chunks)
        return out
    plan = routing_plan(profile)
    z0, k, dark = plan.z0, plan.k, plan.dark
    if kernel == "gather":
        tab, lanes, row_lo, row_hi, fyq = _u8_plan(profile, hv, wv)
        pow2 = n > 1 and (n & (n - 1)) == 0
        mode = 2 if dark is not None else (0 if pow2 else 1)
        shift = 64 - (n.bit_length() - 1)
        with nb.parallel_chunksize(1):
            _simd.encode_u8_blocks(views.reshape(-1), out.reshape(profile.height, -1), z0, _U64(k), n, shift,
                                   _U64(dark or 0), mode, tab, lanes, row_lo, row_hi, fyq, hv * wv * 3, wv * 3,
                                   _pair_stride(wv), chunks)
        return out
    cols = column_sampling(profile, wv)
    rows = row_sampling(profile, hv)
    is_int = bool(np.issubdtype(views.dtype, np.integer))
    top = float(np.iinfo(views.dtype).max) if is_int else 0.0
    _encode_scalar(views, out, z0, _U64(k), plan.shift, n, dark is not None, _U64(dark or 0),
                   np.asarray(profile.rho, dtype=np.int64), cols.lo, cols.hi, cols.weight,
                   rows.lo, rows.hi, rows.weight, is_int, top)
    return out
