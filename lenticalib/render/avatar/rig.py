"""Animated avatars: a rig (canonical Gaussians + blendshapes + bones), its control layout and its deformer.

A *control vector* drives the avatar, in the spirit of the LentiAvatar paper's grouped controls.
It is the concatenation of named groups in the order the rig file lists them; the default layout
(:data:`DEFAULT_LAYOUT`, what the demo avatar uses) is

    group        size  indices  meaning
    expression     50   0..49   blendshape weights (the demo avatar defines 0..9, see demo_avatar.py)
    jaw             3  50..52   jaw rotation, axis-angle radians; jaw[0] > 0 (about +x) opens the mouth
    neck            3  53..55   neck rotation, axis-angle radians, about the neck base
    head            3  56..58   rigid head pose rotation, axis-angle radians, about the pose pivot
    eyes            6  59..64   gaze: the avatar's left eye (+x side) then right eye, axis-angle radians
    eyelids         2  65..66   blink blendshapes, left then right: 0 open, 1 closed
    translation     3  67..69   rigid head pose translation, metres (the rig's units)
                         70 in all

Frames and units: world = the avatar's frame (metres, y up, facing +z for the demo; see
:mod:`.gaussians`); rotations are axis-angle vectors in radians (direction = axis, length =
angle, right-handed); "left" is the avatar's own left (+x when it faces +z).

Deformation (:meth:`Rig.deform`), in this order, from the canonical Gaussians (means x0, quats q0):

1. Blendshapes (canonical frame).  Blendshape e is driven by control ``blend_controls[e]`` with
   coefficient c_e; each entry n of the sparse table adds c_{shape[n]} * blend_pos[n] to the centre
   of Gaussian blend_index[n], likewise the optional small axis-angle ``blend_rot`` (summed per
   Gaussian, then turned into a rotation that pre-rotates the Gaussian's frame) and the optional
   ``blend_color`` (added to the DC SH coefficient).  Linear in the controls for positions and colour.
2. Linear blend skinning.  Bone b rotates by R_b (its 3 controls ``bone_controls[b]``, axis-angle,
   identity when -1) about its canonical pivot p_b, after its parent:
       M_b(x) = M_parent(b)( R_b (x - p_b) + p_b ),  M_root-parent = identity.
   Gaussian g with weights w_gb (row sum <= 1; the rest 1 - sum is bound to the unmoved rest frame)
   moves to  x = sum_b w_gb M_b(x1) + (1 - sum_b w_gb) x1  (blended affine maps), and its frame is
   rotated by the *quaternion blend*: the normalised weighted sum of the bones' world quaternions
   (each taken with w >= 0, plus the identity for the rest weight).  A Gaussian bound to one bone
   turns exactly with it; scales are not changed.
3. Rigid head pose, last: x = R_pose (x - pose_pivot) + pose_pivot + t, frames rotated by R_pose,
   from the ``pose_controls`` (rotation start, translation start; -1 = none).

(Steps 2 and 3 are computed together: the pose is composed into every bone's transform and the
rest frame's before the one blend, which gives the same result because the weights sum to 1.
Cost for 100k Gaussians on a CPU: about 10 ms on one core, 6 ms on two.)

Other rig files may lay the controls out differently (say 100 expression components, as in the
paper's 129-D vector): the groups, their sizes and which controls drive which blendshape, bone
and pose are all data in the file.

Degree-1 SH coefficients are rotated with each Gaussian's total rotation (they transform like a
vector); degree 2 and 3 coefficients are not rotated (view-dependent colour of those bands stays
fixed in the world; the demo avatar has degree 0).

The file that holds a rig (numpy ``.npz``: the arrays, their shapes and checks) is
:mod:`.rig_file`: :func:`~.rig_file.load_rig`, :func:`~.rig_file.save_rig`, :func:`~.rig_file.rig_from_arrays`.
"""

from __future__ import annotations

import dataclasses
import json
from typing import TYPE_CHECKING

import numpy as np

from ...core.files.documents import FORMATS, VERSION_KEY
from ...core.errors import InputError
from .gaussians import Gaussians
from .rig_deform import (apply_blended, quat_from_axis_angle, quat_multiply, quat_to_matrix, sparse_blend,
    with_rest_weight)

if TYPE_CHECKING:
    from .rig_mesh import RigMesh


@dataclasses.dataclass(frozen=True)
class ControlLayout:
    """Named control groups ``((name, size), ...)`` in control-vector order."""

    groups: tuple[tuple[str, int], ...]

    def __post_init__(self):
        names = [name for name, _ in self.groups]
        if len(set(names)) != len(names):
            raise InputError(f"control groups {names} repeat a name", source="control_groups")
        for name, size in self.groups:
            if not isinstance(name, str) or not name.isidentifier():
                raise InputError(f"control group name {name!r} is not an identifier", source="control_groups")
            if isinstance(size, bool) or not isinstance(size, (int, np.integer)) or size < 1:
                raise InputError(f"control group {name!r} has size {size!r}, expected >= 1",
                                 source="control_sizes")

    @property
    def dim(self) -> int:
        return int(sum(size for _, size in self.groups))

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(name for name, _ in self.groups)

    def __contains__(self, name: str) -> bool:
        return name in self.names

    def slice(self, name: str) -> slice:
        """Indices of group ``name`` in the control vector (KeyError when absent)."""
        start = 0
        for group, size in self.groups:
            if group == name:
                return slice(start, start + size)
            start += size
        raise KeyError(name)

    def size(self, name: str) -> int:
        s = self.slice(name)
        return s.stop - s.start

    def describe(self) -> str:
        """``"expression 50, jaw 3, ... (70 in all)"``, for error messages."""
        return ", ".join(f"{name} {size}" for name, size in self.groups) + f" ({self.dim} in all)"

    def default_names(self) -> tuple[str, ...]:
        return tuple(f"{name}.{i}" for name, size in self.groups for i in range(size))


DEFAULT_LAYOUT = ControlLayout((("expression", 50), ("jaw", 3), ("neck", 3), ("head", 3), ("eyes", 6),
                                ("eyelids", 2), ("translation", 3)))


DOCUMENT = FORMATS["lenticalib.rig"]


def envelope_arrays() -> dict[str, np.ndarray]:
    """The rig file's envelope as arrays: ``format`` (str) and ``format_version`` (int32)."""
    return {"format": np.array(DOCUMENT.name), VERSION_KEY: np.array(DOCUMENT.version, dtype=np.int32)}


class Rig:
    """A deformable avatar: canonical Gaussians, blendshapes, bones, a rigid pose (module docstring).

    Tensors live on one torch device (:attr:`device`, :meth:`to`).  Build one with
    :func:`~.rig_file.rig_from_arrays` or :func:`~.rig_file.load_rig`; :meth:`to_arrays` gives the file's arrays back.
    """

    def __init__(self, *, layout: ControlLayout, control_names: tuple[str, ...], canonical: Gaussians,
                 blend_controls, blend_index, blend_shape, blend_pos, blend_rot, blend_color,
                 bone_names: tuple[str, ...], bone_parents: tuple[int, ...], bone_pivots,
                 bone_controls: tuple[int, ...], skin_weights, pose_pivot, pose_controls: tuple[int, int],
                 provenance: dict, mesh: RigMesh | None = None):
        self.layout = layout
        self.control_names = tuple(control_names)
        self.canonical = canonical
        self.blend_controls = blend_controls
        self.blend_index = blend_index
        self.blend_shape = blend_shape
        self.blend_pos = blend_pos
        self.blend_rot = blend_rot
        self.blend_color = blend_color
        self.bone_names = tuple(bone_names)
        self.bone_parents = tuple(int(p) for p in bone_parents)
        self.bone_pivots = bone_pivots
        self.bone_controls = tuple(int(c) for c in bone_controls)
        self.skin_weights = skin_weights
        self.pose_pivot = pose_pivot
        self.pose_controls = (int(pose_controls[0]), int(pose_controls[1]))
        self.provenance = dict(provenance)
        self.mesh = mesh
        self._weights = with_rest_weight(skin_weights)
        self._any_bone = any(c >= 0 for c in self.bone_controls)

    # ---- properties

    @property
    def device(self):
        return self.canonical.means.device

    @property
    def control_dim(self) -> int:
        return self.layout.dim

    @property
    def count(self) -> int:
        return self.canonical.count

    @property
    def blendshape_count(self) -> int:
        return int(self.blend_controls.shape[0])

    def neutral_controls(self):
        """The zero control vector (D,) float32 on the rig's device: the canonical pose."""
        import torch

        return torch.zeros(self.control_dim, dtype=torch.float32, device=self.device)

    def to(self, device) -> "Rig":
        """This rig with every tensor on ``device`` (a torch device or its name)."""
        def move(t):
            return None if t is None else t.to(device)

        return Rig(layout=self.layout, control_names=self.control_names,
                   canonical=self.canonical.to_torch(str(device)),
                   blend_controls=move(self.blend_controls), blend_index=move(self.blend_index),
                   blend_shape=move(self.blend_shape), blend_pos=move(self.blend_pos),
                   blend_rot=move(self.blend_rot), blend_color=move(self.blend_color),
                   bone_names=self.bone_names, bone_parents=self.bone_parents,
                   bone_pivots=move(self.bone_pivots), bone_controls=self.bone_controls,
                   skin_weights=move(self.skin_weights), pose_pivot=move(self.pose_pivot),
                   pose_controls=self.pose_controls, provenance=self.provenance,
                   mesh=None if self.mesh is None else self.mesh.to(device))

    # ---- deformation

    def check_controls(self, controls, source: str = "controls"):
        """``controls`` as a float32 tensor (D,) or (T, D) on the rig's device; else one InputError."""
        import torch

        if not isinstance(controls, torch.Tensor):
            try:
                controls = torch.as_tensor(np.asarray(controls, dtype=np.float32))
            except (TypeError, ValueError):
                raise InputError("controls are not numbers", source=source,
                                 hint=f"expected {self.control_dim} values: {self.layout.describe()}") from None
        if controls.dim() not in (1, 2) or controls.shape[-1] != self.control_dim:
            got = f"{controls.shape[-1]} values" if controls.dim() in (1, 2) else f"shape {tuple(controls.shape)}"
            raise InputError(f"controls have {got}, expected (D,) or (T, D) with D = {self.control_dim}",
                             source=source, hint=f"layout: {self.layout.describe()}")
        return controls.to(device=self.device, dtype=torch.float32)

    def deform(self, controls) -> Gaussians:
        """The Gaussians posed by ``controls`` (D,) or (T, D): torch tensors on the rig's device.

        A (D,) vector gives fields shaped as :class:`Gaussians` documents; a (T, D) batch gives
        every field a leading T (means (T, G, 3), ..., opacities (T, G)).  Unchanged fields are
        expanded views of the canonical tensors, not copies: do not modify the result in place.
        Pure torch, no host synchronisation; controls are not checked for NaN.  A wrong length
        is an InputError naming the expected layout.
        """
        import torch

        c = self.check_controls(controls)
        batch = tuple(c.shape[:-1])
        can = self.canonical
        G = can.count
        means = can.means.expand(batch + (G, 3))
        rot = None  # the accumulated (..., G, 4) rotation applied to every frame, or None
        sh = can.sh

        # 1. blendshapes
        if self.blend_index.shape[0]:
            def blend(values):
                return sparse_blend(c, self.blend_controls, self.blend_index, self.blend_shape, values, G)

            means = blend(self.blend_pos) + can.means
            if self.blend_rot is not None:
                rot = quat_from_axis_angle(blend(self.blend_rot))
            if self.blend_color is not None:
                dc = blend(self.blend_color)
                sh = torch.cat(((can.sh[:, 0] + dc).unsqueeze(-2), can.sh[:, 1:].expand(batch + can.sh[:, 1:].shape)),
                               -2)

        # 2. linear blend skinning and 3. the rigid pose, folded together (:meth:`frame_transforms`)
        M = self.frame_transforms(c)
        if M is not None:
            A = self._weights @ M if self._any_bone else M               # (..., G, 16) or, all alike, (..., 1, 16)
            means = apply_blended(A, means)
            qb = A[..., 12:16]
            qb = qb * torch.rsqrt((qb * qb).sum(-1, keepdim=True))
            rot = qb if rot is None else quat_multiply(qb, rot)

        quats = can.quats.expand(batch + (G, 4)) if rot is None else quat_multiply(rot, can.quats)
        if rot is not None and sh.shape[-2] >= 4:
            # degree 1: colour(d) = C1 a.d with a = (-sh3, -sh1, sh2) per channel; rotating by R gives a' = R a
            R = quat_to_matrix(rot)                                       # (..., G, 3, 3)
            band = sh[..., 1:4, :]
            a = torch.stack((-band[..., 2, :], -band[..., 0, :], band[..., 1, :]), -2)  # (..., G, 3, 3ch)
            a = R @ a
            band = torch.stack((-a[..., 1, :], a[..., 2, :], -a[..., 0, :]), -2)
            sh = torch.cat((sh[..., :1, :].expand(batch + sh.shape[-3:-2] + (1, 3)), band,
                            sh[..., 4:, :].expand(batch + sh.shape[-3:-2] + (sh.shape[-2] - 4, 3))), -2)
        return Gaussians(means=means, quats=quats, scales=can.scales.expand(batch + (G, 3)),
                         opacities=can.opacities.expand(batch + (G,)), sh=sh.expand(batch + tuple(can.sh.shape)))

    def frame_transforms(self, c):
        """Every bone's world transform composed with the rigid pose, and the rest frame's, for
        controls c (..., D): (..., B + 1, 16) rows ``[R[:, 0], R[:, 1], R[:, 2], t, q]`` (the rest
        frame last), or None when the rig has neither bones nor a pose.  Blending them with weights
        that sum to 1 equals skinning then posing (the pose is affine); :func:`apply_blended` maps
        points with the blend."""
        import torch

        r0, t0 = self.pose_controls
        if not (self._any_bone or r0 >= 0 or t0 >= 0):
            return None
        batch = tuple(c.shape[:-1])
        one = torch.ones(batch + (1,), dtype=torch.float32, device=c.device)
        zero = torch.zeros(batch + (1,), dtype=torch.float32, device=c.device)
        Rr = torch.eye(3, dtype=torch.float32, device=c.device).expand(batch + (1, 3, 3))
        tr = torch.zeros(batch + (1, 3), dtype=torch.float32, device=c.device)
        qr = torch.cat((one, zero, zero, zero), -1).unsqueeze(-2)                 # (..., 1, 4)
        if self._any_bone:
            Rw, tw, qw = self._bone_world(c)                         # (..., B, 3, 3), (..., B, 3), (..., B, 4)
            Rr, tr, qr = torch.cat((Rw, Rr), -3), torch.cat((tw, tr), -2), torch.cat((qw, qr), -2)
        if r0 >= 0:
            qp = quat_from_axis_angle(c[..., r0:r0 + 3])             # (..., 4)
            Rp = quat_to_matrix(qp)
            tp = self.pose_pivot - (Rp @ self.pose_pivot.unsqueeze(-1)).squeeze(-1)
            Rr = Rp.unsqueeze(-3) @ Rr
            tr = (Rp.unsqueeze(-3) @ tr.unsqueeze(-1)).squeeze(-1) + tp.unsqueeze(-2)
            qr = quat_multiply(qp.unsqueeze(-2), qr)
        if t0 >= 0:
            tr = tr + c[..., t0:t0 + 3].unsqueeze(-2)
        return torch.cat((Rr.transpose(-1, -2).flatten(-2), tr, qr), -1)

    def pose_mesh(self, controls):
        """The rig's mesh (:mod:`.rig_mesh`) posed by ``controls`` (D,): vertices (V, 3) float32
        torch on the rig's device, world units; InputError naming ``mesh`` when the rig has none."""
        if self.mesh is None:
            raise InputError("the rig carries no mesh", source="mesh",
                             hint="give the avatar's mesh as `mesh` (OBJ or PLY triangles in the avatar's frame and units)")
        return self.mesh.pose(self, self.check_controls(controls))

    def _bone_world(self, c):
        """World rotation, translation and quaternion (w >= 0) of every bone for controls c (..., D)."""
        import torch

        batch = tuple(c.shape[:-1])
        Rs, ts, qs = [], [], []
        for b, parent in enumerate(self.bone_parents):
            k = self.bone_controls[b]
            if k >= 0:
                q = quat_from_axis_angle(c[..., k:k + 3])
            else:  # the identity, made on the device (no host-to-device copy per frame)
                q = c.new_zeros(batch + (4,))
                q[..., 0] = 1.0
            R = quat_to_matrix(q)
            p = self.bone_pivots[b]
            t = p - (R @ p.unsqueeze(-1)).squeeze(-1)
            if parent >= 0:
                q = quat_multiply(qs[parent], q)
                t = (Rs[parent] @ t.unsqueeze(-1)).squeeze(-1) + ts[parent]
                R = Rs[parent] @ R
            Rs.append(R)
            ts.append(t)
            qs.append(q)
        q = torch.stack(qs, -2)
        q = torch.where(q[..., :1] < 0, -q, q)
        return torch.stack(Rs, -3), torch.stack(ts, -2), q

    # ---- file arrays

    def to_arrays(self) -> dict[str, np.ndarray]:
        """The rig as the file's arrays (numpy, float32 / int32 / str), raw Gaussian parameters
        (:mod:`.rig_file` reads and writes them)."""
        g = self.canonical.to_numpy()
        eps = 1e-7
        op = np.clip(g.opacities.astype(np.float64), eps, 1 - eps)

        def arr(t, dtype=np.float32):
            return np.ascontiguousarray(t.detach().cpu().numpy(), dtype=dtype)

        out = {
            **envelope_arrays(), "means": g.means, "quats": g.quats, "log_scales": np.log(g.scales).astype(np.float32),
            "opacity_logits": np.log(op / (1 - op)).astype(np.float32), "sh": g.sh,
            "control_groups": np.array(self.layout.names, dtype=str),
            "control_sizes": np.array([s for _, s in self.layout.groups], dtype=np.int32),
            "control_dim": np.array(self.control_dim, dtype=np.int32),
            "control_names": np.array(self.control_names, dtype=str),
            "blend_controls": arr(self.blend_controls, np.int32), "blend_index": arr(self.blend_index, np.int32),
            "blend_shape": arr(self.blend_shape, np.int32), "blend_pos": arr(self.blend_pos),
            "bone_names": np.array(self.bone_names, dtype=str).reshape(-1),
            "bone_parents": np.array(self.bone_parents, dtype=np.int32).reshape(-1),
            "bone_pivots": arr(self.bone_pivots).reshape(-1, 3),
            "bone_controls": np.array(self.bone_controls, dtype=np.int32).reshape(-1),
            "skin_weights": arr(self.skin_weights), "pose_pivot": arr(self.pose_pivot),
            "pose_controls": np.array(self.pose_controls, dtype=np.int32),
            "provenance": np.array(json.dumps(self.provenance, sort_keys=True)),
        }
        if self.blend_rot is not None:
            out["blend_rot"] = arr(self.blend_rot)
        if self.blend_color is not None:
            out["blend_color"] = arr(self.blend_color)
        if self.mesh is not None:
            out.update(self.mesh.to_arrays())
        return out
