"""The ``cpu`` renderer: a tile-based 3D Gaussian Splatting rasterizer in numba, gsplat's maths.

It reproduces gsplat 1.5's forward pass (``rasterization(..., packed=False, render_mode="RGB",
rasterize_mode="classic")``, CUDA kernels ``ProjectionEWA3DGSFused.cu`` and
``RasterizeToPixels3DGSFwd.cu``, pure-torch twins in ``gsplat/cuda/_torch_impl.py``):

projection (per view, threads over Gaussians)
    mean and covariance R S S^T R^T to the camera frame; culled unless near (0.01) <= z <= far
    (1e10); EWA 2D covariance J W Sigma W^T J^T with x/z and y/z clamped to 1.3 x the field of
    view's half-extent (gsplat's ``lim_x_pos = (W - cx)/fx + 0.3 tan_fovx`` etc.) inside J only;
    + 0.3 px^2 on the diagonal (eps2d); conic = its inverse; culled if det <= 0, opacity < 1/255,
    or the box off-screen.  The box is gsplat's opacity-aware one: half-sizes
    ceil(e sqrt(cov_xx)), ceil(e sqrt(cov_yy)) with e = min(3.33, sqrt(2 ln(255 opacity))), i.e.
    exactly the bounding box of the ellipse where alpha >= 1/255.
colour
    SH of degree 0-3 (gsplat's/Sloan's basis) for the unit direction from the camera centre to
    the mean, + 0.5, clamped at 0 below (not above).
binning and order
    16 x 16 tiles; each Gaussian goes to every tile its box touches; within a tile Gaussians are
    taken front to back by camera-frame z (ties by index: gsplat's stable radix sort).
compositing (threads over tiles)
    per pixel centre p, d = p - mean2d, sigma = 0.5 (a dx^2 + c dy^2) + b dx dy,
    alpha = min(0.999, opacity exp(-sigma)); skipped if sigma < 0 or alpha < 1/255; the pixel
    stops *before* the Gaussian that would take its transmittance T to <= 1e-4; colour += c alpha T.

How it is fast (about 3x a plain scalar numba loop over the same pixels):
a tile keeps its state (T, colour) per row of 16 pixels; Gaussian after Gaussian (front to back),
only the tile rows that the ellipse where alpha can reach 1/255 crosses are visited, and only
those that still have a live pixel on the ellipse's chord; such a row is updated by one
branch-free SIMD step (:func:`_blend_full`, or :func:`_blend_half` for 8 pixels), hand-written
LLVM IR as numba's auto-vectorizer does not handle this loop.

Differences from gsplat: exp is a polynomial in the SIMD step (relative error about 3e-6) and the
projection runs in float64, so images agree with gsplat's to float32 rounding, not bit for bit
(133-142 dB PSNR on the test scenes); Gaussians whose projected variance exceeds 1e30 px^2 are
culled (gsplat's float32 would overflow on them); non-finite parameters are refused.

Pixel convention: the ``Ks`` given are OpenCV's (pixel centres at integer coordinates, as the
virtual cameras of the render layer are built).  gsplat puts pixel (i, j)'s centre at
(j + 0.5, i + 0.5), so this renderer (like the ``gsplat`` backend) adds 0.5 to cx and cy and then
works in gsplat's frame, which is the same projection.

Files: projection, colour, depth order and binning are in :mod:`.cpu_project`; this module holds
the compositing (the SIMD intrinsics and the tile kernel) and :func:`render_cpu`, which runs them.
"""

from __future__ import annotations

import math

import llvmlite.ir as ir
import numba as nb
import numpy as np
from numba import prange, types
from numba.core import cgutils
from numba.extending import intrinsic

from ...core.jit import cached_njit
from ..avatar.gaussians import Gaussians
from .common import TILE_SIZE, check_finite_gaussians, check_render_inputs, jacobian_limits
from .cpu_project import (ALPHA_MIN, BIN_CHUNKS, REC_B, REC_CA, REC_CB, REC_CC, REC_EXT_Y, REC_G, REC_MX, REC_MY,
                          REC_OP, REC_Q, REC_R, REC_SLOPE, RECORD_FIELDS, bin_tiles, front_to_back, project_view,
                          world_covariances)

__all__ = ["ALPHA_MAX", "ALPHA_MIN", "T_MIN", "render_cpu"]

ALPHA_MAX = 0.999
T_MIN = 1e-4  # a pixel stops before its transmittance would fall to this
# A tile's compositing state: per tile row, 5 fields of TILE_SIZE float32 (offsets into the row):
# live transmittance (0 once stopped), transmittance where the pixel stopped, accumulated R, G, B.
_T, _TF, _AR, _AG, _AB = (k * TILE_SIZE for k in range(5))
_ROW = 5 * TILE_SIZE
_LOW32 = 0xFFFFFFFF


_F = np.float32
# exp(-s) for s in [0, 8] (beyond, alpha = o exp(-s) < 1/255 anyway) as p(s / 16) ** 16, p the
# degree-5 Chebyshev interpolant of exp(-t) on [0, 0.5] (coefficients rescaled to take s); relative
# error about 3e-6 (float32 rounding amplified by the squarings)
_EXP_POLY = tuple(float(_F(c / 16.0 ** k)) for k, c in enumerate(np.polynomial.Chebyshev.interpolate(
    lambda t: np.exp(-t), 5, domain=[0.0, 0.5]).convert(kind=np.polynomial.Polynomial).coef))
_EXP_SQUARINGS = 4
_I64 = ir.IntType(64)


def _blend_codegen(lanes):
    """Codegen of a ``_blend_*`` intrinsic: one Gaussian over ``lanes`` pixels of one tile row.

    Arguments (row state address, pixel-centre x address, mean x, a / 2, b dy, c dy^2 / 2, opacity,
    R, G, B).  The state is 5 fields of ``lanes`` float32, TILE_SIZE apart (_T, _TF, _AR, _AG, _AB);
    every lane is computed branch-free: alpha = min(0.999, o exp(-sigma)), zero where sigma < 0 or
    alpha < 1/255; a lane whose transmittance would fall to <= 1e-4 stops (exclusive): its
    transmittance is parked in _TF and the live one set to 0, so later Gaussians add nothing to it.
    Returns the stopped lanes as a bit mask (bit i: lane i) | their number << 32.
    """
    vec = ir.VectorType(ir.FloatType(), lanes)

    def codegen(context, builder, signature, args):
        buf, xs_ptr, mx, half_a, bdy, half_cdy2, op, cr, cg, cb = args

        def field(k):
            return builder.inttoptr(builder.add(buf, ir.Constant(_I64, 4 * k)), vec.as_pointer())

        def splat(value):
            first = builder.insert_element(ir.Constant(vec, ir.Undefined), value, ir.Constant(ir.IntType(32), 0))
            return builder.shuffle_vector(first, ir.Constant(vec, ir.Undefined),
                                          ir.Constant(ir.VectorType(ir.IntType(32), lanes), [0] * lanes))

        def const(value):
            return ir.Constant(vec, [float(_F(value))] * lanes)

        def clamp_above(x, limit):
            return builder.select(builder.fcmp_ordered(">", x, limit), limit, x)

        fma = cgutils.get_or_insert_function(builder.module, ir.FunctionType(vec, [vec, vec, vec]),
                                             f"llvm.fma.v{lanes}f32")
        zero, one = const(0.0), const(1.0)
        xs = builder.load(builder.inttoptr(xs_ptr, vec.as_pointer()), align=4)
        trans, t_final, acc_r, acc_g, acc_b = (builder.load(field(k), align=4) for k in (_T, _TF, _AR, _AG, _AB))
        dx = builder.fsub(xs, splat(mx))
        sigma = builder.call(fma, [builder.fmul(splat(half_a), dx), dx,
                                   builder.call(fma, [splat(bdy), dx, splat(half_cdy2)])])
        s = clamp_above(builder.select(builder.fcmp_ordered("<", sigma, zero), zero, sigma), const(8.0))
        poly = const(_EXP_POLY[-1])
        for coef in _EXP_POLY[-2::-1]:
            poly = builder.call(fma, [poly, s, const(coef)])
        for _ in range(_EXP_SQUARINGS):
            poly = builder.fmul(poly, poly)
        alpha = clamp_above(builder.fmul(splat(op), poly), const(ALPHA_MAX))
        used = builder.and_(builder.fcmp_ordered(">=", sigma, zero), builder.fcmp_ordered(">=", alpha, const(ALPHA_MIN)))
        alpha = builder.select(used, alpha, zero)
        next_t = builder.fmul(trans, builder.fsub(one, alpha))
        stop = builder.and_(builder.fcmp_ordered("<=", next_t, const(T_MIN)), builder.fcmp_ordered(">", trans, zero))
        w = builder.select(stop, zero, builder.fmul(alpha, trans))
        builder.store(builder.select(stop, trans, t_final), field(_TF), align=4)
        builder.store(builder.call(fma, [w, splat(cr), acc_r]), field(_AR), align=4)
        builder.store(builder.call(fma, [w, splat(cg), acc_g]), field(_AG), align=4)
        builder.store(builder.call(fma, [w, splat(cb), acc_b]), field(_AB), align=4)
        builder.store(builder.select(stop, zero, next_t), field(_T), align=4)
        bits = builder.bitcast(stop, ir.IntType(lanes))
        ctpop = cgutils.get_or_insert_function(builder.module, ir.FunctionType(bits.type, [bits.type]),
                                               f"llvm.ctpop.i{lanes}")
        count = builder.zext(builder.call(ctpop, [bits]), _I64)
        return builder.or_(builder.zext(bits, _I64), builder.shl(count, ir.Constant(_I64, 32)))

    return codegen


_BLEND_SIG = types.int64(types.intp, types.intp, *([types.float32] * 8))


@intrinsic
def _blend_full(typingctx, buf, xs_ptr, mx, half_a, bdy, half_cdy2, op, cr, cg, cb):
    """One Gaussian over the TILE_SIZE pixels of a tile row, see :func:`_blend_codegen`."""
    return _BLEND_SIG, _blend_codegen(TILE_SIZE)


@intrinsic
def _blend_half(typingctx, buf, xs_ptr, mx, half_a, bdy, half_cdy2, op, cr, cg, cb):
    """One Gaussian over TILE_SIZE / 2 pixels of a tile row, see :func:`_blend_codegen`."""
    return _BLEND_SIG, _blend_codegen(TILE_SIZE // 2)


# The compositing kernel stays in this file, next to the intrinsics it inlines: numba's on-disk
# cache is keyed on the defining file, so editing either invalidates both.
@cached_njit(parallel=True)
def _composite(records, offsets, ids, tile_order, workers, width, height, tiles_x, background,
               out):  # pragma: no cover - compiled
    """Front-to-back compositing of every tile into ``out`` (H, W, 4): RGB over ``background``, alpha.

    ``workers`` loops share the tiles, worker w taking ``tile_order[w::workers]``: dealt like
    cards, so that every thread gets a fair share of the busy tiles (numba's prange hands each
    thread a fixed block of iterations, and ``parallel_chunksize`` made no difference here).

    Per tile, Gaussian after Gaussian, each tile row whose pixels on the chord of the Gaussian's
    ellipse E are not all stopped goes through :func:`_blend_full`, or :func:`_blend_half` when
    those live pixels lie in one half of the row.  A tile whose pixels have all stopped is done.
    """
    ts = TILE_SIZE
    hs = TILE_SIZE // 2
    half, one = _F(0.5), _F(1.0)
    for worker in prange(workers):
        for k in range(worker, tile_order.shape[0], workers):
            t = tile_order[k]
            ty = t // tiles_x
            tx = t - ty * tiles_x
            x0 = tx * ts
            y0 = ty * ts
            state = np.zeros(ts * _ROW, dtype=np.float32)
            xs = np.empty(ts, dtype=np.float32)
            for i in range(ts):
                xs[i] = _F(x0 + i) + half
            alive = np.zeros(ts, dtype=np.int64)  # per tile row, a bit per live pixel
            remaining = 0
            for r in range(ts):
                for i in range(ts):
                    if y0 + r < height and x0 + i < width:  # pixels outside the image start stopped
                        state[r * _ROW + _T + i] = one
                        alive[r] |= 1 << i
                        remaining += 1
            base = state.ctypes.data
            pxs = xs.ctypes.data
            for j in range(offsets[t], offsets[t + 1]):
                g = ids[j]
                mx, my = records[g, REC_MX], records[g, REC_MY]
                ext_y = np.float64(records[g, REC_EXT_Y])
                slope, q = np.float64(records[g, REC_SLOPE]), np.float64(records[g, REC_Q])
                ra = int(max(np.ceil(my - ext_y - 0.5) - y0, 0.0))  # clamped as floats, then converted
                rb = int(min(np.floor(my + ext_y - 0.5) - y0, ts - 1.0))
                half_a, b, half_c = half * records[g, REC_CA], records[g, REC_CB], half * records[g, REC_CC]
                op = records[g, REC_OP]
                cr, cg, cb = records[g, REC_R], records[g, REC_G], records[g, REC_B]
                for r in range(ra, rb + 1):
                    if alive[r] == 0:
                        continue
                    dy = _F(y0 + r) + half - my
                    # the chord of E on this row, widened by 0.01 px against rounding; lanes la..lb
                    dy64 = np.float64(dy)
                    centre = mx + slope * dy64 - x0 - 0.5
                    width_half = math.sqrt(max(q * (ext_y * ext_y - dy64 * dy64), 0.0)) + 0.01
                    la = int(max(np.ceil(centre - width_half), -1.0))
                    lb = int(min(np.floor(centre + width_half), np.float64(ts)))
                    if lb < 0 or la >= ts:
                        continue
                    live = alive[r] & (((1 << (min(lb, ts - 1) + 1)) - 1) ^ ((1 << max(la, 0)) - 1))
                    if live == 0:  # the chord's pixels have all stopped
                        continue
                    row = base + 4 * _ROW * r
                    if live < (1 << hs):
                        result = _blend_half(row, pxs, mx, half_a, b * dy, half_c * dy * dy, op, cr, cg, cb)
                        stopped = result & _LOW32
                    elif live & ((1 << hs) - 1) == 0:
                        result = _blend_half(row + 4 * hs, pxs + 4 * hs, mx, half_a, b * dy, half_c * dy * dy, op, cr, cg, cb)
                        stopped = (result & _LOW32) << hs
                    else:
                        result = _blend_full(row, pxs, mx, half_a, b * dy, half_c * dy * dy, op, cr, cg, cb)
                        stopped = result & _LOW32
                    alive[r] &= ~stopped
                    remaining -= result >> 32
                if remaining == 0:
                    break
            for y in range(y0, min(y0 + ts, height)):
                for x in range(x0, min(x0 + ts, width)):
                    p = (y - y0) * _ROW + x - x0
                    tp = state[_T + p] if state[_T + p] > 0.0 else state[_TF + p]
                    out[y, x, 0] = state[_AR + p] + tp * background[0]
                    out[y, x, 1] = state[_AG + p] + tp * background[1]
                    out[y, x, 2] = state[_AB + p] + tp * background[2]
                    out[y, x, 3] = one - tp


def render_cpu(gaussians: Gaussians, viewmats, Ks, width: int, height: int, *,
               background=None) -> np.ndarray:
    """Render N views of ``gaussians`` on the CPU; gsplat's forward pass (see the module docstring).

    ARGUMENTS
        gaussians   :class:`~lenticalib.render.avatar.gaussians.Gaussians`, activated (numpy or torch)
        viewmats    (N, 4, 4) world-to-camera, camera frame OpenCV (x right, y down, z forward)
        Ks          (N, 3, 3) intrinsics in pixels, OpenCV (pixel centres at integer coordinates)
        width, height   view size, pixels
        background  None (black) or (3,) RGB

    RETURNED VALUE
        (N, height, width, 4) float32: RGB composited over ``background`` and alpha = 1 - T (the
        transmittance left).  With background None (black) the RGB is premultiplied by alpha;
        ``rgb + (1 - alpha) * b`` puts it over another background b.  Same as gsplat returns.
    """
    viewmats, Ks, background = check_render_inputs(gaussians, viewmats, Ks, width, height, background)
    g = gaussians.to_numpy()
    check_finite_gaussians(g)
    bg = np.zeros(3, dtype=np.float32) if background is None else background.astype(np.float32)
    n = viewmats.shape[0]
    out = np.empty((n, height, width, 4), dtype=np.float32)
    if g.count == 0:
        out[..., :3] = bg
        out[..., 3] = 0.0
        return out
    cov = world_covariances(g.quats, g.scales)
    tiles_x = -(-width // TILE_SIZE)
    tiles_y = -(-height // TILE_SIZE)
    records = np.empty((g.count, RECORD_FIELDS), dtype=np.float32)
    boxes = np.empty((g.count, 4), dtype=np.int32)
    depth = np.empty(g.count, dtype=np.float32)
    index = np.arange(g.count, dtype=np.uint64)
    workers = 4 * nb.get_num_threads()
    for view in range(n):
        k = Ks[view]
        fx, fy, cx, cy = k[0, 0], k[1, 1], k[0, 2] + 0.5, k[1, 2] + 0.5
        project_view(g.means, cov, g.opacities, g.sh, g.sh_degree, viewmats[view], fx, fy, cx, cy,
                     jacobian_limits(width, height, fx, fy, cx, cy), width, height, tiles_x, tiles_y,
                     records, boxes, depth)
        order = front_to_back(depth, index)
        offsets, ids, packed = bin_tiles(order, boxes, records, tiles_x * tiles_y, tiles_x, BIN_CHUNKS)
        # busiest tiles first, dealt to the workers in turn, so that the threads finish together
        tile_order = np.argsort(offsets[:-1] - offsets[1:], kind="stable")
        _composite(packed, offsets, ids, tile_order, workers, width, height, tiles_x, bg, out[view])
    return out
