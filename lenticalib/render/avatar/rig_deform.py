"""The deformation kernels a rig and its mesh share (torch, batched over leading dimensions):
quaternions, blendshape sums and blended bone transforms (:class:`~.rig.Rig`, :class:`~.rig_mesh.RigMesh`).
"""

from __future__ import annotations


# --------------------------------------------------------------------------------------------
# torch helpers (batched over leading dimensions)

def quat_multiply(a, b):
    """Hamilton product a * b of (..., 4) (w, x, y, z) quaternions (broadcasting)."""
    import torch

    aw, ax, ay, az = a.unbind(-1)
    bw, bx, by, bz = b.unbind(-1)
    return torch.stack((aw * bw - ax * bx - ay * by - az * bz,
                        aw * bx + ax * bw + ay * bz - az * by,
                        aw * by - ax * bz + ay * bw + az * bx,
                        aw * bz + ax * by - ay * bx + az * bw), -1)


def quat_from_axis_angle(v):
    """(..., 3) axis-angle (radians) -> (..., 4) unit quaternions (w >= 0 for angles <= pi)."""
    import torch

    theta = torch.sqrt((v * v).sum(-1, keepdim=True) + 1e-30)
    half = 0.5 * theta
    # sin(theta/2)/theta = 0.5 sinc(theta / (2 pi)) with torch.sinc(x) = sin(pi x)/(pi x): exact at 0
    return torch.cat((torch.cos(half), v * (0.5 * torch.sinc(theta / (2 * torch.pi)))), -1)


def quat_to_matrix(q):
    """(..., 4) unit quaternions -> (..., 3, 3) rotation matrices."""
    import torch

    w, x, y, z = q.unbind(-1)
    return torch.stack((1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y),
                        2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x),
                        2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)),
                       -1).reshape(q.shape[:-1] + (3, 3))


# --------------------------------------------------------------------------------------------

def with_rest_weight(skin_weights):
    """Skinning weights (..., B) with the rest frame's weight as a last column, (..., B + 1), rows
    summing to 1 (rows that sum a hair over 1, within the loader's tolerance, are scaled down)."""
    import torch

    w = skin_weights / skin_weights.sum(-1, keepdim=True).clamp(min=1.0)
    return torch.cat((w, (1.0 - w.sum(-1, keepdim=True)).clamp(min=0.0)), -1).contiguous()


def sparse_blend(c, blend_controls, index, shape, values, count: int):
    """Sum of blendshape entries for controls c (..., D): entry n adds c[blend_controls[shape[n]]]
    * values[n] (N, 3) to row index[n]; (..., count, 3) float32 torch."""
    import torch

    coeff = c[..., blend_controls][..., shape].unsqueeze(-1)              # (..., N, 1)
    batch = tuple(c.shape[:-1])
    return torch.zeros(batch + (count, 3), dtype=torch.float32, device=c.device).index_add_(
        len(batch), index, coeff * values)


def apply_blended(A, x):
    """Points x (..., P, 3) mapped by blended transform rows A (..., P or 1, 16) of
    :meth:`.rig.Rig.frame_transforms` (the rotation's columns, then the translation)."""
    return A[..., 0:3] * x[..., 0:1] + A[..., 3:6] * x[..., 1:2] + A[..., 6:9] * x[..., 2:3] + A[..., 9:12]
