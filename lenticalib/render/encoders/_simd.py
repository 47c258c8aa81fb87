"""Explicitly vectorized block kernel for the fast uint8 encoder (numba intrinsic, LLVM IR).

LLVM does not auto-vectorize byte gathers, and a scalar loop spends most of its time on the
four dependent loads per subpixel.  On the AMD EPYC (Zen 4) machines of this project a vector
gather costs about 0.5 ns per element whatever its width, so the kernel is built to need one
gathered element per output value:

* Row pair.  Each thread keeps a buffer of its current two source rows (the bilinear row taps of
  its output row), interleaved per byte for every view: ``pair[v][2 i + t]`` is byte ``i`` of the
  top (``t = 0``) or bottom (``t = 1``) row of view ``v``.  The 8 bytes at ``2 * col`` then hold
  both rows of the left tap (byte ``col``) and, 6 bytes on, of the right tap (``col + 3``, the
  same channel of the next pixel; views are interleaved RGB).  The buffer is rebuilt when the
  row taps change (every ``H / H_v`` output rows), and the next source row is prefetched a few
  cache lines per block meanwhile.

The intrinsic then processes ``LANES`` consecutive output values ``o0 ..`` of one panel row:

1. phase ``Z = (Z0[y] - o0 * K) - D[lane]`` (uint64, wrapping): ``D`` is the per-profile lane
   table of the row's class ``y % rows`` and the block's start ``o0 % (3 * columns)`` of the cell
   pattern, ``(x_s - o0) * K`` plus the slot shift, so ``Z = Z0[y] - x_s * K - shift`` exactly as
   :mod:`lenticalib.core.routing` defines it, without a vector multiply;
2. view ``floor(Z * N / 2**64)`` (the high 32-bit half shifted when N is a power of two, else
   32x32->64 products of the halves); optional dark test ``(Z * N mod 2**64) >= threshold``;
3. one ``llvm.masked.gather`` of 64-bit words from the row pair (base + 32-bit offsets), and a
   byte shuffle that keeps the four taps;
4. fixed-point bilinear blend with 11-bit weights, rounded, stored as ``LANES`` bytes.

The IR is generic: on CPUs without AVX-512/AVX2 gathers LLVM lowers it to scalar loads.
"""

from __future__ import annotations

import llvmlite.ir as ir
import numpy as np
from numba import prange
from numba import types
from numba.core import cgutils
from numba.extending import intrinsic

from ...core.jit import cached_njit

LANES = 64
WEIGHT_BITS = 11  # bilinear weights are integers in [0, 2**WEIGHT_BITS]
COLUMN_BITS = 20  # packed column table: low 20 bits the left tap's byte in the row pair, high 12 bits weight

_I1, _I8, _I32, _I64 = ir.IntType(1), ir.IntType(8), ir.IntType(32), ir.IntType(64)
_V1, _V8, _V32, _V64 = (ir.VectorType(t, LANES) for t in (_I1, _I8, _I32, _I64))
_VPTR = ir.VectorType(ir.PointerType(), LANES)


def splat(builder, value, vty):
    """LLVM IR: the scalar ``value`` broadcast to every lane of vector type ``vty`` (shared with _permute)."""
    first = builder.insert_element(ir.Constant(vty, ir.Undefined), value, ir.Constant(_I32, 0))
    return builder.shuffle_vector(first, ir.Constant(vty, ir.Undefined),
                                  ir.Constant(ir.VectorType(_I32, vty.count), [0] * vty.count))


def vector_constant(vty, value):
    """LLVM IR: a constant of vector type ``vty`` with ``value`` in every lane (shared with _permute)."""
    return ir.Constant(vty, [value] * vty.count)


def _view_index(builder, z, n_or_shift, pow2, dark):
    """``(view, frac)``: ``floor(Z * N / 2**64)`` as i32 lanes and, when ``dark``, ``Z * N mod 2**64``.

    N a power of two from 2 to 2**32 (``n_or_shift = 64 - log2 N``, 32 to 63): the view is the top
    bits of the high 32-bit half of Z.  Otherwise Z is split in 32-bit halves and multiplied
    by N (< 2**32) in 32x32->64 products, which also give the fraction without a 64x64 multiply."""
    if pow2:
        halves = builder.bitcast(z, ir.VectorType(_I32, 2 * LANES))
        high = builder.shuffle_vector(halves, ir.Constant(halves.type, ir.Undefined),
                                      ir.Constant(_V32, [2 * lane + 1 for lane in range(LANES)]))
        return builder.lshr(high, splat(builder, builder.trunc(builder.sub(n_or_shift, ir.Constant(_I64, 32)), _I32), _V32)), None
    n = splat(builder, builder.zext(builder.trunc(n_or_shift, _I32), _I64), _V64)
    c32 = vector_constant(_V64, 32)
    hi = builder.mul(builder.lshr(z, c32), n)
    lo = builder.mul(builder.and_(z, vector_constant(_V64, 0xFFFFFFFF)), n)
    view = builder.trunc(builder.lshr(builder.add(hi, builder.lshr(lo, c32)), c32), _V32)
    return view, (builder.add(lo, builder.shl(hi, c32)) if dark else None)


def _make_codegen(pow2: bool, dark: bool):
    def codegen(context, builder, signature, args):
        base, tab_ptr, lane_ptr, out_ptr, z_block, n_or_shift, threshold, stride, fy = args
        lane = builder.load(builder.inttoptr(lane_ptr, _V64.as_pointer()), align=8)
        z = builder.sub(splat(builder, z_block, _V64), lane)
        view, frac = _view_index(builder, z, n_or_shift, pow2, dark)
        tab = builder.load(builder.inttoptr(tab_ptr, _V32.as_pointer()), align=4)
        col = builder.and_(tab, vector_constant(_V32, (1 << COLUMN_BITS) - 1))
        fx = builder.lshr(tab, vector_constant(_V32, COLUMN_BITS))
        offsets = builder.add(builder.mul(view, splat(builder, builder.trunc(stride, _I32), _V32)), col)
        gather = cgutils.get_or_insert_function(
            builder.module, ir.FunctionType(_V64, [_VPTR, _I32, _V1, _V64]),
            f"llvm.masked.gather.v{LANES}i64.v{LANES}p0")
        # base + 32-bit offsets: LLVM emits the 32-bit-index gather, not the 64-bit-index form
        ptrs = builder.gep(splat(builder, builder.inttoptr(base, ir.PointerType()), _VPTR), [offsets],
                           source_etype=_I8)
        taps = builder.call(gather, [ptrs, ir.Constant(_I32, 1), vector_constant(_V1, 1), ir.Constant(_V64, ir.Undefined)])
        # the 8 bytes hold (top, bottom) of the left tap and, 6 bytes on, of the right tap: keep
        # bytes 0, 6 (top row) and 1, 7 (bottom row) of each, one byte shuffle per output register
        as_bytes = builder.bitcast(taps, ir.VectorType(_I8, 8 * LANES))
        picks = [8 * lane + b for lane in range(LANES) for b in (0, 6, 1, 7)]
        words = builder.bitcast(builder.shuffle_vector(as_bytes, ir.Constant(as_bytes.type, ir.Undefined),
                                                       ir.Constant(ir.VectorType(_I32, 4 * LANES), picks)), _V32)
        one = 1 << WEIGHT_BITS
        gx = builder.sub(vector_constant(_V32, one), fx)
        low_byte = vector_constant(_V32, 255)

        def blend_row(shift):
            left = builder.and_(builder.lshr(words, vector_constant(_V32, shift)) if shift else words, low_byte)
            right = builder.and_(builder.lshr(words, vector_constant(_V32, shift + 8)), low_byte)
            return builder.add(builder.mul(left, gx), builder.mul(right, fx))

        fy32 = builder.trunc(fy, _I32)
        acc = builder.add(
            builder.add(builder.mul(blend_row(0), splat(builder, builder.sub(ir.Constant(_I32, one), fy32), _V32)),
                        builder.mul(blend_row(16), splat(builder, fy32, _V32))),
            vector_constant(_V32, 1 << (2 * WEIGHT_BITS - 1)))
        value = builder.lshr(acc, vector_constant(_V32, 2 * WEIGHT_BITS))
        if dark:
            lit = builder.icmp_unsigned("<", frac, splat(builder, threshold, _V64))
            value = builder.select(lit, value, vector_constant(_V32, 0))
        builder.store(builder.trunc(value, _V8), builder.inttoptr(out_ptr, _V8.as_pointer()), align=1)
        return context.get_dummy_value()

    return codegen


_SIG = types.void(types.intp, types.intp, types.intp, types.intp, types.uint64,
                  types.uint64, types.uint64, types.int64, types.int64)


def _declare(pow2: bool, dark: bool):
    def block(typingctx, base, tab_ptr, lane_ptr, out_ptr, z_block, n_or_shift, threshold, stride, fy):
        return _SIG, _make_codegen(pow2, dark)

    block.__name__ = f"block_{'pow2' if pow2 else 'general'}{'_dark' if dark else ''}"
    return intrinsic(block)


block_pow2 = _declare(True, False)
block_general = _declare(False, False)
block_general_dark = _declare(False, True)


@intrinsic
def prefetch(typingctx, address):
    """Hint the CPU to bring the cache line at ``address`` (an integer) into the cache (no fault)."""
    def codegen(context, builder, signature, args):
        fn = cgutils.get_or_insert_function(builder.module, ir.FunctionType(ir.VoidType(), [ir.PointerType(), _I32, _I32, _I32]),
                                            "llvm.prefetch.p0")
        builder.call(fn, [builder.inttoptr(args[0], ir.PointerType()), ir.Constant(_I32, 0), ir.Constant(_I32, 3),
                          ir.Constant(_I32, 1)])
        return context.get_dummy_value()

    return types.void(types.intp), codegen


@cached_njit(inline="always")
def prefetch_row_lines(row, view, line, count, n_views, lines, plane):  # pragma: no cover - compiled
    """Prefetch the next ``count`` cache lines of a source row of the N views: the row's address in
    view 0 ``row``, ``lines`` lines per view row, views ``plane`` bytes apart, going on from line
    ``line`` of view ``view`` (nothing once ``view == n_views``).  Returns the new ``(view, line)``."""
    for _ in range(count):
        if view < n_views:
            prefetch(row + view * plane + 64 * line)
            line += 1
            if line == lines:
                line = 0
                view += 1
    return view, line


@cached_njit(inline="always")
def next_source_row(row_lo, row_hi, y, end, top, bottom):  # pragma: no cover - compiled
    """The first output row after ``y`` (before ``end``) whose bilinear row taps are not
    ``(top, bottom)``, and the source row it adds (any direction: image flips); ``(end, -1)``
    when the band has no such row."""
    ahead = y + 1
    while ahead < end and row_lo[ahead] == top and row_hi[ahead] == bottom:
        ahead += 1
    if ahead == end:
        return end, -1
    new_row = row_hi[ahead]
    if new_row == top or new_row == bottom:
        new_row = row_lo[ahead]
    return ahead, new_row


# The row kernel lives here, next to the intrinsics it inlines: numba's on-disk cache is keyed on
# the file that defines a jitted function, so keeping both in one file invalidates them together.
_U64 = np.uint64


@cached_njit(boundscheck=False)
def interleave_rows(pair, flat, n_views, plane, top, bottom, row_bytes, stride):  # pragma: no cover - compiled
    """Fill ``pair`` (uint16, ``n_views * stride // 2``): per view, byte ``i`` of source row ``top``
    and of ``bottom`` side by side (``pair[v * stride // 2 + i] = top_i | bottom_i << 8``)."""
    half = stride // 2
    for v in range(n_views):
        upper = flat[v * plane + top:v * plane + top + row_bytes]  # slices: the loop index is >= 0, no
        lower = flat[v * plane + bottom:v * plane + bottom + row_bytes]  # wraparound test, so it vectorizes
        dest = pair[v * half:v * half + row_bytes]
        for i in range(row_bytes):
            dest[i] = np.uint16(upper[i]) | (np.uint16(lower[i]) << np.uint16(8))


@cached_njit(parallel=True, boundscheck=False)
def encode_u8_blocks(flat, out2d, z0, k, n_views, shift, threshold, mode, tab, lane_table,
                     row_lo, row_hi, fyq, plane, row_bytes, stride, n_chunks):  # pragma: no cover - compiled
    height = out2d.shape[0]
    length = out2d.shape[1]
    rows = plane // row_bytes
    classes, starts, lanes = lane_table.shape
    n_blocks = (length + lanes - 1) // lanes
    block_lanes = np.empty(n_blocks, dtype=np.int64)  # byte offset of each block's start in a lane-table row
    for blk in range(n_blocks):
        block_lanes[blk] = 8 * lanes * (min(blk * lanes, length - lanes) % starts)
    ptab = tab.ctypes.data
    lane_ptr = lane_table.ctypes.data
    per_chunk = (height + n_chunks - 1) // n_chunks
    nv = _U64(n_views)
    # While a pair is in use, the next source row is prefetched a few cache lines per block, spread
    # over the output rows that use the pair (the N view planes are too many streams for the
    # hardware prefetcher).
    pf_lines = (row_bytes + 63) // 64
    pf_per_block = n_views * pf_lines // (n_blocks * max(1, height // rows)) + 1
    src = flat.ctypes.data
    for chunk in prange(n_chunks):
        pair = np.empty(n_views * stride // 2 + 4, dtype=np.uint16)  # this thread's row pair
        base = pair.ctypes.data
        have_top, have_bottom = -1, -1
        pf_view, pf_line, pf_row = n_views, 0, 0
        end = min(height, (chunk + 1) * per_chunk)
        for y in range(chunk * per_chunk, end):
            if row_lo[y] != have_top or row_hi[y] != have_bottom:
                have_top, have_bottom = row_lo[y], row_hi[y]
                interleave_rows(pair, flat, n_views, plane, have_top * row_bytes, have_bottom * row_bytes,
                                row_bytes, stride)
                # the source row the next pair of this band adds
                _, new_row = next_source_row(row_lo, row_hi, y, end, have_top, have_bottom)
                pf_view, pf_line = (n_views if new_row < 0 else 0), 0
                if new_row >= 0:
                    pf_row = src + new_row * row_bytes
            z = z0[y]
            fy = fyq[y]
            po = out2d[y].ctypes.data
            row_lanes = lane_ptr + 8 * lanes * starts * (y % classes)
            for blk in range(n_blocks):
                o0 = min(blk * lanes, length - lanes)  # last block overlaps: recomputes, same values
                lp = row_lanes + block_lanes[blk]
                zb = z - _U64(o0) * k
                pf_view, pf_line = prefetch_row_lines(pf_row, pf_view, pf_line, pf_per_block, n_views, pf_lines, plane)
                if mode == 0:
                    block_pow2(base, ptab + 4 * o0, lp, po + o0, zb, _U64(shift), _U64(0), stride, fy)
                elif mode == 1:
                    block_general(base, ptab + 4 * o0, lp, po + o0, zb, nv, _U64(0), stride, fy)
                else:
                    block_general_dark(base, ptab + 4 * o0, lp, po + o0, zb, nv, threshold, stride, fy)
