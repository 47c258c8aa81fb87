"""The rig file: a :class:`~.rig.Rig` as a numpy ``.npz``, read, validated, written.

What the arrays mean (control layout, blendshapes, bones, pose, the order of the deformation)
is documented in :mod:`.rig`; this module owns how they are stored and checked.

No pickled objects; :func:`save_rig` writes the file compressed, atomically.
G Gaussians, K SH coefficients, D controls, E blendshapes, N blendshape entries, B bones:

    format          ()        str    "lenticalib.rig" (:mod:`lenticalib.core.files.documents`)
    format_version  ()        int    1
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
    mesh_*                           optional: the avatar's triangle mesh, skinned like the Gaussians
                                     (:mod:`.rig_mesh`: vertices, triangles, skin weights, blendshapes)

Floats may be stored as float16/32/64 and are used as float32; a missing array (other than the
two optional ones), a wrong shape or index, a non-finite value or another format or version is
one InputError naming the file and the array.  Rigs written before the envelope was shared
(``format`` "lenticalib-rig", ``version`` instead of ``format_version``) still read.  The names,
shapes and dtypes are checked from the headers before any data is inflated
(:mod:`lenticalib.core.files.arrayfile`): arrays claiming more than :data:`MAX_RIG_BYTES` (2 GiB) in
all, or more than the file holds, are refused unread, and so are zip members whose uncompressed
sizes in the central directory add up to more (a few megabytes deflated from gigabytes of zeros).
"""

from __future__ import annotations

import io
import os
from typing import Any

import numpy as np

from ...core.files.arrayfile import GIB, load_npz
from ...core.files.atomic import write_bytes_atomic
from ...core.files.documents import OLD_VERSION_KEY, VERSION_KEY, check_envelope, json_from_text
from ...core.errors import InputError
from .gaussians import Gaussians
from .rig_mesh import MESH_ARRAYS, MESH_BLEND_ARRAYS, mesh_from_arrays

from .rig import DOCUMENT, ControlLayout, Rig
_ENVELOPE = ("format", VERSION_KEY, OLD_VERSION_KEY)  # the version under either key (core.documents)
_REQUIRED = ("format", "means", "quats", "log_scales", "opacity_logits", "sh", "control_groups",
             "control_sizes", "control_dim", "control_names", "blend_controls", "blend_index", "blend_shape",
             "blend_pos", "bone_names", "bone_parents", "bone_pivots", "bone_controls", "skin_weights",
             "pose_pivot", "pose_controls", "provenance")
_OPTIONAL = ("blend_rot", "blend_color", VERSION_KEY, OLD_VERSION_KEY) + MESH_ARRAYS + MESH_BLEND_ARRAYS
# The most bytes a rig's arrays may claim: over 2 million Gaussians with SH degree 3 and 50 bones.
MAX_RIG_BYTES = 2 * GIB


# --------------------------------------------------------------------------------------------
# building, loading, saving

def rig_to_arrays(rig: Rig) -> dict[str, np.ndarray]:
    """The rig as the file's arrays (numpy, float32 / int32 / str), raw Gaussian parameters
    (:meth:`.rig.Rig.to_arrays`)."""
    return rig.to_arrays()


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

    need("format")
    envelope = {}
    for key in _ENVELOPE:
        if key in arrays:
            a = np.asarray(arrays[key])
            if a.shape != () or a.dtype.kind not in ("U" if key == "format" else "iu"):
                raise InputError(f"array {key!r} has shape {a.shape} dtype {a.dtype}, expected a "
                                 f"{'string' if key == 'format' else 'whole number'}", source=source,
                                 hint=DOCUMENT.hint)
            envelope[key] = a.item()
    check_envelope(envelope, DOCUMENT, source)

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
    # the one JSON reader: depth, value count and numbers bounded (a provenance nested 100000 deep is one line)
    provenance = (json_from_text(str(prov), f"{source}: array 'provenance'")
                  if prov.shape == () and prov.dtype.kind == "U" else None)
    if not isinstance(provenance, dict):
        raise InputError("array 'provenance' is not a JSON object string", source=source)

    mesh = mesh_from_arrays(arrays, B, E, source, device)

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
               pose_controls=(int(pose_controls[0]), int(pose_controls[1])), provenance=provenance, mesh=mesh)


def load_rig(path: str | os.PathLike, device: str = "cpu") -> Rig:
    """Read and validate a rig ``.npz`` (module docstring) onto ``device``; one InputError naming the file."""
    source = str(path)
    if not os.path.lexists(path):
        raise InputError("no such rig file", source=source, hint="make one with tools/make_demo_avatar.py")
    if os.path.isdir(path):
        raise InputError("is a folder, not a rig file", source=source)
    # load_npz opens it (a regular file only) and checks the zip's central directory: every member's
    # uncompressed size against MAX_RIG_BYTES, before anything is inflated
    arrays = load_npz(path, wanted=_REQUIRED + _OPTIONAL, required=_REQUIRED, max_bytes=MAX_RIG_BYTES,
                      source=source, hint="a rig file holds: " + " ".join(_REQUIRED))
    return rig_from_arrays(arrays, source=source, device=device)


def save_rig(path: str | os.PathLike, rig: Rig) -> None:
    """Write ``rig`` as a compressed ``.npz`` atomically (a reader sees the old file or the new one)."""
    buf = io.BytesIO()
    np.savez_compressed(buf, **rig_to_arrays(rig))
    write_bytes_atomic(path, buf.getvalue())
