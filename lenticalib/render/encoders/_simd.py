"""Explicitly vectorized block kernel for the fast uint8 encoder (numba intrinsic, LLVM IR).

LLVM does not auto-vectorize byte gathers, and a scalar loop spends most of its time on the
four dependent loads per subpixel.  This intrinsic processes ``LANES`` consecutive output values
of one panel row at once:

1. phase ``Z = (Z0[y] - o0 * K) - D[lane]`` (uint64, wrapping): ``D`` is the per-profile lane
   table of the row's class ``y % rows`` and the block's start ``o0 % (3 * columns)`` of the cell
   pattern, ``(x_s - o0) * K`` plus the slot shift, so ``Z = Z0[y] - x_s * K - shift`` exactly as
   :mod:`lenticalib.core.routing` defines it, without a vector multiply;
2. view ``floor(Z * N / 2**64)`` (a shift when N is a power of two, else a 64x32 split multiply);
   optional dark test ``(Z * N mod 2**64) >= threshold``;
3. two ``llvm.masked.gather`` of 32-bit words, one per source row: the word at the left
   neighbour's byte holds that byte and, 3 bytes on, the right neighbour of the same channel
   (views are interleaved RGB), so one gather fetches both horizontal taps;
4. fixed-point bilinear blend with 11-bit weights, rounded, stored as ``LANES`` bytes.

The IR is generic: on CPUs without AVX-512/AVX2 gathers LLVM lowers it to scalar loads.
"""

from __future__ import annotations

import llvmlite.ir as ir
import numba as nb
import numpy as np
from numba import prange
from numba import types
from numba.core import cgutils
from numba.extending import intrinsic

LANES = 64
WEIGHT_BITS = 11  # bilinear weights are integers in [0, 2**WEIGHT_BITS]
COLUMN_BITS = 20  # packed column table: low 20 bits byte offset, high 12 bits weight

_I1, _I8, _I32, _I64 = ir.IntType(1), ir.IntType(8), ir.IntType(32), ir.IntType(64)
_V1, _V8, _V32, _V64 = (ir.VectorType(t, LANES) for t in (_I1, _I8, _I32, _I64))
_VPTR = ir.VectorType(ir.PointerType(), LANES)


def _splat(builder, value, vty):
    first = builder.insert_element(ir.Constant(vty, ir.Undefined), value, ir.Constant(_I32, 0))
    return builder.shuffle_vector(first, ir.Constant(vty, ir.Undefined),
                                  ir.Constant(ir.VectorType(_I32, vty.count), [0] * vty.count))


def _const(vty, value):
    return ir.Constant(vty, [value] * vty.count)


def _view_index(builder, z, n_or_shift, pow2):
    if pow2:
        return builder.lshr(z, _splat(builder, n_or_shift, _V64))
    n = _splat(builder, n_or_shift, _V64)
    c32 = _const(_V64, 32)
    hi = builder.mul(builder.lshr(z, c32), n)
    lo = builder.mul(builder.and_(z, _const(_V64, 0xFFFFFFFF)), n)
    return builder.lshr(builder.add(hi, builder.lshr(lo, c32)), c32)


def _make_codegen(pow2: bool, dark: bool):
    def codegen(context, builder, signature, args):
        (base, tab_ptr, lane_ptr, out_ptr, z_block, n_or_shift, n_views, threshold,
         plane, r0, dr, fy) = args
        lane = builder.load(builder.inttoptr(lane_ptr, _V64.as_pointer()), align=8)
        z = builder.sub(_splat(builder, z_block, _V64), lane)
        view = builder.trunc(_view_index(builder, z, n_or_shift, pow2), _V32)
        tab = builder.load(builder.inttoptr(tab_ptr, _V32.as_pointer()), align=4)
        col = builder.and_(tab, _const(_V32, (1 << COLUMN_BITS) - 1))
        fx = builder.lshr(tab, _const(_V32, COLUMN_BITS))
        addr0 = builder.add(builder.add(builder.mul(view, _splat(builder, builder.trunc(plane, _I32), _V32)), col),
                            _splat(builder, builder.trunc(r0, _I32), _V32))
        gather = cgutils.get_or_insert_function(
            builder.module, ir.FunctionType(_V32, [_VPTR, _I32, _V1, _V32]),
            f"llvm.masked.gather.v{LANES}i32.v{LANES}p0")
        base_v = _splat(builder, builder.inttoptr(base, ir.PointerType()), _VPTR)
        mask = _const(_V1, 1)

        def load_words(offsets):  # base + 32-bit offsets: vpgatherdd, not the 64-bit-index form
            ptrs = builder.gep(base_v, [offsets], source_etype=_I8)
            return builder.call(gather, [ptrs, ir.Constant(_I32, 1), mask, ir.Constant(_V32, ir.Undefined)])

        top_words = load_words(addr0)
        bottom_words = load_words(builder.add(addr0, _splat(builder, builder.trunc(dr, _I32), _V32)))
        one = 1 << WEIGHT_BITS
        gx = builder.sub(_const(_V32, one), fx)
        low_byte, shift24 = _const(_V32, 255), _const(_V32, 24)

        def blend_row(words):
            return builder.add(builder.mul(builder.and_(words, low_byte), gx),
                               builder.mul(builder.lshr(words, shift24), fx))

        fy32 = builder.trunc(fy, _I32)
        acc = builder.add(
            builder.add(builder.mul(blend_row(top_words), _splat(builder, builder.sub(ir.Constant(_I32, one), fy32), _V32)),
                        builder.mul(blend_row(bottom_words), _splat(builder, fy32, _V32))),
            _const(_V32, 1 << (2 * WEIGHT_BITS - 1)))
        value = builder.lshr(acc, _const(_V32, 2 * WEIGHT_BITS))
        if dark:
            frac = builder.mul(z, _splat(builder, n_views, _V64))
            lit = builder.icmp_unsigned("<", frac, _splat(builder, threshold, _V64))
            value = builder.select(lit, value, _const(_V32, 0))
        builder.store(builder.trunc(value, _V8), builder.inttoptr(out_ptr, _V8.as_pointer()), align=1)
        return context.get_dummy_value()

    return codegen


_SIG = types.void(types.intp, types.intp, types.intp, types.intp, types.uint64,
                  types.uint64, types.uint64, types.uint64, types.int64, types.int64, types.int64, types.int64)


def _declare(pow2: bool, dark: bool):
    def block(typingctx, base, tab_ptr, lane_ptr, out_ptr, z_block, n_or_shift, n_views, threshold,
              plane, r0, dr, fy):
        return _SIG, _make_codegen(pow2, dark)

    block.__name__ = f"block_{'pow2' if pow2 else 'general'}{'_dark' if dark else ''}"
    return intrinsic(block)


block_pow2 = _declare(True, False)
block_general = _declare(False, False)
block_general_dark = _declare(False, True)


# The row kernel lives here, next to the intrinsics it inlines: numba's on-disk cache is keyed on
# the file that defines a jitted function, so keeping both in one file invalidates them together.
_U64 = np.uint64


@nb.njit(parallel=True, cache=True, boundscheck=False)
def encode_u8_blocks(flat, out2d, z0, k, n_views, shift, threshold, mode, tab, lane_table,
                      row0, row_step, fyq, plane, n_chunks):  # pragma: no cover - compiled
    height = out2d.shape[0]
    length = out2d.shape[1]
    classes, starts, lanes = lane_table.shape
    n_blocks = (length + lanes - 1) // lanes
    base = flat.ctypes.data
    ptab = tab.ctypes.data
    lane_ptr = lane_table.ctypes.data
    per_chunk = (height + n_chunks - 1) // n_chunks
    nv = _U64(n_views)
    for chunk in prange(n_chunks):
        for y in range(chunk * per_chunk, min(height, (chunk + 1) * per_chunk)):
            z = z0[y]
            r0 = row0[y]
            dr = row_step[y]
            fy = fyq[y]
            po = out2d[y].ctypes.data
            row_lanes = lane_ptr + 8 * lanes * starts * (y % classes)
            for blk in range(n_blocks):
                o0 = min(blk * lanes, length - lanes)  # last block overlaps: recomputes, same values
                lp = row_lanes + 8 * lanes * (o0 % starts)
                zb = z - _U64(o0) * k
                if mode == 0:
                    block_pow2(base, ptab + 4 * o0, lp, po + o0, zb, _U64(shift), nv, _U64(0), plane, r0, dr, fy)
                elif mode == 1:
                    block_general(base, ptab + 4 * o0, lp, po + o0, zb, nv, nv, _U64(0), plane, r0, dr, fy)
                else:
                    block_general_dark(base, ptab + 4 * o0, lp, po + o0, zb, nv, nv, threshold, plane, r0, dr, fy)


