"""The mesh mask: which pixels of each view an avatar's triangle mesh covers.

:func:`mesh_masks` projects the mesh with the very cameras the views are rendered with
(:class:`~.cameras.ViewCameras`: OpenCV pinhole ``K``, world-to-camera ``viewmats``, pixel
centres at integer coordinates) and marks a pixel when its centre lies inside a projected
triangle, edges included.  The projection is exact (a triangle of the mesh projects to a
triangle of the image); the only approximation is the pixel grid (coverage tested at each
pixel's centre, no partial coverage).  Parts of triangles nearer than the renderers' near plane
(:data:`~.cameras.view_cameras.NEAR_PLANE`) are clipped away, as the renderers drop Gaussians there.

numba, parallel over the views; about 0.1 s for 32 views of 960 x 540 and 60k triangles on two
cores (the time grows with the pixels covered, not with the image size).
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

from ..cameras.view_cameras import NEAR_PLANE


@nb.njit(cache=True, inline="always")
def _fill(mask, ax, ay, bx, by, cx, cy):
    """Mark every pixel of ``mask`` (H, W) whose centre lies in triangle a, b, c (pixels)."""
    H, W = mask.shape
    area = (bx - ax) * (cy - ay) - (by - ay) * (cx - ax)
    if area == 0.0:
        return
    s = 1.0 if area > 0 else -1.0
    x0 = max(int(math.ceil(min(ax, bx, cx))), 0)
    x1 = min(int(math.floor(max(ax, bx, cx))), W - 1)
    y0 = max(int(math.ceil(min(ay, by, cy))), 0)
    y1 = min(int(math.floor(max(ay, by, cy))), H - 1)
    for y in range(y0, y1 + 1):
        for x in range(x0, x1 + 1):
            w0 = s * ((bx - ax) * (y - ay) - (by - ay) * (x - ax))
            w1 = s * ((cx - bx) * (y - by) - (cy - by) * (x - bx))
            w2 = s * ((ax - cx) * (y - cy) - (ay - cy) * (x - cx))
            if w0 >= 0.0 and w1 >= 0.0 and w2 >= 0.0:
                mask[y, x] = True


@nb.njit(parallel=True, cache=True)
def _masks(cam_vertices, triangles, Ks, near, out):
    """cam_vertices (N, V, 3) camera frame; triangles (F, 3); Ks (N, 3, 3); out (N, H, W) bool."""
    N = cam_vertices.shape[0]
    F = triangles.shape[0]
    for n in nb.prange(N):
        fx, sk, cxp = Ks[n, 0, 0], Ks[n, 0, 1], Ks[n, 0, 2]
        fy, cyp = Ks[n, 1, 1], Ks[n, 1, 2]
        poly = np.empty((4, 3))
        pix = np.empty((4, 2))
        for f in range(F):
            # clip the triangle to z >= near (Sutherland-Hodgman against one plane: <= 4 corners)
            m = 0
            for k in range(3):
                p = cam_vertices[n, triangles[f, k]]
                q = cam_vertices[n, triangles[f, (k + 1) % 3]]
                p_in = p[2] >= near
                q_in = q[2] >= near
                if p_in:
                    poly[m, 0], poly[m, 1], poly[m, 2] = p[0], p[1], p[2]
                    m += 1
                if p_in != q_in:
                    t = (near - p[2]) / (q[2] - p[2])
                    poly[m, 0] = p[0] + t * (q[0] - p[0])
                    poly[m, 1] = p[1] + t * (q[1] - p[1])
                    poly[m, 2] = near
                    m += 1
            if m < 3:
                continue
            for k in range(m):
                z = poly[k, 2]
                pix[k, 0] = fx * poly[k, 0] / z + sk * poly[k, 1] / z + cxp
                pix[k, 1] = fy * poly[k, 1] / z + cyp
            for k in range(1, m - 1):
                _fill(out[n], pix[0, 0], pix[0, 1], pix[k, 0], pix[k, 1], pix[k + 1, 0], pix[k + 1, 1])


def mesh_masks(vertices: np.ndarray, triangles: np.ndarray, viewmats: np.ndarray, Ks: np.ndarray,
               width: int, height: int) -> np.ndarray:
    """(N, H, W) bool: pixel (y, x) of view n is True when its centre lies inside the projection
    of a triangle of the mesh (module docstring).

    ``vertices`` (V, 3) world units, ``triangles`` (F, 3) vertex indices, ``viewmats`` (N, 4, 4)
    world-to-camera (OpenCV: x right, y down, z forward), ``Ks`` (N, 3, 3) pixels.
    """
    v = np.asarray(vertices, dtype=np.float64)
    vm = np.asarray(viewmats, dtype=np.float64)
    cam = np.einsum("nij,vj->nvi", vm[:, :3, :3], v) + vm[:, None, :3, 3]
    out = np.zeros((len(vm), int(height), int(width)), dtype=np.bool_)
    _masks(np.ascontiguousarray(cam), np.ascontiguousarray(triangles, dtype=np.int64),
           np.ascontiguousarray(Ks, dtype=np.float64), float(NEAR_PLANE), out)
    return out
