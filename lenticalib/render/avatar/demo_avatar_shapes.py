"""The demo avatar's geometry: the head surface, parameterised surfaces, and sampling them with Gaussians.

Pure numpy shape helpers for :mod:`.demo_avatar_parts` (which places the parts of the head) and
:mod:`.demo_avatar` (which assembles them into a rig).  Frame and units as there: metres, world
y up, the avatar facing +z, "left" the avatar's own left (+x).

    head_surface, face_point     the head: an ellipsoid warped into a face (nose, eye sockets, brow
                                 ridge, cheekbones, lips, chin), from directions or from x, y in front
    sphere_param, head_param,    parameterisations uv (m, 2) -> points (m, 3)
    sphere_at, lid_point
    sample_surface, Surface      exactly n stratified points on a parameterised surface, with normals,
                                 tangents and the size of each point's cell
    frame_quats                  the Gaussian rotations that lay them flat on the surface
    mouth_line, lip_thickness, hairline, in_almond, neck_radius, eye_centres: landmarks of the face
"""

from __future__ import annotations

import math

import numpy as np

HEAD_CENTRE = np.array([0.0, 0.01, -0.005])   # centre of the warped ellipsoid the head is made of
AXES = (0.076, 0.118, 0.122, 0.097)           # x, y above, y below, z semi-axes, metres
EYE_X, EYE_Y, EYE_RADIUS = 0.033, 0.026, 0.0132  # eye centres at (+-EYE_X, EYE_Y, z_eye), eyeball radius
EYE_FORWARD = 0.0045                          # how far the eyeball's front stands out of the face surface
ALMOND = (0.0108, 0.0088)                     # half width, half height of the eye openings


def smoothstep(e0, e1, x):
    t = np.clip((np.asarray(x, dtype=np.float64) - e0) / (e1 - e0), 0.0, 1.0)
    return t * t * (3 - 2 * t)


def gauss(x, y, cx, cy, sx, sy):
    return np.exp(-0.5 * (((x - cx) / sx) ** 2 + ((y - cy) / sy) ** 2))


# ------------------------------------------------------------------ the head surface

def mouth_line(x):
    """y of the line where the lips meet (metres), for |x| up to the mouth corners."""
    return -0.046 + 0.003 * (np.clip(np.abs(x) / 0.025, 0, 1.4)) ** 2


def lip_thickness(x):
    """(upper, lower) lip heights above / below the mouth line at x."""
    ax = np.clip(np.abs(x) / 0.026, 0, 1)
    base = np.sqrt(np.clip(1 - ax ** 2, 0, 1))
    upper = (0.0060 + 0.0015 * np.exp(-((np.abs(x) - 0.005) / 0.004) ** 2)) * base ** 0.7
    lower = 0.0085 * base ** 0.8
    return upper, lower


def head_surface(d):
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
    wings = 0.0085 * (gauss(X, Y, 0.0115, -0.017, 0.0050, 0.0045) + gauss(X, Y, -0.0115, -0.017, 0.0050, 0.0045))
    sockets = -0.011 * (gauss(X, Y, EYE_X, EYE_Y, 0.017, 0.012) + gauss(X, Y, -EYE_X, EYE_Y, 0.017, 0.012))
    brow = 0.0055 * np.exp(-0.5 * ((Y - 0.046) / 0.006) ** 2) * np.exp(-(X / 0.058) ** 4)
    cheeks = 0.0065 * (gauss(X, Y, 0.043, -0.006, 0.016, 0.013) + gauss(X, Y, -0.043, -0.006, 0.016, 0.013))
    ym = mouth_line(X)
    up, lo = lip_thickness(X)
    lips = (0.0040 * np.exp(-0.5 * ((Y - ym - 0.6 * up) / np.maximum(0.45 * up, 1e-4)) ** 2) * (up > 1e-4)
            + 0.0050 * np.exp(-0.5 * ((Y - ym + 0.55 * lo) / np.maximum(0.5 * lo, 1e-4)) ** 2) * (lo > 1e-4))
    line = -0.0015 * np.exp(-0.5 * ((Y - ym) / 0.0008) ** 2) * np.exp(-(X / 0.026) ** 6)
    sulcus = -0.0030 * gauss(X, Y, 0.0, -0.066, 0.013, 0.005)
    chin = 0.0075 * gauss(X, Y, 0.0, -0.084, 0.015, 0.011)
    bumps = nose + wings + sockets + brow + cheeks + lips + line + sulcus + chin
    Z = Z + bumps * f
    concavity = np.clip(-(sockets + line + sulcus) * f, 0, None)
    return np.stack([X, Y, Z], 1), concavity


def sphere_param(uv):
    """Equal-area parameterisation of the unit sphere, y the polar axis: u in [-1, 1], v in [0, 2 pi)."""
    u, v = uv[:, 0], uv[:, 1]
    s = np.sqrt(np.clip(1 - u * u, 0, 1))
    return np.stack([s * np.sin(v), u, s * np.cos(v)], 1)


def head_param(uv):
    return head_surface(sphere_param(uv))[0]


def face_point(x, y):
    """Points of the head surface in front with the given x and y (arrays), by fixed-point iteration."""
    x = np.asarray(x, dtype=np.float64)
    y = np.asarray(y, dtype=np.float64)
    ax, ay_up, _, az = AXES
    dx = (x - HEAD_CENTRE[0]) / ax
    dy = (y - HEAD_CENTRE[1]) / ay_up
    d = np.stack([dx, dy, np.sqrt(np.clip(1 - dx * dx - dy * dy, 0.05, 1))], 1)
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    for _ in range(30):
        p, _ = head_surface(d)
        d[:, 0] += (x - p[:, 0]) / ax
        d[:, 1] += (y - p[:, 1]) / ay_up
        d /= np.linalg.norm(d, axis=1, keepdims=True)
    return head_surface(d)[0]


# ------------------------------------------------------------------ landmarks

def hairline(d, Y):
    """(under the hair?, height above the hairline) for head surface points of direction d and height Y."""
    dz, dx = d[:, 2], d[:, 0]
    h = np.interp(dz, [-1.0, -0.65, -0.25, 0.05, 0.35, 0.6, 1.0],
                  [-0.072, -0.068, 0.008, 0.036, 0.052, 0.075, 0.078])
    phi = np.arctan2(dx, dz)
    h = h + 0.0025 * np.sin(phi * 23) + 0.0015 * np.sin(phi * 57 + 1.0)
    return Y > h, Y - h


def in_almond(x, y, side, grow=0.0):
    """Whether (x, y) lies in the eye opening on ``side`` (1 the avatar's left, -1 its right), widened by ``grow``."""
    ex = (x - side * EYE_X) / (ALMOND[0] + grow)
    return (np.abs(ex) < 1) & (np.abs(y - EYE_Y) < (ALMOND[1] + grow) * np.sqrt(np.clip(1 - ex * ex, 0, 1)) ** 0.8)


def neck_radius(y):
    """The neck's radius at height y as a factor: 1 higher up, flaring to 1.35 at the shoulders."""
    return 1 + 0.35 * smoothstep(-0.16, -0.215, y) ** 1.5


def eye_centres():
    """The eyeball centres, the avatar's left (+x) eye first."""
    z = face_point([EYE_X, -EYE_X], [EYE_Y, EYE_Y])[:, 2]
    return [np.array([s * EYE_X, EYE_Y, zz + EYE_FORWARD - EYE_RADIUS]) for s, zz in zip((1, -1), z)]


# ------------------------------------------------------------------ more surfaces

def sphere_at(centre, r):
    """Sphere about ``centre`` with polar axis +z: u = cos(angle from +z), v = azimuth."""
    def param(uv):
        u, v = uv[:, 0], uv[:, 1]
        s = np.sqrt(np.clip(1 - u * u, 0, 1))
        return centre[None] + r * np.stack([s * np.cos(v), s * np.sin(v), u], 1)
    return param


def lid_point(centre, az, el, r):
    """Points at azimuth ``az`` (about +y, 0 = +z) and elevation ``el`` (radians) at distance ``r`` from ``centre``."""
    return centre[None] + r[:, None] * np.stack([np.cos(el) * np.sin(az), np.sin(el), np.cos(el) * np.cos(az)], 1)


# ------------------------------------------------------------------ sampling

class Surface:
    """Points sampled on a parametric surface: centres, unit normals, unit tangents (along P_u), uv, cells.

    ``cell`` (m, 2) is the size of each point's sampling cell on the surface along the tangent and
    along normal x tangent: a Gaussian about 0.7 cell wide covers the surface without holes.
    """

    def __init__(self, p, normal, tangent, uv, cell):
        self.p, self.normal, self.tangent, self.uv, self.cell = p, normal, tangent, uv, cell

    def scales(self, k=0.7, thin=0.2):
        # a cell is measured by finite differences of the parameterisation, which blow up where
        # it is singular (a sphere's pole): no cell may exceed 4x the surface's typical cell
        cap = 4.0 * np.median(self.cell, axis=0)
        c = k * np.minimum(self.cell, cap[None, :])
        return np.stack([c[:, 0], c[:, 1], thin * np.sqrt(c[:, 0] * c[:, 1])], 1)


def sample_surface(rng, param, n, lo, hi, keep=None, flip_to=None, jitter=0.7):
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
    return Surface(p, nrm, tan, uv, cell)


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


def frame_quats(normal, tangent):
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
