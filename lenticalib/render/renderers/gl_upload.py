"""What the ``gl`` renderer (:mod:`.gl_renderer`) computes on the host and uploads.

:func:`pack_gaussians` and :func:`camera_table` build the GAUSS and CAMS buffers of
:mod:`.gl_shaders` (the GPU sort's path); :func:`host_records` and :func:`record_table` are the CPU
sort's path: the ``cpu`` renderer's own projection and depth order, per view, and the record
texture they are drawn from.
"""

from __future__ import annotations

import numpy as np

from ..avatar.gaussians import Gaussians
from .common import TILE_SIZE, jacobian_limits
from .cpu_project import RECORD_FIELDS, front_to_back, project_view, world_covariances


def camera_table(viewmats: np.ndarray, Ks: np.ndarray, width: int, height: int) -> np.ndarray:
    """(N, 6, 4) float32, the CAMS buffer of :mod:`.gl_shaders`: rows of [R t], (fx, fy, cx + 0.5,
    cy + 0.5), the camera centre -R^T t, and gsplat's clamp limits of J (as :func:`.project_view`)."""
    n = viewmats.shape[0]
    rot, t = viewmats[:, :3, :3], viewmats[:, :3, 3]
    fx, fy = Ks[:, 0, 0], Ks[:, 1, 1]
    cx, cy = Ks[:, 0, 2] + 0.5, Ks[:, 1, 2] + 0.5
    out = np.zeros((n, 6, 4))
    out[:, :3, :3], out[:, :3, 3] = rot, t
    out[:, 3] = np.stack([fx, fy, cx, cy], axis=1)
    out[:, 4, :3] = -np.einsum("nji,nj->ni", rot, t)
    out[:, 5] = np.stack(jacobian_limits(width, height, fx, fy, cx, cy), axis=1)
    return out.astype(np.float32)


def pack_gaussians(g: Gaussians) -> np.ndarray:
    """(G, 10 + 3 K) float32, the GAUSS buffer of :mod:`.gl_shaders` (``g`` numpy)."""
    k = g.sh.shape[1]
    out = np.empty((g.count, 10 + 3 * k), dtype=np.float32)
    out[:, :3] = g.means
    out[:, 3] = g.opacities
    out[:, 4:10] = world_covariances(g.quats, g.scales)
    out[:, 10:] = g.sh.reshape(g.count, 3 * k)
    return out


def host_records(g: Gaussians, viewmats: np.ndarray, Ks: np.ndarray, width: int, height: int) -> list[np.ndarray]:
    """Per view, the records (:mod:`.cpu_project`'s layout, (n_v, 12) float32) of its visible
    Gaussians front to back: the ``cpu`` renderer's :func:`.project_view` and :func:`.front_to_back`
    (``g`` numpy, OpenCV ``Ks``: + 0.5 to cx, cy here)."""
    count = g.count
    cov = world_covariances(g.quats, g.scales)
    tiles_x, tiles_y = -(-width // TILE_SIZE), -(-height // TILE_SIZE)
    records = np.empty((count, RECORD_FIELDS), dtype=np.float32)
    boxes = np.empty((count, 4), dtype=np.int32)
    depth = np.empty(count, dtype=np.float32)
    index = np.arange(count, dtype=np.uint64)
    drawn = []
    for view in range(viewmats.shape[0]):
        k = Ks[view]
        fx, fy, cx, cy = k[0, 0], k[1, 1], k[0, 2] + 0.5, k[1, 2] + 0.5
        project_view(g.means, cov, g.opacities, g.sh, g.sh_degree, viewmats[view], fx, fy, cx, cy,
                     jacobian_limits(width, height, fx, fy, cx, cy), width, height, tiles_x, tiles_y,
                     records, boxes, depth)
        drawn.append(records[front_to_back(depth, index)])
    return drawn


def record_table(drawn: list[np.ndarray], per_row: int) -> np.ndarray:
    """(rows, 3 per_row, 4) float32: the records of every view one after another, ``per_row`` a
    row (3 RGBA texels each), zeros after the last: the CPU sort's record texture."""
    total = sum(len(d) for d in drawn)
    table = np.zeros((-(-total // per_row) * per_row, RECORD_FIELDS), dtype=np.float32)
    np.concatenate(drawn, out=table[:total])
    return table.reshape(-1, 3 * per_row, 4)
