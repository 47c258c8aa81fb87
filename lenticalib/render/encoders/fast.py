"""Fast CPU encoder: routing computed on the fly in the canonical fixed-point arithmetic.

No per-subpixel maps are streamed: per row it needs the start phase ``Z0[y]`` and the bilinear
row taps; per output column one packed int32 (tap offset | x weight); per block of
``_simd.LANES`` output values a row of the per-profile lane table (:func:`_lane_table`).

* uint8 views (the live-video case) go through the explicitly vectorized block kernel of
  :mod:`._simd` (``_simd.LANES`` subpixels per step, one 64-bit gather each from a per-thread
  row-pair buffer), threads over bands of rows; weights are 11-bit fixed point, so values are
  within 1 LSB of the float64 reference.
* uint16 and float views, and layouts the block kernel cannot address (a view 1 pixel wide, a
  stack whose row-pair offsets pass 2**31, a panel row under ``LANES`` values), go through a
  scalar numba kernel with float64 weights and the reference's operations in the same order, so
  its values equal the reference's (tested).

Routing (which view) is identical to :func:`lenticalib.core.routing.view_map` in every case:
stripe panels, subpixel layouts (cell patterns), reversed views and dark bands (``period > N``).

What a subpixel layout costs.  The slot shifts of a layout live in the lane table, whose phase
offsets the kernel subtracts anyway: a layout with a cell pattern of ``rows x columns`` makes
the table ``rows x 3 columns`` blocks of ``LANES`` uint64 (at most 4 x 6 x 512 bytes = 12 KiB,
against 3 x 512 bytes for a stripe panel), built once per profile.  The kernel runs the same
instructions either way, so a cell layout encodes as fast as a stripe (``tools/bench_encode.py
--layout cells``; numbers in the README).
"""

from __future__ import annotations

import functools

import numba as nb
import numpy as np
from numba import prange

from ...core.profile import PanelProfile
from ...core.routing import RoutingPlan, routing_plan
from ..sampling import column_sampling, row_sampling
from . import _simd

_U64 = np.uint64
_MASK32 = np.uint64(0xFFFFFFFF)
_ONE = 1 << _simd.WEIGHT_BITS
_CHUNKS_PER_THREAD = 8  # row bands per thread (each starts with one extra row-pair build)


@nb.njit(parallel=True, cache=True, boundscheck=False)
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


@functools.lru_cache(maxsize=8)
def _u8_plan(profile: PanelProfile, view_height: int, view_width: int):
    """Per-profile constants of the block kernel (cached): per output value the left tap's byte in
    the row pair and its x weight (packed int32), the lane table, the row taps and y weights."""
    cols = column_sampling(profile, view_width)
    rows = row_sampling(profile, view_height)
    nsub = profile.subpixels_per_row
    o = np.arange(nsub)
    chan, x = o % 3, o // 3
    xs = 3 * x + np.asarray(profile.rho)[chan]  # subpixel position of output value o
    fxq = np.rint(cols.weight[xs] * _ONE).astype(np.uint32)
    pair_col = 2 * (cols.lo[xs].astype(np.uint32) * 3 + chan.astype(np.uint32))  # byte in the row pair
    tab = (pair_col | (fxq << _simd.COLUMN_BITS)).view(np.int32)
    lanes = _lane_table(routing_plan(profile), profile.rho)
    fyq = np.rint(rows.weight * _ONE).astype(np.int64)
    return tab, lanes, rows.lo.astype(np.int64), rows.hi.astype(np.int64), fyq


def _pair_stride(view_width: int) -> int:
    """Bytes per view in a thread's row-pair buffer: ``6 W_v`` rounded up to an odd number of
    64-byte lines, so that the same column of the N views falls in different cache sets."""
    lines = -(-6 * view_width // 64)
    return 64 * (lines | 1)


def _block_kernel_fits(views: np.ndarray, nsub: int) -> bool:
    n, _, wv, _ = views.shape
    return (views.dtype == np.uint8 and wv >= 2 and n * _pair_stride(wv) < 2**31
            and 6 * wv < (1 << _simd.COLUMN_BITS) and nsub >= _simd.LANES)


def encode_fast(views: np.ndarray, profile: PanelProfile, out: np.ndarray | None = None) -> np.ndarray:
    """Encode ``views`` ``(N, H_v, W_v, 3)`` into ``out`` ``(height, width, 3)`` (allocated if None)."""
    n, hv, wv, _ = views.shape
    if out is None:
        out = np.empty((profile.height, profile.width, 3), dtype=views.dtype)
    plan = routing_plan(profile)
    z0, k, dark = plan.z0, plan.k, plan.dark
    if _block_kernel_fits(views, profile.subpixels_per_row):
        tab, lanes, row_lo, row_hi, fyq = _u8_plan(profile, hv, wv)
        pow2 = n > 1 and (n & (n - 1)) == 0
        mode = 2 if dark is not None else (0 if pow2 else 1)
        shift = 64 - (n.bit_length() - 1)
        chunks = _CHUNKS_PER_THREAD * max(1, nb.get_num_threads())
        with nb.parallel_chunksize(1):  # chunks handed out one at a time: a busy core takes fewer
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
