"""A procedurally generated demo avatar: a stylised head of about 100k Gaussians, as a :class:`~.rig.Rig`.

No downloads: :func:`make_demo_avatar` builds it from a seed in a few seconds
(``tools/make_demo_avatar.py`` writes it to a rig file: 4.9 MB compressed at 100k Gaussians, made
in about 3 s, so it is generated, not committed).

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
"""

from __future__ import annotations

import math
import time

import numpy as np

from .gaussians import SH_C0
from .rig import DEFAULT_LAYOUT, RIG_FORMAT, RIG_VERSION, Rig, rig_from_arrays

DEMO_EXPRESSIONS = ("smile", "frown", "brows_up", "brows_down", "mouth_wide", "pucker", "cheeks_puff", "sneer",
                    "smile_left", "smile_right")
DEMO_BONES = ("neck", "head", "jaw", "eye_l", "eye_r")
NECK, HEAD, JAW, EYE_L, EYE_R = range(5)

HEAD_CENTRE = np.array([0.0, 0.01, -0.005])   # centre of the warped ellipsoid the head is made of
AXES = (0.076, 0.118, 0.122, 0.097)           # x, y above, y below, z semi-axes, metres
EYE_X, EYE_Y, EYE_RADIUS = 0.033, 0.026, 0.0132  # eye centres at (+-EYE_X, EYE_Y, z_eye), eyeball radius
EYE_FORWARD = 0.0045                          # how far the eyeball's front stands out of the face surface
ALMOND = (0.0108, 0.0088)                     # half width, half height of the eye openings
POSE_PIVOT = (0.0, -0.05, -0.01)
NECK_PIVOT = (0.0, -0.17, -0.02)
JAW_PIVOT = (0.0, 0.0, 0.0)
LID_TOP, LID_OPEN, LID_CLOSED, LID_LOW_TOP = (math.radians(a) for a in (62, 24, -26, -22))
LIGHT = np.array([0.25, 0.40, 0.88]) / np.linalg.norm([0.25, 0.40, 0.88])

# share of the Gaussians per part (the skin takes the remainder)
_SHARES = {"hair": 0.30, "neck": 0.075, "collar": 0.025, "ears": 0.07, "sclera": 0.03, "iris": 0.016,
           "lids": 0.022, "brows": 0.012, "teeth": 0.01, "cavity": 0.012}

SKIN = np.array([0.87, 0.66, 0.54])
HAIR = np.array([0.20, 0.12, 0.07])


def smoothstep(e0, e1, x):
    t = np.clip((np.asarray(x, dtype=np.float64) - e0) / (e1 - e0), 0.0, 1.0)
    return t * t * (3 - 2 * t)


def _gauss(x, y, cx, cy, sx, sy):
    return np.exp(-0.5 * (((x - cx) / sx) ** 2 + ((y - cy) / sy) ** 2))


# ------------------------------------------------------------------ the head surface

def _mouth_line(x):
    """y of the line where the lips meet (metres), for |x| up to the mouth corners."""
    return -0.046 + 0.003 * (np.clip(np.abs(x) / 0.025, 0, 1.4)) ** 2


def _lip_thickness(x):
    """(upper, lower) lip heights above / below the mouth line at x."""
    ax = np.clip(np.abs(x) / 0.026, 0, 1)
    base = np.sqrt(np.clip(1 - ax ** 2, 0, 1))
    upper = (0.0060 + 0.0015 * np.exp(-((np.abs(x) - 0.005) / 0.004) ** 2)) * base ** 0.7
    lower = 0.0085 * base ** 0.8
    return upper, lower


def _head_surface(d):
    """Unit directions (m, 3) from HEAD_CENTRE -> surface points (m, 3) and a 'concavity' (m,) for shading."""
    ax, ay_up, ay_down, az = AXES
    dx, dy, dz = d[:, 0], d[:, 1], d[:, 2]
    x = ax * dx
    y = np.where(dy > 0, ay_up, ay_down) * dy
    z = az * dz
    x = x * (1 - 0.30 * smoothstep(-0.01, -0.115, y))                      # jaw taper
    front = smoothstep(0.0, 0.55, dz)
    z = z + 0.034 * smoothstep(-0.02, -0.10, y) * front                     # chin and mouth forward
    z = z - 0.012 * smoothstep(0.2, -0.6, dz) * smoothstep(-0.03, -0.11, y)  # nape tucked in
    x = x * (1 - 0.05 * smoothstep(0.3, 0.9, dz))                           # flatter face sides
    X, Y, Z = x + HEAD_CENTRE[0], y + HEAD_CENTRE[1], z + HEAD_CENTRE[2]
    f = smoothstep(0.35, 0.75, dz)
    # nose: a ridge from the bridge to the tip, wings at the base
    ridge = np.where(Y > -0.013, 0.029 * smoothstep(0.034, -0.013, Y) ** 1.25,
                     0.029 * np.exp(-((Y + 0.013) / 0.0065) ** 2))
    width = 0.0062 + 0.0050 * smoothstep(0.005, -0.016, Y)
    nose = ridge * np.exp(-0.5 * (X / width) ** 2)
    wings = 0.0085 * (_gauss(X, Y, 0.0115, -0.017, 0.0050, 0.0045) + _gauss(X, Y, -0.0115, -0.017, 0.0050, 0.0045))
    sockets = -0.011 * (_gauss(X, Y, EYE_X, EYE_Y, 0.017, 0.012) + _gauss(X, Y, -EYE_X, EYE_Y, 0.017, 0.012))
    brow = 0.0055 * np.exp(-0.5 * ((Y - 0.046) / 0.006) ** 2) * np.exp(-(X / 0.058) ** 4)
    cheeks = 0.0065 * (_gauss(X, Y, 0.043, -0.006, 0.016, 0.013) + _gauss(X, Y, -0.043, -0.006, 0.016, 0.013))
    ym = _mouth_line(X)
    up, lo = _lip_thickness(X)
    lips = (0.0040 * np.exp(-0.5 * ((Y - ym - 0.6 * up) / np.maximum(0.45 * up, 1e-4)) ** 2) * (up > 1e-4)
            + 0.0050 * np.exp(-0.5 * ((Y - ym + 0.55 * lo) / np.maximum(0.5 * lo, 1e-4)) ** 2) * (lo > 1e-4))
    line = -0.0015 * np.exp(-0.5 * ((Y - ym) / 0.0008) ** 2) * np.exp(-(X / 0.026) ** 6)
    sulcus = -0.0030 * _gauss(X, Y, 0.0, -0.066, 0.013, 0.005)
    chin = 0.0075 * _gauss(X, Y, 0.0, -0.084, 0.015, 0.011)
    bumps = nose + wings + sockets + brow + cheeks + lips + line + sulcus + chin
    Z = Z + bumps * f
    concavity = np.clip(-(sockets + line + sulcus) * f, 0, None)
    return np.stack([X, Y, Z], 1), concavity


def _sphere_param(uv):
    """Equal-area parameterisation of the unit sphere, y the polar axis: u in [-1, 1], v in [0, 2 pi)."""
    u, v = uv[:, 0], uv[:, 1]
    s = np.sqrt(np.clip(1 - u * u, 0, 1))
    return np.stack([s * np.sin(v), u, s * np.cos(v)], 1)


def _head_param(uv):
    return _head_surface(_sphere_param(uv))[0]


def _face_point(x, y):
    """Points of the head surface in front with the given x and y (arrays), by fixed-point iteration."""
    x = np.asarray(x, dtype=np.float64)
    y = np.asarray(y, dtype=np.float64)
    ax, ay_up, _, az = AXES
    dx = (x - HEAD_CENTRE[0]) / ax
    dy = (y - HEAD_CENTRE[1]) / ay_up
    d = np.stack([dx, dy, np.sqrt(np.clip(1 - dx * dx - dy * dy, 0.05, 1))], 1)
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    for _ in range(30):
        p, _ = _head_surface(d)
        d[:, 0] += (x - p[:, 0]) / ax
        d[:, 1] += (y - p[:, 1]) / ay_up
        d /= np.linalg.norm(d, axis=1, keepdims=True)
    return _head_surface(d)[0]


# ------------------------------------------------------------------ sampling

class _Surface:
    """Points sampled on a parametric surface: centres, unit normals, unit tangents (along P_u), uv, cells.

    ``cell`` (m, 2) is the size of each point's sampling cell on the surface along the tangent and
    along normal x tangent: a Gaussian about 0.7 cell wide covers the surface without holes.
    """

    def __init__(self, p, normal, tangent, uv, cell):
        self.p, self.normal, self.tangent, self.uv, self.cell = p, normal, tangent, uv, cell

    def scales(self, k=0.7, thin=0.2):
        c = k * self.cell
        return np.stack([c[:, 0], c[:, 1], thin * np.sqrt(c[:, 0] * c[:, 1])], 1)


def _sample(rng, param, n, lo, hi, keep=None, flip_to=None, jitter=0.7):
    """Exactly n points on the surface ``param`` (uv (m, 2) -> points (m, 3)) over the uv box lo..hi.

    Stratified: a jittered grid in uv whose cells are about square on the surface; each point
    records its cell's size on the surface (so uneven parameterisations still leave no holes).
    ``keep(points, uv)`` drops points; ``flip_to(points)`` gives a direction the normals should face.
    """
    lo = np.asarray(lo, dtype=np.float64)
    hi = np.asarray(hi, dtype=np.float64)
    span = hi - lo
    h = 1e-4 * span

    def frame(uv):
        p = param(uv)
        pu = (param(uv + [h[0], 0]) - param(uv - [h[0], 0])) / (2 * h[0])
        pv = (param(uv + [0, h[1]]) - param(uv - [0, h[1]])) / (2 * h[1])
        return p, np.nan_to_num(pu), np.nan_to_num(pv)

    probe = lo + span * rng.random((4000, 2))
    p, pu, pv = frame(probe)
    kept = np.ones(len(probe), bool) if keep is None else keep(p, probe)
    frac = max(kept.mean(), 0.01)
    lu = np.linalg.norm(pu, axis=1).mean() * span[0]
    lv = np.linalg.norm(pv, axis=1).mean() * span[1]
    cells = n / frac * 1.05
    for _ in range(20):
        nu = max(int(round(math.sqrt(cells * lu / lv))), 1)
        nv = max(int(round(cells / nu)), 1)
        du, dv = span / [nu, nv]
        gu, gv = np.meshgrid((np.arange(nu) + 0.5) * du, (np.arange(nv) + 0.5) * dv, indexing="ij")
        uv = lo + np.stack([gu.ravel(), gv.ravel()], 1)
        uv += (rng.random(uv.shape) - 0.5) * jitter * [du, dv]
        p, pu, pv = frame(uv)
        ok = (np.linalg.norm(np.cross(pu, pv), axis=1) > 0) & np.isfinite(p).all(1)
        if keep is not None:
            ok &= keep(p, uv)
        if ok.sum() >= n:
            break
        cells *= n / max(ok.sum(), 1) * 1.03
    idx = np.flatnonzero(ok)
    boost = math.sqrt(len(idx) / n)  # dropping points at random: widen the rest to cover
    idx = np.sort(rng.choice(idx, size=n, replace=False))
    p, pu, pv, uv = p[idx], pu[idx], pv[idx], uv[idx]
    nrm = np.cross(pu, pv)
    area = np.linalg.norm(nrm, axis=1)
    nrm = nrm / np.maximum(area, 1e-30)[:, None]
    lpu = np.maximum(np.linalg.norm(pu, axis=1), 1e-30)
    tan = pu / lpu[:, None]
    cell = np.stack([lpu * du, area * du * dv / (lpu * du)], 1) * boost
    if flip_to is not None:
        sign = np.sign((nrm * flip_to(p)).sum(1))
        nrm = nrm * np.where(sign == 0, 1, sign)[:, None]
    return _Surface(p, nrm, tan, uv, cell)


def _matrix_to_quat(R):
    """(m, 3, 3) rotation matrices -> (m, 4) unit quaternions (w, x, y, z)."""
    m00, m11, m22 = R[:, 0, 0], R[:, 1, 1], R[:, 2, 2]
    tr = m00 + m11 + m22
    q = np.empty((len(R), 4))
    cases = np.argmax(np.stack([tr, m00, m11, m22], 1), 1)
    for k in range(4):
        s = cases == k
        r = R[s]
        if k == 0:
            t = np.sqrt(1 + tr[s]) * 2
            q[s] = np.stack([0.25 * t, (r[:, 2, 1] - r[:, 1, 2]) / t, (r[:, 0, 2] - r[:, 2, 0]) / t,
                             (r[:, 1, 0] - r[:, 0, 1]) / t], 1)
        elif k == 1:
            t = np.sqrt(1 + r[:, 0, 0] - r[:, 1, 1] - r[:, 2, 2]) * 2
            q[s] = np.stack([(r[:, 2, 1] - r[:, 1, 2]) / t, 0.25 * t, (r[:, 0, 1] + r[:, 1, 0]) / t,
                             (r[:, 0, 2] + r[:, 2, 0]) / t], 1)
        elif k == 2:
            t = np.sqrt(1 + r[:, 1, 1] - r[:, 0, 0] - r[:, 2, 2]) * 2
            q[s] = np.stack([(r[:, 0, 2] - r[:, 2, 0]) / t, (r[:, 0, 1] + r[:, 1, 0]) / t, 0.25 * t,
                             (r[:, 1, 2] + r[:, 2, 1]) / t], 1)
        else:
            t = np.sqrt(1 + r[:, 2, 2] - r[:, 0, 0] - r[:, 1, 1]) * 2
            q[s] = np.stack([(r[:, 1, 0] - r[:, 0, 1]) / t, (r[:, 0, 2] + r[:, 2, 0]) / t,
                             (r[:, 1, 2] + r[:, 2, 1]) / t, 0.25 * t], 1)
    return q / np.linalg.norm(q, axis=1, keepdims=True)


def _frame_quats(normal, tangent):
    """Quaternions turning the Gaussian's (x, y, z) axes to (tangent, normal x tangent, normal)."""
    n = normal / np.linalg.norm(normal, axis=1, keepdims=True)
    t = tangent - (tangent * n).sum(1, keepdims=True) * n
    bad = np.linalg.norm(t, axis=1) < 1e-9
    if bad.any():  # tangent along the normal: any perpendicular will do
        alt = np.where(np.abs(n[bad, :1]) < 0.9, [[1.0, 0, 0]], [[0, 1.0, 0]])
        t[bad] = alt - (alt * n[bad]).sum(1, keepdims=True) * n[bad]
    t /= np.linalg.norm(t, axis=1, keepdims=True)
    b = np.cross(n, t)
    return _matrix_to_quat(np.stack([t, b, n], 2))


class _Part:
    """Gaussians of one part: centres, normals, tangents, scales (m, 3), albedo (m, 3), opacity, weights.

    ``weights`` is a bone index (bound to it alone), (m, 5) skinning weights, or None (the rest frame).
    """

    def __init__(self, name, p, normal, tangent, scales, albedo, opacity, weights, shade=True, ao=None):
        m = len(p)
        self.name = name
        self.p = p
        self.normal = normal
        self.tangent = tangent
        self.scales = np.broadcast_to(np.asarray(scales, dtype=np.float64), (m, 3)).copy()
        self.albedo = np.broadcast_to(np.asarray(albedo, dtype=np.float64), (m, 3)).copy()
        self.opacity = np.broadcast_to(np.asarray(opacity, dtype=np.float64), (m,)).copy()
        self.weights = np.zeros((m, len(DEMO_BONES)))
        if isinstance(weights, int):          # bound to one bone
            self.weights[:, weights] = 1.0
        elif weights is not None:
            assert np.shape(weights) == (m, len(DEMO_BONES)), np.shape(weights)
            self.weights[:] = weights
        self.shade = shade
        self.ao = np.zeros(m) if ao is None else ao


# ------------------------------------------------------------------ parts

def _hairline(d, Y):
    """(under the hair?, height above the hairline) for head surface points of direction d and height Y."""
    dz, dx = d[:, 2], d[:, 0]
    h = np.interp(dz, [-1.0, -0.65, -0.25, 0.05, 0.35, 0.6, 1.0],
                  [-0.072, -0.068, 0.008, 0.036, 0.052, 0.075, 0.078])
    phi = np.arctan2(dx, dz)
    h = h + 0.0025 * np.sin(phi * 23) + 0.0015 * np.sin(phi * 57 + 1.0)
    return Y > h, Y - h


def _in_almond(x, y, side, grow=0.0):
    ex = (x - side * EYE_X) / (ALMOND[0] + grow)
    return (np.abs(ex) < 1) & (np.abs(y - EYE_Y) < (ALMOND[1] + grow) * np.sqrt(np.clip(1 - ex * ex, 0, 1)) ** 0.8)


def _skin(rng, n):
    def keep(p, uv):
        x, y, z = p[:, 0], p[:, 1], p[:, 2]
        ok = ~((_in_almond(x, y, 1) | _in_almond(x, y, -1)) & (z > 0.03))
        ok &= ~((y < -0.07) & ((x / 0.050) ** 2 + ((z + 0.022) / 0.052) ** 2 < 0.7))  # inside the neck
        return ok

    surf = _sample(rng, _head_param, n, (-1, 0), (1, 2 * math.pi), keep, flip_to=lambda q: q - HEAD_CENTRE)
    p, nrm = surf.p, surf.normal
    d = _sphere_param(surf.uv)
    _, conc = _head_surface(d)
    x, y, z = p[:, 0], p[:, 1], p[:, 2]
    albedo = np.tile(SKIN, (n, 1))
    ym = _mouth_line(x)
    up, lo = _lip_thickness(x)
    lip = (y > ym - lo) & (y < ym + up) & (np.abs(x) < 0.027) & (z > 0.05)
    albedo[lip] = [0.74, 0.36, 0.37]
    albedo[lip & (np.abs(y - ym) < 0.0008)] = [0.40, 0.14, 0.14]
    blush = 0.5 * (_gauss(x, y, 0.045, -0.012, 0.014, 0.011) + _gauss(x, y, -0.045, -0.012, 0.014, 0.011)
                   + 0.5 * _gauss(x, y, 0.0, -0.012, 0.008, 0.006)) * (z > 0)
    albedo = albedo * (1 - 0.10 * blush[:, None]) + blush[:, None] * 0.10 * np.array([0.92, 0.45, 0.45])
    nostril = ((np.abs(np.abs(x) - 0.0068) < 0.0024) & (np.abs(y + 0.0205) < 0.0017) & (nrm[:, 1] < -0.5)
               & (z > 0.09))
    albedo[nostril] = [0.42, 0.22, 0.20]
    scalp, _ = _hairline(d, y)
    albedo[scalp] = HAIR * 0.7
    weights = np.zeros((n, len(DEMO_BONES)))
    wj = _jaw_weight(p)
    weights[:, JAW] = wj
    weights[:, HEAD] = 1 - wj
    return _Part("skin", p, nrm, surf.tangent, surf.scales(), albedo, 0.96, weights, ao=conc * 25)


def _jaw_weight(p):
    """How much a point of the lower face follows the jaw: 1 below the lips, 0 above, soft at the cheeks."""
    x, y, z = p[:, 0], p[:, 1], p[:, 2]
    ax = np.abs(x)
    ym = _mouth_line(np.minimum(ax, 0.025))
    over = np.clip(ax - 0.019, 0, None)
    line = ym - 0.9 * over          # the jaw's upper edge falls from the mouth corners towards the jaw angle
    band = 0.0007 + 0.9 * over      # and softens there, so the corners stretch instead of tearing
    w = smoothstep(line + band, line - band, y)
    return w * smoothstep(-0.03, 0.035, z)


def _hair(rng, n):
    def keep(p, uv):
        return _hairline(_sphere_param(uv), p[:, 1])[0]

    layers = (0.30, 0.65, 1.0)
    counts = (n // 4, n // 3, n - n // 4 - n // 3)
    crown = np.array([0.0, 0.14, -0.035])
    out = []
    for f, m in zip(layers, counts):
        surf = _sample(rng, _head_param, m, (-1, 0), (1, 2 * math.pi), keep, flip_to=lambda q: q - HEAD_CENTRE)
        d = _sphere_param(surf.uv)
        _, above = _hairline(d, surf.p[:, 1])
        thick = (0.005 + 0.011 * smoothstep(-0.4, 0.85, d[:, 1])) * np.maximum(smoothstep(0.0, 0.025, above), 0.25)
        q = surf.p + surf.normal * (thick * f)[:, None]
        # strands flow away from the crown; the fringe is combed towards +x from a parting at x = -0.02
        flow = q - crown
        fringe = smoothstep(0.0, 0.06, q[:, 2]) * smoothstep(0.04, 0.09, q[:, 1])
        flow = flow + fringe[:, None] * np.array([1.0, -0.3, 0.0]) * 0.08 * np.sign(q[:, 0] + 0.02)[:, None]
        # streaks: a tone per strand (angle about the crown)
        ang = np.arctan2(q[:, 0] - crown[0], q[:, 2] - crown[2])
        strand = np.floor((ang + math.pi) / (2 * math.pi) * 700)
        tone = 0.75 + 0.5 * ((np.sin(strand * 12.9898) * 43758.5453) % 1.0)
        albedo = HAIR[None] * (tone * (0.65 + 0.35 * f))[:, None]
        cell = np.sqrt(surf.cell.prod(1))
        scales = np.stack([2.2 * cell, 0.55 * cell, 0.2 * cell], 1)
        out.append(_Part("hair", q, surf.normal, flow, scales, albedo, 0.92, HEAD))
    return out


def _neck_radius(y):
    return 1 + 0.35 * smoothstep(-0.16, -0.215, y) ** 1.5


def _neck(rng, n):
    def param(uv):
        a, y = uv[:, 0], uv[:, 1]
        r = _neck_radius(y)
        return np.stack([0.050 * r * np.sin(a), y, -0.022 + 0.052 * r * np.cos(a)], 1)

    def keep(p, uv):
        return (((p - HEAD_CENTRE) / [AXES[0] * 0.95, AXES[2] * 0.97, AXES[3] * 0.95]) ** 2).sum(1) > 1

    surf = _sample(rng, param, n, (0, -0.205), (2 * math.pi, -0.03), keep,
                   flip_to=lambda q: (q - [0, 0, -0.022]) * [1, 0, 1])
    p = surf.p
    p[:, 2] += 0.004 * _gauss(p[:, 0], p[:, 1], 0.0, -0.125, 0.008, 0.01) * (p[:, 2] > 0)  # Adam's apple
    weights = np.zeros((n, len(DEMO_BONES)))
    weights[:, NECK] = smoothstep(-0.185, -0.09, p[:, 1])
    return _Part("neck", p, surf.normal, surf.tangent, surf.scales(), SKIN * 0.97, 0.96, weights)


def _collar(rng, n):
    def param(uv):
        a, t = uv[:, 0], uv[:, 1]  # t in [0, 1] across the roll of the collar
        y = -0.208 + 0.030 * t
        r = _neck_radius(y) + 0.010 * np.sin(t * math.pi) / 0.05
        return np.stack([0.050 * r * np.sin(a), y, -0.022 + 0.052 * r * np.cos(a)], 1)

    surf = _sample(rng, param, n, (0, 0), (2 * math.pi, 1), flip_to=lambda q: (q - [0, 0, -0.022]) * [1, 0, 1])
    knit = 0.85 + 0.15 * (np.sin(surf.uv[:, 0] * 90) > 0)
    albedo = np.array([0.13, 0.33, 0.38])[None] * knit[:, None]
    return _Part("collar", surf.p, surf.normal, surf.tangent, surf.scales(), albedo, 0.97, None)


def _ears(rng, n):
    """Two ears standing out from the sides: a rim (helix), a bowl, a lobe; two layers (front and back)."""
    parts = []
    for side, m in ((1, n // 2), (-1, n - n // 2)):
        root = np.array([side * 0.0705, 0.008, 0.006])
        back = np.array([side * math.sin(math.radians(38)), 0.0, -math.cos(math.radians(38))])
        upv = np.array([0.0, 1.0, 0.0])
        out = np.cross(upv, back)
        out *= np.sign(out[0] * side)             # away from the head

        def half_width(v):
            return 0.5 * (1 + 0.3 * v) * np.sqrt(np.clip(1 - v * v, 0, 1)) ** 0.7

        def param(uv, layer):
            u, v = uv[:, 0], uv[:, 1]             # u 0..1 back from the root, v -1..1 bottom to top
            edge = np.clip(np.abs(u - 0.5) / np.maximum(half_width(v), 1e-3), 0, 1)
            rim = smoothstep(0.6, 0.95, np.maximum(edge, np.abs(v))) * (u > 0.3)
            bowl = np.exp(-(((u - 0.40) / 0.22) ** 2 + ((v + 0.05) / 0.40) ** 2))
            depth = 0.0050 * rim - 0.0045 * bowl + 0.004 * np.clip(u, 0, None) ** 1.5 + layer
            return (root[None] + (0.036 * u)[:, None] * back[None] + (0.033 * v)[:, None] * upv[None]
                    + depth[:, None] * out[None])

        for layer, k in ((0.0, int(round(m * 0.6))), (-0.0028, m - int(round(m * 0.6)))):
            surf = _sample(rng, lambda q, L=layer: param(q, L), k, (0.0, -1.0), (1.0, 1.0),
                           keep=lambda q, uv: np.abs(uv[:, 0] - 0.5) < half_width(uv[:, 1]),
                           flip_to=lambda q, f=(out if layer == 0.0 else -out): np.broadcast_to(f, q.shape))
            u, v = surf.uv[:, 0], surf.uv[:, 1]
            bowl = np.exp(-(((u - 0.40) / 0.22) ** 2 + ((v + 0.05) / 0.40) ** 2))
            parts.append(_Part("ears", surf.p, surf.normal, surf.tangent, surf.scales(0.75), [0.88, 0.62, 0.52],
                               0.97, HEAD, ao=0.35 * bowl if layer == 0.0 else None))
    return parts


def _eye_centres():
    z = _face_point([EYE_X, -EYE_X], [EYE_Y, EYE_Y])[:, 2]
    return [np.array([s * EYE_X, EYE_Y, zz + EYE_FORWARD - EYE_RADIUS]) for s, zz in zip((1, -1), z)]


def _sph(centre, r):
    """Sphere about ``centre`` with polar axis +z: u = cos(angle from +z), v = azimuth."""
    def param(uv):
        u, v = uv[:, 0], uv[:, 1]
        s = np.sqrt(np.clip(1 - u * u, 0, 1))
        return centre[None] + r * np.stack([s * np.cos(v), s * np.sin(v), u], 1)
    return param


def _eyes(rng, n_sclera, n_iris):
    parts = []
    for centre, bone, m, k in zip(_eye_centres(), (EYE_L, EYE_R), (n_sclera // 2, n_sclera - n_sclera // 2),
                                  (n_iris // 2, n_iris - n_iris // 2)):
        surf = _sample(rng, _sph(centre, EYE_RADIUS), m, (-0.3, 0), (math.cos(0.45), 2 * math.pi),
                       flip_to=lambda q, c=centre: q - c)
        ang = np.arccos(np.clip(surf.uv[:, 0], -1, 1))
        albedo = np.tile([0.95, 0.94, 0.91], (m, 1)) * (1 - 0.25 * smoothstep(0.9, 1.6, ang))[:, None]
        parts.append(_Part("sclera", surf.p, surf.normal, surf.tangent, surf.scales(), albedo, 0.98, bone))
        # iris and pupil: a cap of half-angle 0.47 rad, slightly in front of the sclera
        surf = _sample(rng, _sph(centre, EYE_RADIUS + 0.0003), k, (math.cos(0.47), 0), (1, 2 * math.pi),
                       flip_to=lambda q, c=centre: q - c)
        ang = np.arccos(np.clip(surf.uv[:, 0], -1, 1))
        iris = np.array([0.22, 0.42, 0.52]) * (0.8 + 0.4 * np.sin(surf.uv[:, 1] * 37) ** 2)[:, None]
        iris = iris * (1 - 0.5 * smoothstep(0.36, 0.47, ang))[:, None]
        albedo = np.where((ang < 0.19)[:, None], [0.03, 0.03, 0.035], iris)
        glint = _gauss(surf.p[:, 0], surf.p[:, 1], centre[0] + 0.0020, centre[1] + 0.0024, 0.0006, 0.0006)
        albedo = albedo + glint[:, None] * (1.0 - albedo)
        p = surf.p + surf.normal * np.where(ang < 0.19, 0.0002, 0.0)[:, None]
        parts.append(_Part("iris", p, surf.normal, surf.tangent, surf.scales(0.75), albedo, 0.99, bone, shade=False))
    return parts


def _lid_point(centre, az, el, r):
    return centre[None] + r[:, None] * np.stack([np.cos(el) * np.sin(az), np.sin(el), np.cos(el) * np.cos(az)], 1)


def _lids(rng, n):
    """Upper lids (canonical: open; their closed positions give the blink), lower lids, socket linings."""
    parts, closed = [], []
    for centre, side, m in zip(_eye_centres(), (1, -1), (n // 2, n - n // 2)):
        mu, ml = int(m * 0.55), int(m * 0.2)
        mw = m - mu - ml
        r_lid = EYE_RADIUS + 0.0010
        az_max = math.radians(78)
        # upper lid: azimuth x elevation grid, s = 0 at the top, 1 at the edge
        surf = _sample(rng, lambda uv: _lid_point(centre, uv[:, 0], LID_TOP + uv[:, 1] * (LID_OPEN - LID_TOP),
                                                  r_lid + 0.0006 * (1 - uv[:, 1])),
                       mu, (-az_max, 0.0), (az_max, 1.0), flip_to=lambda q: q - centre)
        az, s = surf.uv[:, 0], surf.uv[:, 1]
        r = r_lid + 0.0006 * (1 - s)
        p_closed = _lid_point(centre, az, LID_TOP + s * (LID_CLOSED - LID_TOP), r)
        albedo = np.tile(SKIN * 0.93, (mu, 1))
        albedo[s > 0.88] = [0.12, 0.08, 0.07]  # lashes along the edge
        # the edge travels 2.2x further than the top: widen along the lid to cover when closed
        sc = surf.scales(0.75)
        sc[:, 1] *= 1 + 1.2 * s
        parts.append(_Part("lids", surf.p, surf.normal, surf.tangent, sc, albedo, 0.98, HEAD))
        closed.append((side, p_closed - surf.p))
        # lower lid: a fixed band below the eye
        surf = _sample(rng, lambda uv: _lid_point(centre, uv[:, 0], uv[:, 1], np.full(len(uv), r_lid)),
                       ml, (-az_max, math.radians(-62)), (az_max, LID_LOW_TOP), flip_to=lambda q: q - centre)
        parts.append(_Part("lids", surf.p, surf.normal, surf.tangent, surf.scales(0.75), SKIN * 0.95, 0.98, HEAD))
        closed.append((0, np.zeros((ml, 3))))
        # socket lining: a wall from the edge of the eye opening down onto the eyeball
        def wall(uv, c=centre, sd=side):
            t, depth = uv[:, 0], uv[:, 1]
            ex = np.cos(t)
            bx = sd * EYE_X + ALMOND[0] * ex
            by = EYE_Y + ALMOND[1] * np.sign(np.sin(t)) * np.abs(np.sin(t)) ** 0.8
            face_z = _face_point(bx, by)[:, 2]
            rr = np.minimum((bx - c[0]) ** 2 + (by - c[1]) ** 2, (EYE_RADIUS * 0.98) ** 2)
            ball_z = c[2] + np.sqrt(EYE_RADIUS ** 2 - rr)
            pull = 0.25 * depth
            return np.stack([bx + (c[0] - bx) * pull, by + (c[1] - by) * pull,
                             face_z + (ball_z - 0.001 - face_z) * depth], 1)

        surf = _sample(rng, wall, mw, (0.0, 0.0), (2 * math.pi, 1.0),
                       flip_to=lambda q, c=centre: (c - q) * [1, 1, 0] + [0, 0, 1e-3])
        parts.append(_Part("lids", surf.p, surf.normal, surf.tangent, surf.scales(0.8), [0.74, 0.52, 0.46], 0.98,
                           HEAD, shade=False))
        closed.append((0, np.zeros((mw, 3))))
    return parts, closed


def _brows(rng, skin, n):
    """Short dark strands copied from the skin over the brow arcs, a little in front of it."""
    x, y = skin.p[:, 0], skin.p[:, 1]
    sel = np.zeros(len(x), bool)
    for s in (1, -1):
        dx = (x - s * EYE_X) * s                     # > 0 towards the temple
        centre = 0.046 + 0.006 * (1 - (dx / 0.021) ** 2) - 0.002 * (dx > 0.012)
        thick = 0.0032 * (1.2 - 0.5 * smoothstep(-0.02, 0.022, dx))
        sel |= (np.abs(dx + 0.001) < 0.022) & (np.abs(y - centre) < thick) & (skin.p[:, 2] > 0.05)
    idx = np.flatnonzero(sel)
    idx = rng.choice(idx, size=n, replace=len(idx) < n)
    p = skin.p[idx] + skin.normal[idx] * 0.0009 + rng.normal(0, 0.0004, (n, 3))
    tan = np.tile([1.0, 0.15, 0.0], (n, 1)) * np.sign(p[:, :1])
    albedo = HAIR[None] * (0.8 + 0.4 * rng.random((n, 1)))
    sc = 0.0006
    return _Part("brows", p, skin.normal[idx], tan, (3.0 * sc, 0.9 * sc, 0.5 * sc), albedo, 0.95, HEAD)


def _teeth(rng, n):
    parts = []
    radius = 0.024
    z0 = _face_point([0.0], [-0.046])[0, 2] - 0.012 - radius
    for upper, m in ((True, n // 2), (False, n - n // 2)):
        y0, y1 = (-0.0458, -0.0365) if upper else (-0.0545, -0.0462)

        def param(uv):
            a, y = uv[:, 0], uv[:, 1]
            return np.stack([radius * np.sin(a), y, z0 + radius * np.cos(a)], 1)

        surf = _sample(rng, param, m, (-0.85, y0), (0.85, y1), flip_to=lambda q: (q - [0, 0, z0]) * [1, 0, 1])
        gap = np.abs(((surf.uv[:, 0] / 0.16) % 1.0) - 0.5) > 0.45
        albedo = np.where(gap[:, None], [0.70, 0.66, 0.58], [0.96, 0.94, 0.86])
        parts.append(_Part("teeth", surf.p, surf.normal, surf.tangent, surf.scales(), albedo, 0.98,
                           HEAD if upper else JAW))
    return parts


def _cavity(rng, n):
    centre = np.array([0.0, -0.047, _face_point([0.0], [-0.046])[0, 2] - 0.028])
    radii = np.array([0.030, 0.018, 0.022])
    surf = _sample(rng, lambda uv: centre[None] + radii[None] * _sphere_param(uv), n, (-1, 0), (1, 2 * math.pi),
                   keep=lambda q, uv: q[:, 2] < centre[2] + 0.016, flip_to=lambda q: centre[None] - q)
    p = surf.p
    albedo = np.where((p[:, 1] < centre[1] - 0.004)[:, None], [0.55, 0.22, 0.25], [0.28, 0.06, 0.08])
    cheek = smoothstep(0.016, 0.026, np.abs(p[:, 0]))[:, None]   # the insides of the cheeks, seen at the corners
    albedo = albedo * (1 - cheek) + cheek * np.array([0.62, 0.34, 0.33])
    wj = smoothstep(centre[1] + 0.004, centre[1] - 0.004, p[:, 1])
    weights = np.zeros((n, len(DEMO_BONES)))
    weights[:, JAW] = wj
    weights[:, HEAD] = 1 - wj
    return _Part("cavity", p, surf.normal, surf.tangent, surf.scales(), albedo, 0.98, weights, shade=False)


# ------------------------------------------------------------------ blendshapes

def _expression_offsets(p, part_names):
    """(10, m, 3) position offsets per unit control of DEMO_EXPRESSIONS, for points p (m, 3)."""
    x, y, z = p[:, 0], p[:, 1], p[:, 2]
    face = np.isin(part_names, ["skin", "brows"]) * smoothstep(0.02, 0.06, z)
    out = np.zeros((len(DEMO_EXPRESSIONS), len(p), 3))
    sgn = np.sign(x)
    corner = _gauss(np.abs(x), y, 0.025, -0.045, 0.011, 0.010)
    cheek = _gauss(np.abs(x), y, 0.042, -0.018, 0.015, 0.014)

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
    puff = _gauss(np.abs(x), y, 0.045, -0.040, 0.016, 0.016) * face
    out[6] = np.stack([sgn * 0.0060 * puff, np.zeros_like(x), 0.0035 * puff], 1)
    sneer = _gauss(np.abs(x), y, 0.011, -0.030, 0.010, 0.008) * face
    out[7, :, 1] = 0.0040 * sneer
    out[7, :, 2] = 0.0010 * sneer
    out[8] = smile_field(smoothstep(-0.004, 0.004, x))
    out[9] = smile_field(smoothstep(0.004, -0.004, x))
    return out


# ------------------------------------------------------------------ assembly

def demo_avatar_arrays(seed: int = 0, count: int = 100_000) -> dict[str, np.ndarray]:
    """The demo avatar as rig-file arrays (see :mod:`.rig`); exactly ``count`` Gaussians (>= 2000)."""
    if isinstance(count, bool) or not isinstance(count, (int, np.integer)) or count < 2000:
        from ..errors import InputError
        raise InputError(f"count {count!r} is too small", source="count", hint="use at least 2000 Gaussians")
    started = time.perf_counter()
    rng = np.random.default_rng(seed)
    k = {name: max(int(round(share * count)), 8) for name, share in _SHARES.items()}
    n_skin = count - sum(k.values())
    skin = _skin(rng, n_skin)
    parts = [skin, *_hair(rng, k["hair"]), _neck(rng, k["neck"]), _collar(rng, k["collar"])]
    parts += _ears(rng, k["ears"])
    parts += _eyes(rng, k["sclera"], k["iris"])
    lid_parts, lid_closed = _lids(rng, k["lids"])
    lid_first = sum(len(q.p) for q in parts)
    parts += lid_parts
    parts.append(_brows(rng, skin, k["brows"]))
    parts += _teeth(rng, k["teeth"])
    parts.append(_cavity(rng, k["cavity"]))

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

    quats = _frame_quats(n, tangent)

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

    eyes = _eye_centres()
    pivots = np.array([NECK_PIVOT, (0.0, -0.06, -0.02), JAW_PIVOT, eyes[0], eyes[1]], dtype=np.float32)
    bone_controls = np.array([layout.slice("neck").start, -1, layout.slice("jaw").start,
                              layout.slice("eyes").start, layout.slice("eyes").start + 3], dtype=np.int32)
    eps = 1e-4
    op = np.clip(opacity, eps, 1 - eps)
    provenance = {"made_by": "lenticalib.render.demo_avatar.make_demo_avatar", "seed": int(seed),
                  "count": int(count), "seconds": round(time.perf_counter() - started, 3),
                  "expressions": list(DEMO_EXPRESSIONS), "units": "metres, y up, facing +z"}
    return {
        "format": np.array(RIG_FORMAT), "version": np.array(RIG_VERSION, dtype=np.int32),
        "means": p.astype(np.float32), "quats": quats.astype(np.float32),
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
        "provenance": np.array(__import__("json").dumps(provenance, sort_keys=True)),
        "part_names": names,  # not part of the format: dropped by make_demo_avatar, kept for inspection
    }


def make_demo_avatar(seed: int = 0, count: int = 100_000, device: str = "cpu") -> Rig:
    """The demo avatar (module docstring) as a :class:`~.rig.Rig` on ``device``; seconds to build."""
    arrays = demo_avatar_arrays(seed, count)
    arrays.pop("part_names")
    return rig_from_arrays(arrays, source="demo avatar", device=device)
