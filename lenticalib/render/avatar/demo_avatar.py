"""A procedurally generated demo avatar: a stylised head of about 100k Gaussians, as a :class:`~.rig.Rig`.

No downloads: :func:`make_demo_avatar` builds it from a seed in a few seconds
(``tools/make_demo_avatar.py`` writes it to a rig file: 5.6 MB compressed at 100k Gaussians
with its mesh, made in about 4 s, so it is generated, not committed).

Frame and units: metres, world y up, the avatar facing +z, "left" the avatar's own left (+x).
The head (chin to the top of the hair) is about 0.25 m tall and centred near the origin; a neck
and a collar reach down to y = -0.21.  Parts: a skin-coloured head (an ellipsoid warped into a
face: nose, eye sockets, brow ridge, cheekbones, lips, a chin and jaw), two eyes (white sclera,
iris and pupil on an eyeball skinned to its eye bone), upper eyelids (a blink blendshape) and
lower lids, eyebrows, two ears standing out from the sides, dark hair on top and back, teeth and a
dark mouth cavity behind the lips, a neck and a collar.  Surfaces are flat Gaussians (a few mm,
oriented to the surface, opacity 0.95, hair 0.9 and elongated along strands) with SH degree 0;
the colour has a soft light from the front-above baked in (renderers apply no lighting).

Controls: the default layout (:data:`~.rig.DEFAULT_LAYOUT`, 70 values).  Expression components
0..9 are blendshapes (:data:`DEMO_EXPRESSIONS`), 10..49 do nothing:

    0 smile        mouth corners up and out, cheeks up
    1 frown        mouth corners down
    2 brows_up     eyebrows and lower forehead up
    3 brows_down   eyebrows down and together
    4 mouth_wide   mouth corners outwards
    5 pucker       lips forward and together
    6 cheeks_puff  cheeks outwards
    7 sneer        upper lip and nose wings up
    8 smile_left   smile on the avatar's left (+x) side only
    9 smile_right  smile on the avatar's right (-x) side only

Bones (pivots in metres): neck (root, (0, -0.17, -0.02), driven by ``neck``), head (child of
neck, no control of its own: the skull follows the neck), jaw (child of head, pivot (0, 0, 0),
``jaw``; jaw[0] > 0 opens the mouth, the chin moving down and back), eye_l / eye_r (children of
head, at the eyeball centres, ``eyes[0:3]`` / ``eyes[3:6]``; eyes[1] > 0 turns a gaze towards +x).
The rigid head pose (``head`` rotation, ``translation``) pivots about (0, -0.05, -0.01), about
where the skull sits on the neck.  ``eyelids`` 0 open, 1 closed (left, right).

Modules: the geometry (head surface, parameterised surfaces, sampling) is in
:mod:`.demo_avatar_shapes`, the parts and the bones they follow in :mod:`.demo_avatar_parts`,
the triangle mesh of those surfaces that the rig carries (for the side-view diagnostics) in
:mod:`.demo_avatar_mesh`; this one adds the expression and blink blendshapes, the bone pivots and the baked light, and
builds the rig.
"""

from __future__ import annotations

import json
import time

import numpy as np

from ...core.errors import InputError
from .demo_avatar_parts import (DEMO_BONES, HEAD, NECK, make_brows, make_cavity, make_collar, make_ears,
    make_eyes, make_hair, make_lids, make_neck, make_skin, make_teeth)
from .demo_avatar_mesh import demo_mesh_arrays
from .demo_avatar_shapes import eye_centres, frame_quats, gauss, smoothstep
from .gaussians import SH_C0
from .rig import DEFAULT_LAYOUT, Rig, envelope_arrays
from .rig_file import rig_from_arrays

DEMO_EXPRESSIONS = ("smile", "frown", "brows_up", "brows_down", "mouth_wide", "pucker", "cheeks_puff", "sneer",
                    "smile_left", "smile_right")
POSE_PIVOT = (0.0, -0.05, -0.01)
NECK_PIVOT = (0.0, -0.17, -0.02)
JAW_PIVOT = (0.0, 0.0, 0.0)
LIGHT = np.array([0.25, 0.40, 0.88]) / np.linalg.norm([0.25, 0.40, 0.88])

# share of the Gaussians per part (the skin takes the remainder)
_SHARES = {"hair": 0.30, "neck": 0.075, "collar": 0.025, "ears": 0.07, "sclera": 0.03, "iris": 0.016,
           "lids": 0.022, "brows": 0.012, "teeth": 0.01, "cavity": 0.012}


# ------------------------------------------------------------------ blendshapes

def _expression_offsets(p, part_names):
    """(10, m, 3) position offsets per unit control of DEMO_EXPRESSIONS, for points p (m, 3)."""
    x, y, z = p[:, 0], p[:, 1], p[:, 2]
    face = np.isin(part_names, ["skin", "brows"]) * smoothstep(0.02, 0.06, z)
    out = np.zeros((len(DEMO_EXPRESSIONS), len(p), 3))
    sgn = np.sign(x)
    corner = gauss(np.abs(x), y, 0.025, -0.045, 0.011, 0.010)
    cheek = gauss(np.abs(x), y, 0.042, -0.018, 0.015, 0.014)

    def smile_field(mask):
        o = np.zeros((len(p), 3))
        o[:, 0] = sgn * 0.0035 * corner
        o[:, 1] = 0.0055 * corner + 0.0022 * cheek
        o[:, 2] = -0.0015 * corner + 0.0015 * cheek
        return o * (face * mask)[:, None]

    out[0] = smile_field(1.0)
    out[1, :, 1] = -0.0050 * corner * face
    out[1, :, 0] = sgn * 0.0008 * corner * face
    brow = np.exp(-0.5 * ((y - 0.05) / 0.013) ** 2) * np.exp(-(x / 0.065) ** 4) * smoothstep(0.030, 0.040, y)
    out[2, :, 1] = 0.0060 * brow * face
    inner = np.exp(-0.5 * ((np.abs(x) - 0.02) / 0.014) ** 2) * np.exp(-0.5 * ((y - 0.045) / 0.008) ** 2)
    inner = inner * smoothstep(0.032, 0.040, y)
    out[3, :, 1] = -0.0040 * inner * face
    out[3, :, 0] = -sgn * 0.0020 * inner * face
    out[3, :, 2] = 0.0010 * inner * face
    out[4, :, 0] = sgn * 0.0060 * corner * face
    out[4, :, 2] = -0.0010 * corner * face
    lips = np.exp(-((x / 0.030) ** 2) - ((y + 0.046) / 0.012) ** 2)
    out[5, :, 2] = 0.0065 * lips * face
    out[5, :, 0] = -0.25 * x * lips * face
    puff = gauss(np.abs(x), y, 0.045, -0.040, 0.016, 0.016) * face
    out[6] = np.stack([sgn * 0.0060 * puff, np.zeros_like(x), 0.0035 * puff], 1)
    sneer = gauss(np.abs(x), y, 0.011, -0.030, 0.010, 0.008) * face
    out[7, :, 1] = 0.0040 * sneer
    out[7, :, 2] = 0.0010 * sneer
    out[8] = smile_field(smoothstep(-0.004, 0.004, x))
    out[9] = smile_field(smoothstep(0.004, -0.004, x))
    return out


# ------------------------------------------------------------------ assembly

def demo_avatar_arrays(seed: int = 0, count: int = 100_000) -> dict[str, np.ndarray]:
    """The demo avatar as rig-file arrays (see :mod:`.rig_file`); exactly ``count`` Gaussians (>= 2000)."""
    if isinstance(count, bool) or not isinstance(count, (int, np.integer)) or count < 2000:
        raise InputError(f"count {count!r} is too small", source="count", hint="use at least 2000 Gaussians")
    started = time.perf_counter()
    rng = np.random.default_rng(seed)
    k = {name: max(int(round(share * count)), 8) for name, share in _SHARES.items()}
    n_skin = count - sum(k.values())
    skin = make_skin(rng, n_skin)
    parts = [skin, *make_hair(rng, k["hair"]), make_neck(rng, k["neck"]), make_collar(rng, k["collar"])]
    parts += make_ears(rng, k["ears"])
    parts += make_eyes(rng, k["sclera"], k["iris"])
    lid_parts, lid_closed = make_lids(rng, k["lids"])
    lid_first = sum(len(q.p) for q in parts)
    parts += lid_parts
    parts.append(make_brows(rng, skin, k["brows"]))
    parts += make_teeth(rng, k["teeth"])
    parts.append(make_cavity(rng, k["cavity"]))

    p = np.concatenate([q.p for q in parts])
    names = np.concatenate([[q.name] * len(q.p) for q in parts])
    normal = np.concatenate([q.normal for q in parts])
    tangent = np.concatenate([q.tangent for q in parts])
    scales = np.concatenate([q.scales for q in parts])
    opacity = np.concatenate([q.opacity for q in parts])
    weights = np.concatenate([q.weights for q in parts])
    albedo = np.concatenate([q.albedo for q in parts])
    ao = np.concatenate([q.ao for q in parts])
    shade = np.concatenate([np.full(len(q.p), q.shade) for q in parts])
    G = len(p)
    assert G == count, (G, count)

    # baked light: key from the front-above, a fill from the other side, some sky; darker in concavities
    n = normal / np.linalg.norm(normal, axis=1, keepdims=True)
    fill = np.array([-0.6, 0.1, 0.4]) / np.linalg.norm([-0.6, 0.1, 0.4])
    light = (0.42 + 0.50 * np.clip(n @ LIGHT, 0, None) + 0.14 * np.clip(n @ fill, 0, None)
             + 0.08 * np.clip(n[:, 1], 0, None))
    light = np.where(shade, light, 1.0) * np.clip(1 - ao, 0.45, 1)
    jitter = 1 + 0.035 * rng.standard_normal((G, 1))
    rgb = np.clip(albedo * light[:, None] * jitter, 0.0, 1.0)
    sh = ((rgb - 0.5) / SH_C0)[:, None, :]

    quats = frame_quats(n, tangent)

    # blendshapes: expressions over the skin and brows, blinks over the upper lids
    entries_idx, entries_shape, entries_pos = [], [], []
    expr = _expression_offsets(p, names)
    for e in range(len(DEMO_EXPRESSIONS)):
        nz = np.flatnonzero(np.abs(expr[e]).max(1) > 2e-5)
        entries_idx.append(nz)
        entries_shape.append(np.full(len(nz), e))
        entries_pos.append(expr[e, nz])
    first = lid_first
    blink = {1: ([], []), -1: ([], [])}
    for q, (side, off) in zip(lid_parts, lid_closed):
        if side:
            blink[side][0].append(first + np.arange(len(q.p)))
            blink[side][1].append(off)
        first += len(q.p)
    for e, side in ((len(DEMO_EXPRESSIONS), 1), (len(DEMO_EXPRESSIONS) + 1, -1)):
        idx = np.concatenate(blink[side][0])
        entries_idx.append(idx)
        entries_shape.append(np.full(len(idx), e))
        entries_pos.append(np.concatenate(blink[side][1]))

    layout = DEFAULT_LAYOUT
    expr_slice, lid_slice = layout.slice("expression"), layout.slice("eyelids")
    blend_controls = np.array([expr_slice.start + e for e in range(len(DEMO_EXPRESSIONS))]
                              + [lid_slice.start, lid_slice.start + 1], dtype=np.int32)
    control_names = list(layout.default_names())
    for e, name in enumerate(DEMO_EXPRESSIONS):
        control_names[expr_slice.start + e] = f"expression.{name}"
    for group, labels in (("jaw", "xyz"), ("neck", "xyz"), ("head", "xyz"), ("translation", "xyz"),
                          ("eyes", ["left_x", "left_y", "left_z", "right_x", "right_y", "right_z"]),
                          ("eyelids", ["left", "right"])):
        s = layout.slice(group)
        for i, label in enumerate(labels):
            control_names[s.start + i] = f"{group}.{label}"

    eyes = eye_centres()
    pivots = np.array([NECK_PIVOT, (0.0, -0.06, -0.02), JAW_PIVOT, eyes[0], eyes[1]], dtype=np.float32)
    bone_controls = np.array([layout.slice("neck").start, -1, layout.slice("jaw").start,
                              layout.slice("eyes").start, layout.slice("eyes").start + 3], dtype=np.int32)
    eps = 1e-4
    op = np.clip(opacity, eps, 1 - eps)
    provenance = {"made_by": "lenticalib.render.avatar.demo_avatar.make_demo_avatar", "seed": int(seed),
                  "count": int(count), "seconds": round(time.perf_counter() - started, 3),
                  "expressions": list(DEMO_EXPRESSIONS), "units": "metres, y up, facing +z"}
    return {
        **envelope_arrays(), "means": p.astype(np.float32), "quats": quats.astype(np.float32),
        "log_scales": np.log(scales).astype(np.float32),
        "opacity_logits": np.log(op / (1 - op)).astype(np.float32), "sh": sh.astype(np.float32),
        "control_groups": np.array(layout.names), "control_sizes": np.array([s for _, s in layout.groups], np.int32),
        "control_dim": np.array(layout.dim, np.int32), "control_names": np.array(control_names),
        "blend_controls": blend_controls, "blend_index": np.concatenate(entries_idx).astype(np.int32),
        "blend_shape": np.concatenate(entries_shape).astype(np.int32),
        "blend_pos": np.concatenate(entries_pos).astype(np.float32),
        "bone_names": np.array(DEMO_BONES), "bone_parents": np.array([-1, NECK, HEAD, HEAD, HEAD], np.int32),
        "bone_pivots": pivots, "bone_controls": bone_controls, "skin_weights": weights.astype(np.float32),
        "pose_pivot": np.array(POSE_PIVOT, np.float32),
        "pose_controls": np.array([layout.slice("head").start, layout.slice("translation").start], np.int32),
        "provenance": np.array(json.dumps(provenance, sort_keys=True)),
        **demo_mesh_arrays(_expression_offsets, len(DEMO_EXPRESSIONS)),
        "part_names": names,  # not part of the format: dropped by make_demo_avatar, kept for inspection
    }


def make_demo_avatar(seed: int = 0, count: int = 100_000, device: str = "cpu") -> Rig:
    """The demo avatar (module docstring) as a :class:`~.rig.Rig` on ``device``; seconds to build."""
    arrays = demo_avatar_arrays(seed, count)
    arrays.pop("part_names")
    return rig_from_arrays(arrays, source="demo avatar", device=device)
