"""The mesh a rig may carry: its triangles, skinned and blendshaped like the Gaussians.

FLAME-based avatars (GaussianAvatars, FlashAvatar and similar) bind their Gaussians to a head
mesh; the side-view diagnostics (:mod:`.diagnose`) need that mesh posed by the same controls.
A rig file (:mod:`.rig_file`) holds it in these optional arrays (all or none of the first three;
V vertices, F triangles, B bones, E blendshapes, M blendshape entries):

    mesh_vertices      (V, 3)  float  canonical vertices, world units
    mesh_triangles     (F, 3)  int    vertex indices, F >= 1
    mesh_skin_weights  (V, B)  float  in [0, 1], row sums <= 1, the bones of the rig
    mesh_blend_index   (M,)    int    optional: vertex of entry m
    mesh_blend_shape   (M,)    int    blendshape of entry m (0..E-1), the rig's blendshapes
    mesh_blend_pos     (M, 3)  float  vertex offset per unit control, world units

The vertices are deformed exactly as the Gaussians' centres are (:meth:`.rig.Rig.deform`):
blendshapes, then linear blend skinning and the rigid pose (:meth:`.rig.Rig.frame_transforms`).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ...core.errors import InputError
from .mesh import check_mesh
from .rig_deform import apply_blended, sparse_blend, with_rest_weight

MESH_ARRAYS = ("mesh_vertices", "mesh_triangles", "mesh_skin_weights")
MESH_BLEND_ARRAYS = ("mesh_blend_index", "mesh_blend_shape", "mesh_blend_pos")


class RigMesh:
    """A rig's mesh: ``vertices`` (V, 3) and ``skin_weights`` (V, B) float32 torch,
    ``triangles`` (F, 3) int64 numpy, the blend entries torch (module docstring)."""

    def __init__(self, vertices, triangles: np.ndarray, skin_weights, blend_index, blend_shape, blend_pos):
        self.vertices = vertices
        self.triangles = triangles
        self.skin_weights = skin_weights
        self.blend_index = blend_index
        self.blend_shape = blend_shape
        self.blend_pos = blend_pos
        self._weights = with_rest_weight(skin_weights)

    @property
    def count(self) -> int:
        return int(self.vertices.shape[0])

    def to(self, device) -> "RigMesh":
        return RigMesh(self.vertices.to(device), self.triangles, self.skin_weights.to(device),
                       self.blend_index.to(device), self.blend_shape.to(device), self.blend_pos.to(device))

    def pose(self, rig, c):
        """Vertices (V, 3) float32 torch posed by the :class:`~.rig.Rig` ``rig``'s controls c (D,), world units."""
        x = self.vertices
        if self.blend_index.shape[0]:
            x = x + sparse_blend(c, rig.blend_controls, self.blend_index, self.blend_shape, self.blend_pos, self.count)
        M = rig.frame_transforms(c)
        if M is None:
            return x
        return apply_blended(self._weights @ M, x)

    def to_arrays(self) -> dict[str, np.ndarray]:
        """The file's arrays (module docstring)."""
        def arr(t, dtype=np.float32):
            return np.ascontiguousarray(t.detach().cpu().numpy(), dtype=dtype)

        return {"mesh_vertices": arr(self.vertices), "mesh_triangles": self.triangles.astype(np.int32),
                "mesh_skin_weights": arr(self.skin_weights), "mesh_blend_index": arr(self.blend_index, np.int32),
                "mesh_blend_shape": arr(self.blend_shape, np.int32), "mesh_blend_pos": arr(self.blend_pos)}


def mesh_from_arrays(arrays: dict[str, Any], bones: int, blendshapes: int, source: str,
                     device: str = "cpu") -> RigMesh | None:
    """The rig's mesh from the file's arrays (None when it has none); one InputError naming
    ``source`` and the array for a wrong shape, index or weight."""
    import torch

    present = [k for k in MESH_ARRAYS if k in arrays]
    if not present:
        return None
    if len(present) != len(MESH_ARRAYS):
        missing = sorted(set(MESH_ARRAYS) - set(present))
        raise InputError(f"the rig has {', '.join(present)} but not {', '.join(missing)}", source=source,
                         hint="a rig's mesh needs " + ", ".join(MESH_ARRAYS))
    try:
        mesh = check_mesh(np.asarray(arrays["mesh_vertices"]), np.asarray(arrays["mesh_triangles"]), source)
    except InputError as exc:
        raise InputError(f"array 'mesh_triangles': {exc.message}", source=source, hint=exc.hint) from None
    V = len(mesh.vertices)
    weights = np.asarray(arrays["mesh_skin_weights"], dtype=np.float64)
    if weights.shape != (V, bones):
        raise InputError(f"array 'mesh_skin_weights' has shape {weights.shape}, expected ({V}, {bones})",
                         source=source)
    if not np.isfinite(weights).all() or (weights < -1e-6).any() or (weights.sum(1) > 1 + 1e-4).any():
        raise InputError("array 'mesh_skin_weights' has weights that are not >= 0 or rows summing to more than 1",
                         source=source)
    blend = [k for k in MESH_BLEND_ARRAYS if k in arrays]
    if blend and len(blend) != len(MESH_BLEND_ARRAYS):
        raise InputError(f"the rig has {', '.join(blend)} but not all of {', '.join(MESH_BLEND_ARRAYS)}",
                         source=source)
    if blend:
        index = np.asarray(arrays["mesh_blend_index"])
        shape = np.asarray(arrays["mesh_blend_shape"])
        pos = np.asarray(arrays["mesh_blend_pos"], dtype=np.float64)
        M = index.shape[0] if index.ndim == 1 else -1
        if (M < 0 or index.dtype.kind not in "iu" or shape.shape != (M,) or shape.dtype.kind not in "iu"
                or pos.shape != (M, 3)):
            raise InputError(f"arrays 'mesh_blend_*' have shapes {index.shape}, {shape.shape}, {pos.shape}, "
                             "expected (M,), (M,) integers and (M, 3)", source=source)
        if M and (index.min() < 0 or index.max() >= V or shape.min() < 0 or shape.max() >= blendshapes):
            raise InputError(f"array 'mesh_blend_index' or 'mesh_blend_shape' points past the {V} vertices or "
                             f"the {blendshapes} blendshapes", source=source)
        if not np.isfinite(pos).all():
            raise InputError("array 'mesh_blend_pos' is not finite", source=source)
    else:
        index, shape, pos = np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros((0, 3))

    def t(a, dtype=torch.float32):
        return torch.from_numpy(np.ascontiguousarray(a)).to(device=device, dtype=dtype)

    return RigMesh(t(mesh.vertices), mesh.triangles, t(weights), t(index, torch.long), t(shape, torch.long), t(pos))
