"""The parts of the demo avatar's head (skin, hair, neck, collar, ears, eyes, lids, brows, teeth, mouth
cavity): where each part's Gaussians sit, their colour, and the bones (:data:`DEMO_BONES`) they follow.

Each ``make_*`` function samples its part's surface (:mod:`.demo_avatar_shapes`) and returns
:class:`Part` objects; :mod:`.demo_avatar` shares the Gaussians out among them and assembles the rig.
"""

from __future__ import annotations

import math

import numpy as np

from .demo_avatar_shapes import (ALMOND, AXES, EYE_RADIUS, EYE_X, EYE_Y, HEAD_CENTRE, eye_centres, face_point,
    gauss, hairline, head_param, head_surface, in_almond, lid_point, lip_thickness, mouth_line, neck_radius,
    sample_surface, smoothstep, sphere_at, sphere_param)

DEMO_BONES = ("neck", "head", "jaw", "eye_l", "eye_r")
NECK, HEAD, JAW, EYE_L, EYE_R = range(5)
LID_TOP, LID_OPEN, LID_CLOSED, LID_LOW_TOP = (math.radians(a) for a in (62, 24, -26, -22))

SKIN = np.array([0.87, 0.66, 0.54])
HAIR = np.array([0.20, 0.12, 0.07])


class Part:
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

def make_skin(rng, n):
    def keep(p, uv):
        x, y, z = p[:, 0], p[:, 1], p[:, 2]
        ok = ~((in_almond(x, y, 1) | in_almond(x, y, -1)) & (z > 0.03))
        ok &= ~((y < -0.07) & ((x / 0.050) ** 2 + ((z + 0.022) / 0.052) ** 2 < 0.7))  # inside the neck
        return ok

    surf = sample_surface(rng, head_param, n, (-1, 0), (1, 2 * math.pi), keep, flip_to=lambda q: q - HEAD_CENTRE)
    p, nrm = surf.p, surf.normal
    d = sphere_param(surf.uv)
    _, conc = head_surface(d)
    x, y, z = p[:, 0], p[:, 1], p[:, 2]
    albedo = np.tile(SKIN, (n, 1))
    ym = mouth_line(x)
    up, lo = lip_thickness(x)
    lip = (y > ym - lo) & (y < ym + up) & (np.abs(x) < 0.027) & (z > 0.05)
    albedo[lip] = [0.74, 0.36, 0.37]
    albedo[lip & (np.abs(y - ym) < 0.0008)] = [0.40, 0.14, 0.14]
    blush = 0.5 * (gauss(x, y, 0.045, -0.012, 0.014, 0.011) + gauss(x, y, -0.045, -0.012, 0.014, 0.011)
                   + 0.5 * gauss(x, y, 0.0, -0.012, 0.008, 0.006)) * (z > 0)
    albedo = albedo * (1 - 0.10 * blush[:, None]) + blush[:, None] * 0.10 * np.array([0.92, 0.45, 0.45])
    nostril = ((np.abs(np.abs(x) - 0.0068) < 0.0024) & (np.abs(y + 0.0205) < 0.0017) & (nrm[:, 1] < -0.5)
               & (z > 0.09))
    albedo[nostril] = [0.42, 0.22, 0.20]
    scalp, _ = hairline(d, y)
    albedo[scalp] = HAIR * 0.7
    weights = np.zeros((n, len(DEMO_BONES)))
    wj = jaw_weight(p)
    weights[:, JAW] = wj
    weights[:, HEAD] = 1 - wj
    return Part("skin", p, nrm, surf.tangent, surf.scales(), albedo, 0.96, weights, ao=conc * 25)


def jaw_weight(p):
    """How much a point of the lower face follows the jaw: 1 below the lips, 0 above, soft at the cheeks."""
    x, y, z = p[:, 0], p[:, 1], p[:, 2]
    ax = np.abs(x)
    ym = mouth_line(np.minimum(ax, 0.025))
    over = np.clip(ax - 0.019, 0, None)
    line = ym - 0.9 * over          # the jaw's upper edge falls from the mouth corners towards the jaw angle
    band = 0.0007 + 0.9 * over      # and softens there, so the corners stretch instead of tearing
    w = smoothstep(line + band, line - band, y)
    return w * smoothstep(-0.03, 0.035, z)


def make_hair(rng, n):
    def keep(p, uv):
        return hairline(sphere_param(uv), p[:, 1])[0]

    layers = (0.30, 0.65, 1.0)
    counts = (n // 4, n // 3, n - n // 4 - n // 3)
    crown = np.array([0.0, 0.14, -0.035])
    out = []
    for f, m in zip(layers, counts):
        surf = sample_surface(rng, head_param, m, (-1, 0), (1, 2 * math.pi), keep, flip_to=lambda q: q - HEAD_CENTRE)
        d = sphere_param(surf.uv)
        _, above = hairline(d, surf.p[:, 1])
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
        out.append(Part("hair", q, surf.normal, flow, scales, albedo, 0.92, HEAD))
    return out



def make_neck(rng, n):
    def param(uv):
        a, y = uv[:, 0], uv[:, 1]
        r = neck_radius(y)
        return np.stack([0.050 * r * np.sin(a), y, -0.022 + 0.052 * r * np.cos(a)], 1)

    def keep(p, uv):
        return (((p - HEAD_CENTRE) / [AXES[0] * 0.95, AXES[2] * 0.97, AXES[3] * 0.95]) ** 2).sum(1) > 1

    surf = sample_surface(rng, param, n, (0, -0.205), (2 * math.pi, -0.03), keep,
                   flip_to=lambda q: (q - [0, 0, -0.022]) * [1, 0, 1])
    p = surf.p
    p[:, 2] += 0.004 * gauss(p[:, 0], p[:, 1], 0.0, -0.125, 0.008, 0.01) * (p[:, 2] > 0)  # Adam's apple
    weights = np.zeros((n, len(DEMO_BONES)))
    weights[:, NECK] = smoothstep(-0.185, -0.09, p[:, 1])
    return Part("neck", p, surf.normal, surf.tangent, surf.scales(), SKIN * 0.97, 0.96, weights)


def make_collar(rng, n):
    def param(uv):
        a, t = uv[:, 0], uv[:, 1]  # t in [0, 1] across the roll of the collar
        y = -0.208 + 0.030 * t
        r = neck_radius(y) + 0.010 * np.sin(t * math.pi) / 0.05
        return np.stack([0.050 * r * np.sin(a), y, -0.022 + 0.052 * r * np.cos(a)], 1)

    surf = sample_surface(rng, param, n, (0, 0), (2 * math.pi, 1), flip_to=lambda q: (q - [0, 0, -0.022]) * [1, 0, 1])
    knit = 0.85 + 0.15 * (np.sin(surf.uv[:, 0] * 90) > 0)
    albedo = np.array([0.13, 0.33, 0.38])[None] * knit[:, None]
    return Part("collar", surf.p, surf.normal, surf.tangent, surf.scales(), albedo, 0.97, None)


def ear_geometry(side):
    """One ear (``side`` 1 the avatar's left, -1 its right): ``param(uv, layer)`` the surface over
    u 0..1 back from the root and v -1..1 bottom to top (``layer`` metres along ``out``, 0 the front
    layer), ``half_width(v)`` the half width in u of the ear's outline about u = 0.5, and ``out``
    (3,) the unit vector away from the head."""
    root = np.array([side * 0.0705, 0.008, 0.006])
    back = np.array([side * math.sin(math.radians(38)), 0.0, -math.cos(math.radians(38))])
    upv = np.array([0.0, 1.0, 0.0])
    out = np.cross(upv, back)
    out *= np.sign(out[0] * side)             # away from the head

    def half_width(v):
        return 0.5 * (1 + 0.3 * v) * np.sqrt(np.clip(1 - v * v, 0, 1)) ** 0.7

    def param(uv, layer):
        u, v = uv[:, 0], uv[:, 1]
        edge = np.clip(np.abs(u - 0.5) / np.maximum(half_width(v), 1e-3), 0, 1)
        rim = smoothstep(0.6, 0.95, np.maximum(edge, np.abs(v))) * (u > 0.3)
        bowl = np.exp(-(((u - 0.40) / 0.22) ** 2 + ((v + 0.05) / 0.40) ** 2))
        depth = 0.0050 * rim - 0.0045 * bowl + 0.004 * np.clip(u, 0, None) ** 1.5 + layer
        return (root[None] + (0.036 * u)[:, None] * back[None] + (0.033 * v)[:, None] * upv[None]
                + depth[:, None] * out[None])

    return param, half_width, out


def make_ears(rng, n):
    """Two ears standing out from the sides: a rim (helix), a bowl, a lobe; two layers (front and back)."""
    parts = []
    for side, m in ((1, n // 2), (-1, n - n // 2)):
        param, half_width, out = ear_geometry(side)

        for layer, k in ((0.0, int(round(m * 0.6))), (-0.0028, m - int(round(m * 0.6)))):
            surf = sample_surface(rng, lambda q, L=layer: param(q, L), k, (0.0, -1.0), (1.0, 1.0),
                           keep=lambda q, uv: np.abs(uv[:, 0] - 0.5) < half_width(uv[:, 1]),
                           flip_to=lambda q, f=(out if layer == 0.0 else -out): np.broadcast_to(f, q.shape))
            u, v = surf.uv[:, 0], surf.uv[:, 1]
            bowl = np.exp(-(((u - 0.40) / 0.22) ** 2 + ((v + 0.05) / 0.40) ** 2))
            parts.append(Part("ears", surf.p, surf.normal, surf.tangent, surf.scales(0.75), [0.88, 0.62, 0.52],
                               0.97, HEAD, ao=0.35 * bowl if layer == 0.0 else None))
    return parts



def make_eyes(rng, n_sclera, n_iris):
    parts = []
    for centre, bone, m, k in zip(eye_centres(), (EYE_L, EYE_R), (n_sclera // 2, n_sclera - n_sclera // 2),
                                  (n_iris // 2, n_iris - n_iris // 2)):
        surf = sample_surface(rng, sphere_at(centre, EYE_RADIUS), m, (-0.3, 0), (math.cos(0.45), 2 * math.pi),
                       flip_to=lambda q, c=centre: q - c)
        ang = np.arccos(np.clip(surf.uv[:, 0], -1, 1))
        albedo = np.tile([0.95, 0.94, 0.91], (m, 1)) * (1 - 0.25 * smoothstep(0.9, 1.6, ang))[:, None]
        parts.append(Part("sclera", surf.p, surf.normal, surf.tangent, surf.scales(), albedo, 0.98, bone))
        # iris and pupil: a cap of half-angle 0.47 rad, slightly in front of the sclera
        surf = sample_surface(rng, sphere_at(centre, EYE_RADIUS + 0.0003), k, (math.cos(0.47), 0), (1, 2 * math.pi),
                       flip_to=lambda q, c=centre: q - c)
        ang = np.arccos(np.clip(surf.uv[:, 0], -1, 1))
        iris = np.array([0.22, 0.42, 0.52]) * (0.8 + 0.4 * np.sin(surf.uv[:, 1] * 37) ** 2)[:, None]
        iris = iris * (1 - 0.5 * smoothstep(0.36, 0.47, ang))[:, None]
        albedo = np.where((ang < 0.19)[:, None], [0.03, 0.03, 0.035], iris)
        glint = gauss(surf.p[:, 0], surf.p[:, 1], centre[0] + 0.0020, centre[1] + 0.0024, 0.0006, 0.0006)
        albedo = albedo + glint[:, None] * (1.0 - albedo)
        p = surf.p + surf.normal * np.where(ang < 0.19, 0.0002, 0.0)[:, None]
        parts.append(Part("iris", p, surf.normal, surf.tangent, surf.scales(0.75), albedo, 0.99, bone, shade=False))
    return parts



def make_lids(rng, n):
    """Upper lids (canonical: open; their closed positions give the blink), lower lids, socket linings."""
    parts, closed = [], []
    for centre, side, m in zip(eye_centres(), (1, -1), (n // 2, n - n // 2)):
        mu, ml = int(m * 0.55), int(m * 0.2)
        mw = m - mu - ml
        r_lid = EYE_RADIUS + 0.0010
        az_max = math.radians(78)
        # upper lid: azimuth x elevation grid, s = 0 at the top, 1 at the edge
        surf = sample_surface(rng, lambda uv: lid_point(centre, uv[:, 0], LID_TOP + uv[:, 1] * (LID_OPEN - LID_TOP),
                                                  r_lid + 0.0006 * (1 - uv[:, 1])),
                       mu, (-az_max, 0.0), (az_max, 1.0), flip_to=lambda q: q - centre)
        az, s = surf.uv[:, 0], surf.uv[:, 1]
        r = r_lid + 0.0006 * (1 - s)
        p_closed = lid_point(centre, az, LID_TOP + s * (LID_CLOSED - LID_TOP), r)
        albedo = np.tile(SKIN * 0.93, (mu, 1))
        albedo[s > 0.88] = [0.12, 0.08, 0.07]  # lashes along the edge
        # the edge travels 2.2x further than the top: widen along the lid to cover when closed
        sc = surf.scales(0.75)
        sc[:, 1] *= 1 + 1.2 * s
        parts.append(Part("lids", surf.p, surf.normal, surf.tangent, sc, albedo, 0.98, HEAD))
        closed.append((side, p_closed - surf.p))
        # lower lid: a fixed band below the eye
        surf = sample_surface(rng, lambda uv: lid_point(centre, uv[:, 0], uv[:, 1], np.full(len(uv), r_lid)),
                       ml, (-az_max, math.radians(-62)), (az_max, LID_LOW_TOP), flip_to=lambda q: q - centre)
        parts.append(Part("lids", surf.p, surf.normal, surf.tangent, surf.scales(0.75), SKIN * 0.95, 0.98, HEAD))
        closed.append((0, np.zeros((ml, 3))))
        # socket lining: a wall from the edge of the eye opening down onto the eyeball
        def wall(uv, c=centre, sd=side):
            t, depth = uv[:, 0], uv[:, 1]
            ex = np.cos(t)
            bx = sd * EYE_X + ALMOND[0] * ex
            by = EYE_Y + ALMOND[1] * np.sign(np.sin(t)) * np.abs(np.sin(t)) ** 0.8
            face_z = face_point(bx, by)[:, 2]
            rr = np.minimum((bx - c[0]) ** 2 + (by - c[1]) ** 2, (EYE_RADIUS * 0.98) ** 2)
            ball_z = c[2] + np.sqrt(EYE_RADIUS ** 2 - rr)
            pull = 0.25 * depth
            return np.stack([bx + (c[0] - bx) * pull, by + (c[1] - by) * pull,
                             face_z + (ball_z - 0.001 - face_z) * depth], 1)

        surf = sample_surface(rng, wall, mw, (0.0, 0.0), (2 * math.pi, 1.0),
                       flip_to=lambda q, c=centre: (c - q) * [1, 1, 0] + [0, 0, 1e-3])
        parts.append(Part("lids", surf.p, surf.normal, surf.tangent, surf.scales(0.8), [0.74, 0.52, 0.46], 0.98,
                           HEAD, shade=False))
        closed.append((0, np.zeros((mw, 3))))
    return parts, closed


def make_brows(rng, skin, n):
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
    return Part("brows", p, skin.normal[idx], tan, (3.0 * sc, 0.9 * sc, 0.5 * sc), albedo, 0.95, HEAD)


def make_teeth(rng, n):
    parts = []
    radius = 0.024
    z0 = face_point([0.0], [-0.046])[0, 2] - 0.012 - radius
    for upper, m in ((True, n // 2), (False, n - n // 2)):
        y0, y1 = (-0.0458, -0.0365) if upper else (-0.0545, -0.0462)

        def param(uv):
            a, y = uv[:, 0], uv[:, 1]
            return np.stack([radius * np.sin(a), y, z0 + radius * np.cos(a)], 1)

        surf = sample_surface(rng, param, m, (-0.85, y0), (0.85, y1), flip_to=lambda q: (q - [0, 0, z0]) * [1, 0, 1])
        gap = np.abs(((surf.uv[:, 0] / 0.16) % 1.0) - 0.5) > 0.45
        albedo = np.where(gap[:, None], [0.70, 0.66, 0.58], [0.96, 0.94, 0.86])
        parts.append(Part("teeth", surf.p, surf.normal, surf.tangent, surf.scales(), albedo, 0.98,
                           HEAD if upper else JAW))
    return parts


def make_cavity(rng, n):
    centre = np.array([0.0, -0.047, face_point([0.0], [-0.046])[0, 2] - 0.028])
    radii = np.array([0.030, 0.018, 0.022])
    surf = sample_surface(rng, lambda uv: centre[None] + radii[None] * sphere_param(uv), n, (-1, 0), (1, 2 * math.pi),
                   keep=lambda q, uv: q[:, 2] < centre[2] + 0.016, flip_to=lambda q: centre[None] - q)
    p = surf.p
    albedo = np.where((p[:, 1] < centre[1] - 0.004)[:, None], [0.55, 0.22, 0.25], [0.28, 0.06, 0.08])
    cheek = smoothstep(0.016, 0.026, np.abs(p[:, 0]))[:, None]   # the insides of the cheeks, seen at the corners
    albedo = albedo * (1 - cheek) + cheek * np.array([0.62, 0.34, 0.33])
    wj = smoothstep(centre[1] + 0.004, centre[1] - 0.004, p[:, 1])
    weights = np.zeros((n, len(DEMO_BONES)))
    weights[:, JAW] = wj
    weights[:, HEAD] = 1 - wj
    return Part("cavity", p, surf.normal, surf.tangent, surf.scales(), albedo, 0.98, weights, shade=False)
