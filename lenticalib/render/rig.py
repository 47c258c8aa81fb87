"""Animated avatars: a rig file (canonical Gaussians + blendshapes + bones) and its deformer.

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

The file (numpy ``.npz``, no pickled objects; :func:`save_rig` writes it compressed, atomically).
G Gaussians, K SH coefficients, D controls, E blendshapes, N blendshape entries, B bones:

    format          ()        str    "lenticalib-rig"
    version         ()        int    1 (:data:`RIG_VERSION`)
    means           (G, 3)    float  canonical centres, world units
    quats           (G, 4)    float  canonical rotations (w, x, y, z), any non-zero length
    log_scales      (G, 3)    float  log of the standard deviations (raw, as the 3DGS PLY)
    opacity_logits  (G,)      float  logit of the opacities (raw, as the 3DGS PLY)
    sh              (G, K, 3) float  SH coefficients, DC first, K in 1, 4, 9, 16 (as Gaussians.sh)
    control_groups  (NG,)     str    group names, in control-vector order
    control_sizes   (NG,)     int    their sizes
    control_dim     ()        int    D = sum(control_sizes)
    control_names   (D,)      str    a name per control component ("expression.smile", "jaw.x")
    blend_controls  (E,)      int    control index driving blendshape e
    blend_index     (N,)      int    Gaussian of entry n
    blend_shape     (N,)      int    blendshape of entry n (0..E-1)
    blend_pos       (N, 3)    float  centre offset per unit control, world units
    blend_rot       (N, 3)    float  optional: axis-angle offset per unit control, radians
    blend_color     (N, 3)    float  optional: DC SH offset per unit control
    bone_names      (B,)      str
    bone_parents    (B,)      int    parent bone index, -1 for a root; a parent precedes its children
    bone_pivots     (B, 3)    float  canonical pivot points, world units
    bone_controls   (B,)      int    first of the bone's 3 rotation controls, -1 for none
    skin_weights    (G, B)    float  in [0, 1], row sums <= 1
    pose_pivot      (3,)      float  pivot of the rigid head pose, world units
    pose_controls   (2,)      int    first rotation control and first translation control (3 each), -1 = none
    provenance      ()        str    a JSON object: what made the file, with which parameters

Floats may be stored as float16/32/64 and are used as float32; a missing array (other than the
two optional ones), a wrong shape or index, a non-finite value or another version is one
InputError naming the file and the array.
"""

from __future__ import annotations

import dataclasses
import io
import json
import os
import zipfile
from typing import Any

import numpy as np

from ..atomic import write_bytes_atomic
from ..errors import InputError
from .gaussians import Gaussians

RIG_FORMAT = "lenticalib-rig"
RIG_VERSION = 1


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

_REQUIRED = ("format", "version", "means", "quats", "log_scales", "opacity_logits", "sh", "control_groups",
             "control_sizes", "control_dim", "control_names", "blend_controls", "blend_index", "blend_shape",
             "blend_pos", "bone_names", "bone_parents", "bone_pivots", "bone_controls", "skin_weights",
             "pose_pivot", "pose_controls", "provenance")
_OPTIONAL = ("blend_rot", "blend_color")


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

class Rig:
    """A deformable avatar: canonical Gaussians, blendshapes, bones, a rigid pose (module docstring).

    Tensors live on one torch device (:attr:`device`, :meth:`to`).  Build one with
    :func:`rig_from_arrays` or :func:`load_rig`; :meth:`to_arrays` gives the file's arrays back.
    """

    def __init__(self, *, layout: ControlLayout, control_names: tuple[str, ...], canonical: Gaussians,
                 blend_controls, blend_index, blend_shape, blend_pos, blend_rot, blend_color,
                 bone_names: tuple[str, ...], bone_parents: tuple[int, ...], bone_pivots,
                 bone_controls: tuple[int, ...], skin_weights, pose_pivot, pose_controls: tuple[int, int],
                 provenance: dict):
        import torch

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
        # weights with the rest frame as a last column, (G, B + 1), rows summing to 1 (rows that
        # sum a hair over 1, within the loader's tolerance, are scaled down)
        w = skin_weights / skin_weights.sum(-1, keepdim=True).clamp(min=1.0)
        self._weights = torch.cat((w, (1.0 - w.sum(-1, keepdim=True)).clamp(min=0.0)), -1).contiguous()
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
                   pose_controls=self.pose_controls, provenance=self.provenance)

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
            coeff = c[..., self.blend_controls][..., self.blend_shape].unsqueeze(-1)  # (..., N, 1)
            dim = len(batch)
            means = torch.zeros(batch + (G, 3), dtype=torch.float32, device=c.device).index_add_(
                dim, self.blend_index, coeff * self.blend_pos) + can.means
            if self.blend_rot is not None:
                omega = torch.zeros(batch + (G, 3), dtype=torch.float32, device=c.device).index_add_(
                    dim, self.blend_index, coeff * self.blend_rot)
                rot = quat_from_axis_angle(omega)
            if self.blend_color is not None:
                dc = torch.zeros(batch + (G, 3), dtype=torch.float32, device=c.device).index_add_(
                    dim, self.blend_index, coeff * self.blend_color)
                sh = torch.cat(((can.sh[:, 0] + dc).unsqueeze(-2), can.sh[:, 1:].expand(batch + can.sh[:, 1:].shape)),
                               -2)

        # 2. linear blend skinning and 3. the rigid pose, folded together: every bone's world
        # transform (and the rest frame's identity) is composed with the pose, then blended once
        # (the pose is affine and the weights sum to 1, so this equals skinning then posing)
        r0, t0 = self.pose_controls
        if self._any_bone or r0 >= 0 or t0 >= 0:
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
            # rows [R[:, 0], R[:, 1], R[:, 2], t, q]: (..., B + 1, 16), blended per Gaussian in one product
            M = torch.cat((Rr.transpose(-1, -2).flatten(-2), tr, qr), -1)
            A = self._weights @ M if self._any_bone else M               # (..., G, 16) or, all alike, (..., 1, 16)
            x = means
            means = (A[..., 0:3] * x[..., 0:1] + A[..., 3:6] * x[..., 1:2] + A[..., 6:9] * x[..., 2:3]
                     + A[..., 9:12])
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
        """The rig as the file's arrays (numpy, float32 / int32 / str), raw Gaussian parameters."""
        g = self.canonical.to_numpy()
        eps = 1e-7
        op = np.clip(g.opacities.astype(np.float64), eps, 1 - eps)

        def arr(t, dtype=np.float32):
            return np.ascontiguousarray(t.detach().cpu().numpy(), dtype=dtype)

        out = {
            "format": np.array(RIG_FORMAT), "version": np.array(RIG_VERSION, dtype=np.int32),
            "means": g.means, "quats": g.quats, "log_scales": np.log(g.scales).astype(np.float32),
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
        return out


# --------------------------------------------------------------------------------------------
# building, loading, saving

def rig_from_arrays(arrays: dict[str, Any], source: str = "rig", device: str = "cpu") -> Rig:
    """Validate the file's arrays (module docstring) and build a :class:`Rig` on ``device``.

    Raw Gaussian parameters are activated here (exp, sigmoid, normalised quaternions).  Every
    problem is one InputError naming ``source`` and the array.
    """
    import torch

    def need(name):
        if name not in arrays:
            raise InputError(f"array {name!r} is missing", source=source,
                             hint="a rig file holds: " + " ".join(_REQUIRED))
        return np.asarray(arrays[name])

    def floats(name, shape, *, optional=False):
        if optional and name not in arrays:
            return None
        a = need(name)
        if a.dtype.kind not in "fiu":
            raise InputError(f"array {name!r} has dtype {a.dtype}, expected floats", source=source)
        if a.shape != shape:
            raise InputError(f"array {name!r} has shape {a.shape}, expected {shape}", source=source)
        a = a.astype(np.float32)
        if a.size and not np.isfinite(a).all():
            where = np.argwhere(~np.isfinite(a))[0]
            raise InputError(f"array {name!r} holds a non-finite value (NaN or inf) at {tuple(int(i) for i in where)}",
                             source=source)
        return a

    def ints(name, shape, lo, hi, what):
        a = need(name)
        if a.dtype.kind not in "iu":
            raise InputError(f"array {name!r} has dtype {a.dtype}, expected integers", source=source)
        if a.shape != shape:
            raise InputError(f"array {name!r} has shape {a.shape}, expected {shape}", source=source)
        a = a.astype(np.int64)
        bad = (a < lo) | (a > hi)
        if bad.any():
            i = int(np.argwhere(bad)[0][0]) if a.ndim else 0
            raise InputError(f"array {name!r} holds {int(a.reshape(-1)[i])} at {i}, expected {what} in {lo}..{hi}",
                             source=source)
        return a

    def strings(name, n=None):
        a = need(name)
        if a.dtype.kind != "U" or (n is not None and a.shape != (n,)) or (n is None and a.ndim != 1):
            raise InputError(f"array {name!r} has shape {a.shape} dtype {a.dtype}, expected "
                             f"({'N' if n is None else n},) strings", source=source)
        return tuple(str(s) for s in a)

    fmt = need("format")
    if fmt.shape != () or fmt.dtype.kind != "U" or str(fmt) != RIG_FORMAT:
        raise InputError(f"not a rig file (format {fmt!r})", source=source,
                         hint=f"expected format {RIG_FORMAT!r}; make one with tools/make_demo_avatar.py")
    version = need("version")
    if version.shape != () or version.dtype.kind not in "iu" or int(version) != RIG_VERSION:
        raise InputError(f"rig format version {version}, this lenticalib reads version {RIG_VERSION}",
                         source=source, hint="re-export the rig with a matching lenticalib")

    means = need("means")
    if means.ndim != 2 or means.shape[1] != 3 or means.shape[0] < 1:
        raise InputError(f"array 'means' has shape {means.shape}, expected (G, 3) with G >= 1", source=source)
    G = means.shape[0]
    means = floats("means", (G, 3))
    quats = floats("quats", (G, 4))
    qn = np.linalg.norm(quats, axis=1)
    if (qn < 1e-12).any():
        raise InputError(f"array 'quats' has a zero-length quaternion in row {int(np.argmin(qn))}", source=source)
    log_scales = floats("log_scales", (G, 3))
    if (log_scales > 80).any():
        raise InputError("array 'log_scales' overflows exp()", source=source)
    logits = floats("opacity_logits", (G,))
    sh = need("sh")
    if sh.ndim != 3 or sh.shape[0] != G or sh.shape[2] != 3 or sh.shape[1] not in (1, 4, 9, 16):
        raise InputError(f"array 'sh' has shape {sh.shape}, expected ({G}, K, 3) with K in 1, 4, 9, 16",
                         source=source)
    sh = floats("sh", sh.shape)

    groups = strings("control_groups")
    sizes = ints("control_sizes", (len(groups),), 1, 1 << 20, "group sizes")
    try:
        layout = ControlLayout(tuple(zip(groups, (int(s) for s in sizes))))
    except InputError as exc:
        raise InputError(exc.message, source=source) from None
    D = layout.dim
    dim = need("control_dim")
    if dim.shape != () or dim.dtype.kind not in "iu" or int(dim) != D:
        raise InputError(f"array 'control_dim' is {dim}, but the groups add up to {D} ({layout.describe()})",
                         source=source)
    names = strings("control_names", D)
    if len(set(names)) != D:
        raise InputError("array 'control_names' repeats a name", source=source)

    bc = need("blend_controls")
    E = bc.shape[0] if bc.ndim == 1 else -1
    if E < 0:
        raise InputError(f"array 'blend_controls' has shape {bc.shape}, expected (E,)", source=source)
    blend_controls = ints("blend_controls", (E,), 0, D - 1, "control indices")
    bi = need("blend_index")
    N = bi.shape[0] if bi.ndim == 1 else -1
    if N < 0:
        raise InputError(f"array 'blend_index' has shape {bi.shape}, expected (N,)", source=source)
    blend_index = ints("blend_index", (N,), 0, G - 1, "Gaussian indices")
    blend_shape = ints("blend_shape", (N,), 0, E - 1, "blendshape indices")
    blend_pos = floats("blend_pos", (N, 3))
    blend_rot = floats("blend_rot", (N, 3), optional=True)
    blend_color = floats("blend_color", (N, 3), optional=True)

    bone_names = strings("bone_names")
    B = len(bone_names)
    parents = ints("bone_parents", (B,), -1, max(B - 1, -1), "parent indices")
    for b, p in enumerate(parents):
        if p >= b:
            raise InputError(f"bone {bone_names[b]!r} has parent {p}, which does not precede it", source=source,
                             hint="list parents before their children")
    pivots = floats("bone_pivots", (B, 3))
    bone_controls = ints("bone_controls", (B,), -1, D - 3, "first-control indices")
    weights = floats("skin_weights", (G, B))
    if weights.size and ((weights < -1e-6).any() or (weights.sum(1) > 1 + 1e-4).any()):
        row = int(np.argmax((weights < -1e-6).any(1) | (weights.sum(1) > 1 + 1e-4)))
        raise InputError(f"array 'skin_weights' row {row} is {weights[row].tolist()}, expected weights >= 0 "
                         "summing to at most 1", source=source)
    pose_pivot = floats("pose_pivot", (3,))
    pose_controls = ints("pose_controls", (2,), -1, D - 3, "first-control indices")
    prov = need("provenance")
    try:
        provenance = json.loads(str(prov)) if prov.shape == () and prov.dtype.kind == "U" else None
    except json.JSONDecodeError:
        provenance = None
    if not isinstance(provenance, dict):
        raise InputError("array 'provenance' is not a JSON object string", source=source)

    def t(a, dtype=torch.float32):
        return None if a is None else torch.from_numpy(np.ascontiguousarray(a)).to(device=device, dtype=dtype)

    q = quats / qn[:, None]
    canonical = Gaussians(means=means, quats=q.astype(np.float32), scales=np.exp(log_scales).astype(np.float32),
                          opacities=(1.0 / (1.0 + np.exp(-logits.astype(np.float64)))).astype(np.float32),
                          sh=sh).to_torch(device)
    return Rig(layout=layout, control_names=names, canonical=canonical,
               blend_controls=t(blend_controls, torch.long), blend_index=t(blend_index, torch.long),
               blend_shape=t(blend_shape, torch.long), blend_pos=t(blend_pos), blend_rot=t(blend_rot),
               blend_color=t(blend_color), bone_names=bone_names, bone_parents=tuple(int(p) for p in parents),
               bone_pivots=t(pivots), bone_controls=tuple(int(c) for c in bone_controls),
               skin_weights=t(weights), pose_pivot=t(pose_pivot),
               pose_controls=(int(pose_controls[0]), int(pose_controls[1])), provenance=provenance)


def load_rig(path: str | os.PathLike, device: str = "cpu") -> Rig:
    """Read and validate a rig ``.npz`` (module docstring) onto ``device``; one InputError naming the file."""
    source = str(path)
    try:
        with open(path, "rb") as fh:
            magic = fh.read(4)
    except FileNotFoundError:
        raise InputError("no such rig file", source=source, hint="make one with tools/make_demo_avatar.py") from None
    except IsADirectoryError:
        raise InputError("is a folder, not a rig file", source=source) from None
    except OSError as exc:
        raise InputError(f"cannot read: {exc.strerror}", source=source) from None
    if magic != b"PK\x03\x04":
        raise InputError("not a readable .npz file (not a zip archive)", source=source,
                         hint="a rig file is a numpy .npz, see lenticalib/render/rig.py")
    try:
        with np.load(path, allow_pickle=False) as data:
            arrays = {name: data[name] for name in data.files}
    except FileNotFoundError:
        raise InputError("no such rig file", source=source, hint="make one with tools/make_demo_avatar.py") from None
    except IsADirectoryError:
        raise InputError("is a folder, not a rig file", source=source) from None
    except ValueError as exc:
        if "pickle" in str(exc).lower():
            raise InputError("holds a pickled object array, which rig files never do", source=source) from None
        raise InputError(f"not a readable .npz file: {str(exc).splitlines()[0] if str(exc) else 'bad data'}",
                         source=source) from None
    except (OSError, EOFError, zipfile.BadZipFile) as exc:
        raise InputError(f"not a readable .npz file: {str(exc).splitlines()[0] if str(exc) else type(exc).__name__}",
                         source=source) from None
    return rig_from_arrays(arrays, source=source, device=device)


def save_rig(path: str | os.PathLike, rig: Rig) -> None:
    """Write ``rig`` as a compressed ``.npz`` atomically (a reader sees the old file or the new one)."""
    buf = io.BytesIO()
    np.savez_compressed(buf, **rig.to_arrays())
    write_bytes_atomic(path, buf.getvalue())
