"""Projection, colour and binning kernels of the ``cpu`` renderer (:mod:`.cpu`), in numba.

Per view: :func:`world_covariances` (once per render, R S S^T R^T), :func:`project_view` (EWA
projection, culling, gsplat's opacity-aware tile box, SH colour by :func:`_sh_colour`),
:func:`front_to_back` (depth order, ties by index) and :func:`bin_tiles` (per-tile lists, a parallel
counting sort).  The maths and gsplat's constants are described in :mod:`.cpu`'s docstring; the
compositing that consumes the records written here lives there.

Public because they are a contract shared by two renderers: :mod:`.cpu` composites the records, and
the ``gl`` renderer (:mod:`.gl_upload`, :mod:`.gl_renderer`, :mod:`.gl_shaders`) uploads the same
records and uses ``COV_MAX`` / ``SIGMA_MARGIN`` in its shaders.

The per-Gaussian record layout (``REC_MX`` ... ``REC_EXT_Y``, ``RECORD_FIELDS``) is defined here and read by
:func:`lenticalib.render.renderers.cpu._composite`.  numba's on-disk cache (``cache=True``) is
keyed on each kernel's own file and freezes imported constants at compile time, so a change to
the layout here must also touch cpu.py (or clear its ``__pycache__``) to recompile the compositor.
"""

from __future__ import annotations

import math

import numpy as np
from numba import prange

from ...core.jit import cached_njit
from ..cameras.view_cameras import NEAR_PLANE
from .common import EPS2D, FAR_PLANE, TILE_SIZE

ALPHA_MIN = 1.0 / 255.0  # gsplat's ALPHA_THRESHOLD
SIGMA_MARGIN = 1e-3  # the visited ellipse reaches slightly past alpha = 1/255; alpha is tested exactly
BIN_CHUNKS = 16  # runs of Gaussians binned in parallel
# Gaussians whose 2D variance exceeds this (px^2; a radius of 1e15 px) are culled, so that every
# per-Gaussian value fits float32 (gsplat's float32 kernels would overflow on them)
COV_MAX = 1e30

# Per-Gaussian record of one view, float32, RECORD_FIELDS values; REC_* are the column indices:
# mean (REC_MX, REC_MY) px; conic (REC_CA, REC_CB, REC_CC) of [[a, b], [b, c]] (1/px^2); opacity REC_OP;
# colour (REC_R, REC_G, REC_B) from the SH; ellipse REC_SLOPE (px per row), REC_Q, half-height REC_EXT_Y (rows).
# The ellipse E where sigma <= ln(255 opacity) + margin (outside it alpha < 1/255) reaches rows
# |dy| <= REC_EXT_Y, and on row dy it spans
# x in mx + REC_SLOPE dy -+ sqrt(REC_Q (REC_EXT_Y^2 - dy^2)) (pixels).
REC_MX, REC_MY, REC_CA, REC_CB, REC_CC, REC_OP, REC_R, REC_G, REC_B, REC_SLOPE, REC_Q, REC_EXT_Y = range(12)
RECORD_FIELDS = 12


@cached_njit(parallel=True)
def world_covariances(quats, scales):  # pragma: no cover - compiled
    """(G, 6) float64 covariances R S S^T R^T, upper triangle xx xy xz yy yz zz, quats normalised."""
    g = quats.shape[0]
    out = np.empty((g, 6))
    for i in prange(g):
        w, x, y, z = (np.float64(quats[i, 0]), np.float64(quats[i, 1]),
                      np.float64(quats[i, 2]), np.float64(quats[i, 3]))
        inv = 1.0 / math.sqrt(w * w + x * x + y * y + z * z)
        w *= inv
        x *= inv
        y *= inv
        z *= inv
        r00, r01, r02 = 1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)
        r10, r11, r12 = 2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)
        r20, r21, r22 = 2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)
        s0, s1, s2 = np.float64(scales[i, 0]), np.float64(scales[i, 1]), np.float64(scales[i, 2])
        m00, m01, m02 = r00 * s0, r01 * s1, r02 * s2
        m10, m11, m12 = r10 * s0, r11 * s1, r12 * s2
        m20, m21, m22 = r20 * s0, r21 * s1, r22 * s2
        out[i, 0] = m00 * m00 + m01 * m01 + m02 * m02
        out[i, 1] = m00 * m10 + m01 * m11 + m02 * m12
        out[i, 2] = m00 * m20 + m01 * m21 + m02 * m22
        out[i, 3] = m10 * m10 + m11 * m11 + m12 * m12
        out[i, 4] = m10 * m20 + m11 * m21 + m12 * m22
        out[i, 5] = m20 * m20 + m21 * m21 + m22 * m22
    return out


@cached_njit(inline="always")
def _sh_colour(sh, i, degree, x, y, z, c):  # pragma: no cover - compiled
    """0.5 + sum_k sh[i, k, c] Y_k(x, y, z), clamped at 0; (x, y, z) a unit vector (gsplat's basis)."""
    r = 0.2820947917738781 * sh[i, 0, c]
    if degree >= 1:
        r += 0.48860251190292 * (-y * sh[i, 1, c] + z * sh[i, 2, c] - x * sh[i, 3, c])
        if degree >= 2:
            z2 = z * z
            t0b = -1.092548430592079 * z
            c1 = x * x - y * y
            s1 = 2.0 * x * y
            r += (0.5462742152960395 * s1 * sh[i, 4, c] + t0b * y * sh[i, 5, c]
                  + (0.9461746957575601 * z2 - 0.3153915652525201) * sh[i, 6, c]
                  + t0b * x * sh[i, 7, c] + 0.5462742152960395 * c1 * sh[i, 8, c])
            if degree >= 3:
                t0c = -2.285228997322329 * z2 + 0.4570457994644658
                t1b = 1.445305721320277 * z
                c2 = x * c1 - y * s1
                s2 = x * s1 + y * c1
                r += (-0.5900435899266435 * s2 * sh[i, 9, c] + t1b * s1 * sh[i, 10, c]
                      + t0c * y * sh[i, 11, c] + z * (1.865881662950577 * z2 - 1.119528997770346) * sh[i, 12, c]
                      + t0c * x * sh[i, 13, c] + t1b * c1 * sh[i, 14, c] - 0.5900435899266435 * c2 * sh[i, 15, c])
    return max(r + 0.5, 0.0)


@cached_njit(parallel=True)
def project_view(means, cov, opacities, sh, degree, vm, fx, fy, cx, cy, limits, width, height, tiles_x, tiles_y,
             records, boxes, depth):  # pragma: no cover - compiled
    """Project every Gaussian into one view (gsplat's frame: cx, cy already + 0.5; ``limits`` the
    Jacobian's clamp, :func:`.common.jacobian_limits`).

    Writes, per Gaussian, ``records`` (G, RECORD_FIELDS) float32 (mean 2D, conic (a, b, c) of
    [[a, b], [b, c]], opacity, colour, ellipse half-extents), ``boxes`` (G, 4) int32 the tiles
    [x0, x1) x [y0, y1) its box touches and ``depth`` (G,) float32, +inf where culled.
    """
    g = means.shape[0]
    r00, r01, r02, t0 = vm[0, 0], vm[0, 1], vm[0, 2], vm[0, 3]
    r10, r11, r12, t1 = vm[1, 0], vm[1, 1], vm[1, 2], vm[1, 3]
    r20, r21, r22, t2 = vm[2, 0], vm[2, 1], vm[2, 2], vm[2, 3]
    # camera centre -R^T t (viewmats are checked rigid)
    px = -(r00 * t0 + r10 * t1 + r20 * t2)
    py = -(r01 * t0 + r11 * t1 + r21 * t2)
    pz = -(r02 * t0 + r12 * t1 + r22 * t2)
    lim_x_pos, lim_x_neg, lim_y_pos, lim_y_neg = limits
    for i in prange(g):
        wx, wy, wz = np.float64(means[i, 0]), np.float64(means[i, 1]), np.float64(means[i, 2])
        x = r00 * wx + r01 * wy + r02 * wz + t0
        y = r10 * wx + r11 * wy + r12 * wz + t1
        z = r20 * wx + r21 * wy + r22 * wz + t2
        depth[i] = np.inf
        op = np.float64(opacities[i])
        if z < NEAR_PLANE or z > FAR_PLANE or op < ALPHA_MIN:
            continue
        # covariance in the camera frame: W C W^T, C symmetric (xx xy xz yy yz zz)
        cxx, cxy, cxz, cyy, cyz, czz = cov[i, 0], cov[i, 1], cov[i, 2], cov[i, 3], cov[i, 4], cov[i, 5]
        # rows of W C
        a00 = r00 * cxx + r01 * cxy + r02 * cxz
        a01 = r00 * cxy + r01 * cyy + r02 * cyz
        a02 = r00 * cxz + r01 * cyz + r02 * czz
        a10 = r10 * cxx + r11 * cxy + r12 * cxz
        a11 = r10 * cxy + r11 * cyy + r12 * cyz
        a12 = r10 * cxz + r11 * cyz + r12 * czz
        a20 = r20 * cxx + r21 * cxy + r22 * cxz
        a21 = r20 * cxy + r21 * cyy + r22 * cyz
        a22 = r20 * cxz + r21 * cyz + r22 * czz
        k00 = a00 * r00 + a01 * r01 + a02 * r02
        k01 = a00 * r10 + a01 * r11 + a02 * r12
        k02 = a00 * r20 + a01 * r21 + a02 * r22
        k11 = a10 * r10 + a11 * r11 + a12 * r12
        k12 = a10 * r20 + a11 * r21 + a12 * r22
        k22 = a20 * r20 + a21 * r21 + a22 * r22
        rz = 1.0 / z
        tx = z * min(lim_x_pos, max(-lim_x_neg, x * rz))
        ty = z * min(lim_y_pos, max(-lim_y_neg, y * rz))
        # J = [[j00, 0, j02], [0, j11, j12]]
        j00 = fx * rz
        j02 = -fx * tx * rz * rz
        j11 = fy * rz
        j12 = -fy * ty * rz * rz
        c00 = j00 * j00 * k00 + 2.0 * j00 * j02 * k02 + j02 * j02 * k22 + EPS2D
        c01 = j00 * j11 * k01 + j00 * j12 * k02 + j02 * j11 * k12 + j02 * j12 * k22
        c11 = j11 * j11 * k11 + 2.0 * j11 * j12 * k12 + j12 * j12 * k22 + EPS2D
        det = c00 * c11 - c01 * c01
        if not (det > 0.0 and c00 < COV_MAX and c11 < COV_MAX):  # NaN-safe; COV_MAX: see above
            continue
        extend = min(3.33, math.sqrt(2.0 * math.log(op / ALPHA_MIN)))
        rx = np.ceil(extend * math.sqrt(c00))
        ry = np.ceil(extend * math.sqrt(c11))
        if rx <= 0.0 and ry <= 0.0:
            continue
        u = fx * x * rz + cx
        v = fy * y * rz + cy
        if u + rx <= 0.0 or u - rx >= width or v + ry <= 0.0 or v - ry >= height:
            continue
        depth[i] = z
        records[i, REC_MX] = u
        records[i, REC_MY] = v
        records[i, REC_CA] = c11 / det
        records[i, REC_CB] = -c01 / det
        records[i, REC_CC] = c00 / det
        records[i, REC_OP] = op
        slim = math.log(op / ALPHA_MIN) + SIGMA_MARGIN
        records[i, REC_SLOPE] = c01 / c11
        records[i, REC_Q] = det / (c11 * c11)
        records[i, REC_EXT_Y] = math.sqrt(2.0 * slim * c11)
        # gsplat's tile box (IntersectTile.cu): [floor((u - rx) / ts), ceil((u + rx) / ts)) clamped
        boxes[i, 0] = int(min(max(np.floor((u - rx) / TILE_SIZE), 0.0), tiles_x))
        boxes[i, 1] = int(min(max(np.ceil((u + rx) / TILE_SIZE), 0.0), tiles_x))
        boxes[i, 2] = int(min(max(np.floor((v - ry) / TILE_SIZE), 0.0), tiles_y))
        boxes[i, 3] = int(min(max(np.ceil((v + ry) / TILE_SIZE), 0.0), tiles_y))
        dx, dy, dz = wx - px, wy - py, wz - pz
        n = math.sqrt(dx * dx + dy * dy + dz * dz)
        if n > 0.0:
            dx, dy, dz = dx / n, dy / n, dz / n
        for ch in range(3):
            records[i, REC_R + ch] = _sh_colour(sh, i, degree, dx, dy, dz, ch)


@cached_njit(parallel=True)
def bin_tiles(order, boxes, records, ntiles, tiles_x, chunks):  # pragma: no cover - compiled
    """Tile lists of the visible Gaussians ``order`` (front to back), a parallel counting sort.

    Returns (offsets (ntiles + 1,) int64, ids int32 ranks into ``order``, packed (n, RECORD_FIELDS)
    float32 records in rank order): tile t holds ids[offsets[t]:offsets[t + 1]], ascending = front
    to back.  ``chunks`` runs of ranks are counted and filled in parallel, each into its own slots.
    """
    n = order.shape[0]
    packed = np.empty((n, RECORD_FIELDS), dtype=np.float32)
    box = np.empty((n, 4), dtype=np.int32)
    for r in prange(n):
        i = order[r]
        for q in range(RECORD_FIELDS):  # element loops: row-slice assignment is several times slower here
            packed[r, q] = records[i, q]
        for q in range(4):
            box[r, q] = boxes[i, q]
    per = (n + chunks - 1) // chunks
    counts = np.zeros((chunks, ntiles), dtype=np.int64)
    for k in prange(chunks):
        for r in range(k * per, min(n, (k + 1) * per)):
            for ty in range(box[r, 2], box[r, 3]):
                for tx in range(box[r, 0], box[r, 1]):
                    counts[k, ty * tiles_x + tx] += 1
    offsets = np.empty(ntiles + 1, dtype=np.int64)
    total = 0
    for t in range(ntiles):  # tile-major, chunk-minor: chunk k's slots follow chunk k - 1's
        offsets[t] = total
        for k in range(chunks):
            c = counts[k, t]
            counts[k, t] = total
            total += c
    offsets[ntiles] = total
    ids = np.empty(total, dtype=np.int32)
    for k in prange(chunks):
        for r in range(k * per, min(n, (k + 1) * per)):
            for ty in range(box[r, 2], box[r, 3]):
                for tx in range(box[r, 0], box[r, 1]):
                    t = ty * tiles_x + tx
                    ids[counts[k, t]] = r
                    counts[k, t] += 1
    return offsets, ids, packed


def front_to_back(depth: np.ndarray, index: np.ndarray) -> np.ndarray:
    """Indices of the finite ``depth`` values, ascending, ties by index (gsplat's stable sort).

    Positive float32 sort like their bit patterns, so one uint64 key (bits << 32 | index) sorts
    both at once; culled Gaussians (+inf) go last and are dropped.
    """
    keys = np.sort((depth.view(np.uint32).astype(np.uint64) << np.uint64(32)) | index)
    visible = int(np.count_nonzero(depth < np.inf))
    return (keys[:visible] & np.uint64(0xFFFFFFFF)).astype(np.int64)
