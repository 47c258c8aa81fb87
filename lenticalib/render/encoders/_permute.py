"""Gather-free block kernel of the fast uint8 encoder, for CPUs with AVX-512 VBMI byte permutes.

Why.  On the AMD EPYC (Zen 4) machines of this project a vector gather costs about 0.5 ns per
element, and the gather kernel (:mod:`._simd`) needs one per output value: gathers alone take
most of its time.  A two-source byte permute (``vpermi2b``) picks 64 bytes out of 128 in about
one cycle, so this kernel reads the views through permutes instead.

How.  Per source row ``r`` each thread keeps the row *transposed*: ``T_r[s * VS + v]`` is byte
``s`` (``3 x + c`` of the view's interleaved RGB row) of view ``v``, ``VS`` (16, 32 or 64) the
view count rounded up to a power of two.  An output value reads the views at four taps (top and
bottom source row, left and right source column of the bilinear sample), all of the same channel
and view.  For a block of ``LANES`` consecutive output values ``o0 ..`` of a panel row, the left
(and right) taps lie in a few consecutive 128-byte *windows* of the transposed rows, starting at
the block's smallest tap ``s_min``: tap ``s`` of view ``v`` is byte ``(s - s_min) * VS + v`` from
there, i.e. byte ``((s - s_min) * VS) % 128 + v`` of window ``((s - s_min) * VS) // 128``.  So per
block and tap, one permute per window with the index ``base + v`` and a mask of the lanes whose
tap lies in that window; ``base``, the window of each lane, the masks and ``s_min`` depend on the
profile and view size only (:func:`block_tables`, built once per profile).

The view of each output value comes from the canonical ``view_map`` (routing bit-identical to
:mod:`lenticalib.core.routing`, ties, cell layouts, reversed views and dark bands included),
stored once per profile as one byte per output value (``DARK`` where no view lights it).

The bilinear blend: the x blend in 16-bit pairs (``pmaddwd``, weights in 1/2**X_BITS), the y blend
in int32 (weights in 1/2**Y_BITS), rounded half up: within 1 LSB of the float64 reference.

The transposition (:func:`transpose_stages`): a 64-byte column block of the ``VS`` rows is
transposed in registers by ``log2 VS`` rounds of two-source byte shuffles, each round swapping one
bit of the row index with one bit of the byte index; every source row is transposed once per
thread band (about a fifth of the time at 4K, measured; the next row is prefetched meanwhile).
"""

from __future__ import annotations

import functools

import llvmlite.ir as ir
import numba as nb
import numpy as np
from numba import prange, types
from numba.core import cgutils
from numba.extending import intrinsic

from ...core.jit import cached_njit
from ._simd import next_source_row, prefetch_row_lines, splat, vector_constant

LANES = 64
WINDOW = 128  # bytes a two-source byte permute selects from
MAX_WINDOWS = 10  # windows per block; from about 11 on the gather kernel is as fast (tools/bench_encode.py)
VIEW_SLOTS = (16, 32, 64)  # bytes per transposed source byte: the view count rounded up
X_BITS = 14  # x weights in 1/2**X_BITS (pairs fit int16 for pmaddwd)
Y_DROP = 4  # low bits of the x blend dropped before the y blend, so it stays in int32
Y_BITS = 12  # y weights in 1/2**Y_BITS
DARK = 255  # view-map byte of a subpixel no view lights

_I1, _I8, _I16, _I32, _I64 = (ir.IntType(b) for b in (1, 8, 16, 32, 64))
_V8 = ir.VectorType(_I8, LANES)


@functools.cache
def available() -> bool:
    """True when the host CPU has AVX-512 VBMI and BW and numba compiles for the host CPU."""
    import llvmlite.binding as llvm

    features = llvm.get_host_cpu_features()
    host = nb.config.CPU_NAME in (None, "", "host")
    return bool(host and features.get("avx512vbmi") and features.get("avx512bw"))


def view_slots(n_views: int) -> int | None:
    """Bytes per transposed source byte for ``n_views`` views, or None when more than 64."""
    return next((vs for vs in VIEW_SLOTS if n_views <= vs), None)


def transpose_stages(vs: int) -> list[list[tuple[int, int, list[int], list[int]]]]:
    """Shuffle rounds that turn ``vs`` rows of 64 bytes (row ``v``, byte ``s``) into ``vs`` vectors
    holding byte ``(s % (64 // vs)) * vs + v`` of vector ``s // (64 // vs)``.

    Each round is a list of ``(a, b, mask_a, mask_b)``: vectors ``a`` and ``b`` are replaced by the
    two-source shuffles of ``(vector a, vector b)`` with those masks (0..127); checked by tracking
    labels ``v * 64 + s`` through the rounds before it is returned."""
    bits = vs.bit_length() - 1
    low = 6 - bits  # byte-index bits that stay (the s values within one output vector)
    stages = []
    for i in range(bits):
        p = low + i  # byte bit swapped with row bit i: a keeps the bytes with bit p clear, b the others
        mask_a = [e if not e >> p & 1 else 64 + (e & ~(1 << p)) for e in range(64)]
        mask_b = [(e | 1 << p) if not e >> p & 1 else 64 + e for e in range(64)]
        stages.append([[a, a | 1 << i, mask_a, mask_b] for a in range(vs) if not a >> i & 1])
    # fold the final reordering (byte s_low + v * 2**low -> s_low * vs + v) into the last round
    order = [(e // vs) + (e % vs) * (1 << low) for e in range(64)]
    for entry in stages[-1]:
        entry[2], entry[3] = [entry[2][order[e]] for e in range(64)], [entry[3][order[e]] for e in range(64)]
    current = [[v * 64 + s for s in range(64)] for v in range(vs)]
    for stage in stages:
        new = list(current)
        for a, b, mask_a, mask_b in stage:
            both = current[a] + current[b]
            new[a], new[b] = [both[m] for m in mask_a], [both[m] for m in mask_b]
        current = new
    per = 64 // vs
    for j, vec in enumerate(current):
        for e, label in enumerate(vec):
            v, s = divmod(label, 64)
            assert s == j * per + e // vs and v == e % vs, "transpose rounds are wrong"
    return [[tuple(entry) for entry in stage] for stage in stages]


def _declare_transpose(vs: int):
    stages = transpose_stages(vs)

    def codegen(context, builder, signature, args):
        src, plane, n_views, dst = args
        vec_ptr = _V8.as_pointer()
        last = builder.sub(n_views, ir.Constant(_I64, 1))
        vecs = []
        for v in range(vs):  # rows past the view count repeat the last view (never addressed)
            row = builder.select(builder.icmp_unsigned("<", ir.Constant(_I64, v), n_views), ir.Constant(_I64, v), last)
            vecs.append(builder.load(builder.inttoptr(builder.add(src, builder.mul(row, plane)), vec_ptr), align=1))
        for stage in stages:
            new = list(vecs)
            for a, b, mask_a, mask_b in stage:
                new[a] = builder.shuffle_vector(vecs[a], vecs[b], ir.Constant(ir.VectorType(_I32, 64), mask_a))
                new[b] = builder.shuffle_vector(vecs[a], vecs[b], ir.Constant(ir.VectorType(_I32, 64), mask_b))
            vecs = new
        for j, vec in enumerate(vecs):
            builder.store(vec, builder.inttoptr(builder.add(dst, ir.Constant(_I64, 64 * j)), vec_ptr), align=1)
        return context.get_dummy_value()

    def transpose(typingctx, src, plane, n_views, dst):
        return types.void(types.int64, types.int64, types.int64, types.int64), codegen

    transpose.__name__ = f"transpose_{vs}"
    return intrinsic(transpose)


transpose_16, transpose_32, transpose_64 = (_declare_transpose(vs) for vs in VIEW_SLOTS)


def _permute(builder, table_lo, index, table_hi):
    fn = cgutils.get_or_insert_function(builder.module, ir.FunctionType(_V8, [_V8, _V8, _V8]),
                                        "llvm.x86.avx512.vpermi2var.qi.512")
    return builder.call(fn, [table_lo, index, table_hi])


def _madd(builder, words, weights):
    v16, v32 = ir.VectorType(_I16, 32), ir.VectorType(_I32, 16)
    fn = cgutils.get_or_insert_function(builder.module, ir.FunctionType(v32, [v16, v16]),
                                        "llvm.x86.avx512.pmaddw.d.512")
    return builder.call(fn, [words, weights])


def _concat(builder, parts):
    while len(parts) > 1:
        n = parts[0].type.count
        parts = [builder.shuffle_vector(parts[i], parts[i + 1], ir.Constant(ir.VectorType(_I32, 2 * n), list(range(2 * n))))
                 for i in range(0, len(parts), 2)]
    return parts[0]


def _x_blend(builder, left, right, weights):
    """``left * gx + right * fx`` per lane (int32 ``<LANES>``): byte pairs widened to int16 and
    multiplied-added with the (gx, fx) int16 pairs ``weights`` ``<2 LANES x i16>``."""
    pairs = builder.shuffle_vector(left, right, ir.Constant(ir.VectorType(_I32, 2 * LANES),
                                                            [j // 2 + LANES * (j % 2) for j in range(2 * LANES)]))
    words = builder.zext(pairs, ir.VectorType(_I16, 2 * LANES))
    parts = []
    for q in range(2 * LANES // 32):
        pick = ir.Constant(ir.VectorType(_I32, 32), list(range(32 * q, 32 * q + 32)))
        parts.append(_madd(builder, builder.shuffle_vector(words, words, pick),
                           builder.shuffle_vector(weights, weights, pick)))
    return _concat(builder, parts)


def _block_codegen(context, builder, signature, args):
    top, bottom, view_ptr, tables, out_ptr, fy, windows = args
    v32 = ir.VectorType(_I32, LANES)

    def load(address, offset, vty=_V8, align=1):
        if not isinstance(offset, ir.Value):
            offset = ir.Constant(_I64, offset)
        return builder.load(builder.inttoptr(builder.add(address, offset), vty.as_pointer()), align=align)

    view = load(view_ptr, 0)
    # block tables: base_l (64 B), base_r (64 B), weights (2 LANES int16), masks (windows x 2 uint64)
    index_l = builder.add(load(tables, 0), view)
    index_r = builder.add(load(tables, LANES), view)
    weights = load(tables, 2 * LANES, ir.VectorType(_I16, 2 * LANES))
    zero = ir.Constant(_V8, None)
    # for k in range(windows): one permute per tap from window k of the top and bottom rows
    entry = builder.block
    loop = builder.append_basic_block("windows")
    done = builder.append_basic_block("blend")
    builder.branch(loop)
    builder.position_at_end(loop)
    k = builder.phi(_I64)
    k.add_incoming(ir.Constant(_I64, 0), entry)
    taps = []
    for _ in range(4):  # top-left, top-right, bottom-left, bottom-right
        taps.append(builder.phi(_V8))
        taps[-1].add_incoming(zero, entry)
    at_mask = builder.add(ir.Constant(_I64, 6 * LANES), builder.mul(k, ir.Constant(_I64, 16)))
    mask_l = builder.bitcast(load(tables, at_mask, _I64, 8), ir.VectorType(_I1, LANES))
    mask_r = builder.bitcast(load(tables, builder.add(at_mask, ir.Constant(_I64, 8)), _I64, 8), ir.VectorType(_I1, LANES))
    at_window = builder.mul(k, ir.Constant(_I64, WINDOW))
    new = []
    for base, (t_l, t_r) in ((top, taps[:2]), (bottom, taps[2:])):
        lo, hi = load(base, at_window), load(builder.add(base, ir.Constant(_I64, LANES)), at_window)
        new.append(builder.select(mask_l, _permute(builder, lo, index_l, hi), t_l))
        new.append(builder.select(mask_r, _permute(builder, lo, index_r, hi), t_r))
    k_next = builder.add(k, ir.Constant(_I64, 1))
    k.add_incoming(k_next, loop)
    for phi, value in zip(taps, new):
        phi.add_incoming(value, loop)
    builder.cbranch(builder.icmp_unsigned("<", k_next, windows), loop, done)
    builder.position_at_end(done)
    upper = builder.lshr(_x_blend(builder, new[0], new[1], weights), vector_constant(v32, Y_DROP))
    lower = builder.lshr(_x_blend(builder, new[2], new[3], weights), vector_constant(v32, Y_DROP))
    fy32 = splat(builder, builder.trunc(fy, _I32), v32)
    acc = builder.add(builder.add(builder.shl(upper, vector_constant(v32, Y_BITS)), builder.mul(builder.sub(lower, upper), fy32)),
                      vector_constant(v32, 1 << (X_BITS - Y_DROP + Y_BITS - 1)))
    value = builder.trunc(builder.lshr(acc, vector_constant(v32, X_BITS - Y_DROP + Y_BITS)), _V8)
    value = builder.select(builder.icmp_unsigned("==", view, vector_constant(_V8, DARK)), zero, value)
    builder.store(value, builder.inttoptr(out_ptr, _V8.as_pointer()), align=1)
    return context.get_dummy_value()


@intrinsic
def block(typingctx, top, bottom, view_ptr, tables, out_ptr, fy, windows):
    """One block of ``LANES`` output values: ``top``/``bottom`` the addresses of the block's first
    window in the two transposed rows, ``view_ptr`` its views, ``tables`` its block tables,
    ``out_ptr`` where the values go, ``fy`` the row's y weight (1/2**Y_BITS), ``windows`` >= 1."""
    return types.void(*(types.int64,) * 7), _block_codegen


def table_bytes(windows: int) -> int:
    """Bytes of one block's tables: two index bases, the weight pairs, two masks per window."""
    return 2 * LANES + 4 * LANES + 16 * windows


def block_tables(s_left: np.ndarray, s_right: np.ndarray, x_weight: np.ndarray, vs: int):
    """Per-profile tables of the blocks of a panel row.

    ``s_left``, ``s_right``: int ``(L,)`` left and right column tap of every output value as a
    byte of the source row (``3 * column + channel``); ``x_weight``: float ``(L,)`` weight of the
    right tap.  Returns ``(starts, s_min_bytes, tables, windows)``: int64 ``(blocks,)`` first
    output value of each block (the last block overlaps the one before), int64 ``(blocks,)``
    ``s_min * vs``, uint8 ``(blocks, table_bytes(windows))`` and the window count (None when a
    block needs more than ``MAX_WINDOWS``)."""
    length = s_left.shape[0]
    starts = np.minimum(np.arange(0, length, LANES), length - LANES).astype(np.int64)
    lanes = starts[:, None] + np.arange(LANES)[None, :]
    sl, sr = s_left[lanes].astype(np.int64), s_right[lanes].astype(np.int64)
    s_min = np.minimum(sl.min(axis=1), sr.min(axis=1))
    at_l, at_r = (sl - s_min[:, None]) * vs, (sr - s_min[:, None]) * vs
    windows = int(max(at_l.max(), at_r.max()) // WINDOW) + 1
    if windows > MAX_WINDOWS:
        return starts, s_min * vs, None, None
    tables = np.zeros((starts.shape[0], table_bytes(windows)), dtype=np.uint8)
    tables[:, :LANES] = at_l % WINDOW
    tables[:, LANES:2 * LANES] = at_r % WINDOW
    fx = np.rint(x_weight[lanes] * (1 << X_BITS)).astype(np.int16)
    pairs = np.stack([(1 << X_BITS) - fx, fx], axis=-1).reshape(starts.shape[0], 2 * LANES)
    tables[:, 2 * LANES:6 * LANES] = pairs.view(np.uint8)
    bit = np.uint64(1) << np.arange(LANES, dtype=np.uint64)
    masks = np.zeros((starts.shape[0], windows, 2), dtype=np.uint64)
    for k in range(windows):
        masks[:, k, 0] = np.where(at_l // WINDOW == k, bit, np.uint64(0)).sum(axis=1, dtype=np.uint64)
        masks[:, k, 1] = np.where(at_r // WINDOW == k, bit, np.uint64(0)).sum(axis=1, dtype=np.uint64)
    tables[:, 6 * LANES:] = masks.reshape(starts.shape[0], -1).view(np.uint8)
    return starts, s_min * vs, tables, windows


@cached_njit(boundscheck=False)
def _transpose_row(flat, row_start, plane, n_views, row_bytes, vs, dest):  # pragma: no cover - compiled
    """Transpose source row ``row_start`` (byte offset in a view plane) of all views into ``dest``."""
    src = flat.ctypes.data + row_start
    dst = dest.ctypes.data
    for b in range(0, row_bytes, 64):
        s0 = min(b, row_bytes - 64)  # last block overlaps: same bytes again
        if vs == 16:
            transpose_16(src + s0, plane, n_views, dst + s0 * vs)
        elif vs == 32:
            transpose_32(src + s0, plane, n_views, dst + s0 * vs)
        else:
            transpose_64(src + s0, plane, n_views, dst + s0 * vs)


@cached_njit(parallel=True, boundscheck=False)
def encode_u8_permute(flat, out2d, views_u8, row_lo, row_hi, fyq, starts, s_min_bytes, tables, windows,
                      plane, row_bytes, n_views, vs, t_bytes, n_chunks):  # pragma: no cover - compiled
    """Encode uint8 views with the permute kernel: threads over ``n_chunks`` bands of rows."""
    height = out2d.shape[0]
    n_blocks = starts.shape[0]
    tab_stride = tables.shape[1]
    per_chunk = (height + n_chunks - 1) // n_chunks
    ptab = tables.ctypes.data
    # While rows are in use, the next source row is prefetched a few cache lines per block (the
    # N view planes are too many streams for the hardware prefetcher), so its transposition
    # reads from the cache.
    pf_lines = (row_bytes + 63) // 64
    src = flat.ctypes.data
    for chunk in prange(n_chunks):
        rows = np.empty((2, t_bytes), dtype=np.uint8)  # two transposed source rows
        held0, held1 = -1, -1
        pf_view, pf_line, pf_row, pf_per_block = n_views, 0, 0, 0
        end = min(height, (chunk + 1) * per_chunk)
        for y in range(chunk * per_chunk, end):
            top, bottom = row_lo[y], row_hi[y]
            changed = False
            for need in (top, bottom):
                if need != held0 and need != held1:
                    changed = True
                    if held0 != top and held0 != bottom:  # slot 0 holds neither needed row
                        _transpose_row(flat, need * row_bytes, plane, n_views, row_bytes, vs, rows[0])
                        held0 = need
                    else:
                        _transpose_row(flat, need * row_bytes, plane, n_views, row_bytes, vs, rows[1])
                        held1 = need
            if changed:  # the source row the next change of taps in this band adds
                ahead, new_row = next_source_row(row_lo, row_hi, y, end, top, bottom)
                pf_view, pf_line = (n_views if new_row < 0 else 0), 0
                if new_row >= 0:
                    pf_row = src + new_row * row_bytes
                    pf_per_block = n_views * pf_lines // (n_blocks * (ahead - y)) + 1
            pt = rows[0].ctypes.data if held0 == top else rows[1].ctypes.data
            pb = rows[0].ctypes.data if held0 == bottom else rows[1].ctypes.data
            pv = views_u8[y].ctypes.data
            po = out2d[y].ctypes.data
            fy = fyq[y]
            for blk in range(n_blocks):
                o0 = starts[blk]
                at = s_min_bytes[blk]
                tb = ptab + blk * tab_stride
                pf_view, pf_line = prefetch_row_lines(pf_row, pf_view, pf_line, pf_per_block, n_views, pf_lines, plane)
                block(pt + at, pb + at, pv + o0, tb, po + o0, fy, windows)
