"""The demo avatar's mesh: the surfaces its Gaussians are sampled from, as triangles (a FLAME-like
head mesh: skin and scalp, eyeballs, ears, neck, collar; no hair, as FLAME has none).

Each part is one of the parameterised surfaces of :mod:`.demo_avatar_shapes` and
:mod:`.demo_avatar_parts` evaluated on a regular grid of its parameters and split into
triangles, so the mesh lies on the very surfaces the Gaussians sit on (to within the chord of a
grid cell: under 0.05 mm at these resolutions).  Vertices follow the bones the parts' Gaussians
follow (the jaw weight of the skin, the neck's fade, the eye bones) and the expression
blendshapes of the skin, so the mesh is posed with the Gaussians (:mod:`.rig_mesh`).

:func:`demo_mesh_arrays` returns the rig file's ``mesh_*`` arrays (:mod:`.rig_mesh`).
"""

from __future__ import annotations

import math

import numpy as np

from .demo_avatar_parts import DEMO_BONES, EYE_L, EYE_R, HEAD, JAW, NECK, ear_geometry, jaw_weight
from .demo_avatar_shapes import EYE_RADIUS, eye_centres, head_surface, neck_radius, smoothstep, sphere_at

HEAD_GRID = (120, 240)   # polar x azimuth steps of the head surface
NECK_GRID = (24, 120)    # height x azimuth
COLLAR_GRID = (8, 120)
EAR_GRID = (20, 24)      # across x along
EYE_GRID = (24, 48)


def grid_triangles(rows: int, cols: int, wrap: bool) -> np.ndarray:
    """(F, 3) triangles of a (rows + 1) x cols vertex grid (row-major), columns wrapping around when
    ``wrap`` (a closed ring), else a (rows + 1) x (cols + 1) grid."""
    width = cols if wrap else cols + 1
    i, j = np.meshgrid(np.arange(rows), np.arange(cols), indexing="ij")
    a = i * width + j
    b = i * width + ((j + 1) % width if wrap else j + 1)
    c, d = a + width, b + width
    return np.concatenate([np.stack([a, c, b], -1).reshape(-1, 3), np.stack([b, c, d], -1).reshape(-1, 3)])


def _head():
    nu, nv = HEAD_GRID
    theta = np.linspace(0.0, math.pi, nu + 1)
    phi = np.linspace(0.0, 2 * math.pi, nv, endpoint=False)
    T, P = np.meshgrid(theta, phi, indexing="ij")
    d = np.stack([np.sin(T) * np.sin(P), np.cos(T), np.sin(T) * np.cos(P)], -1).reshape(-1, 3)
    p, _ = head_surface(d)
    w = np.zeros((len(p), len(DEMO_BONES)))
    wj = jaw_weight(p)
    w[:, JAW], w[:, HEAD] = wj, 1 - wj
    return p, grid_triangles(nu, nv, True), w, True


def _ring(rows, cols, point):
    """A ring surface ``point(a, t)`` over azimuth a in [0, 2 pi) and t in [0, 1]."""
    t = np.linspace(0.0, 1.0, rows + 1)
    a = np.linspace(0.0, 2 * math.pi, cols, endpoint=False)
    T, A = np.meshgrid(t, a, indexing="ij")
    return point(A.ravel(), T.ravel()), grid_triangles(rows, cols, True)


def _neck():
    def point(a, t):
        y = -0.205 + t * (-0.03 + 0.205)
        r = neck_radius(y)
        return np.stack([0.050 * r * np.sin(a), y, -0.022 + 0.052 * r * np.cos(a)], 1)

    p, tri = _ring(*NECK_GRID, point)
    w = np.zeros((len(p), len(DEMO_BONES)))
    w[:, NECK] = smoothstep(-0.185, -0.09, p[:, 1])
    return p, tri, w, False


def _collar():
    def point(a, t):
        y = -0.208 + 0.030 * t
        r = neck_radius(y) + 0.010 * np.sin(t * math.pi) / 0.05
        return np.stack([0.050 * r * np.sin(a), y, -0.022 + 0.052 * r * np.cos(a)], 1)

    p, tri = _ring(*COLLAR_GRID, point)
    return p, tri, np.zeros((len(p), len(DEMO_BONES))), False


def _ears():
    out = []
    for side in (1, -1):
        param, half_width, _ = ear_geometry(side)
        nu, nv = EAR_GRID
        s = np.linspace(0.0, 1.0, nu + 1)
        v = np.linspace(-1.0, 1.0, nv + 1)
        S, V = np.meshgrid(s, v, indexing="ij")
        U = 0.5 + (2 * S - 1) * half_width(V)          # the grid spans the ear's outline exactly
        p = param(np.stack([U.ravel(), V.ravel()], 1), 0.0)
        w = np.zeros((len(p), len(DEMO_BONES)))
        w[:, HEAD] = 1.0
        out.append((p, grid_triangles(nu, nv, False), w, False))
    return out


def _eyes():
    out = []
    for centre, bone in zip(eye_centres(), (EYE_L, EYE_R)):
        nu, nv = EYE_GRID
        u = np.cos(np.linspace(0.0, math.pi, nu + 1))
        a = np.linspace(0.0, 2 * math.pi, nv, endpoint=False)
        Uu, A = np.meshgrid(u, a, indexing="ij")
        p = sphere_at(centre, EYE_RADIUS)(np.stack([Uu.ravel(), A.ravel()], 1))
        w = np.zeros((len(p), len(DEMO_BONES)))
        w[:, bone] = 1.0
        out.append((p, grid_triangles(nu, nv, True), w, False))
    return out


def demo_mesh_arrays(expression_offsets, expression_count: int) -> dict[str, np.ndarray]:
    """The demo avatar's ``mesh_*`` rig arrays (:mod:`.rig_mesh`).

    ``expression_offsets(p, part_names)`` gives the (E, m, 3) expression blendshape offsets of
    points p (m, 3) per unit control (the demo avatar's), applied to the skin's vertices; the mesh's
    blendshape entries use blendshapes 0..``expression_count``-1.
    """
    parts = [_head(), _neck(), _collar(), *_ears(), *_eyes()]
    vertices, triangles, weights, skin = [], [], [], []
    first = 0
    for p, tri, w, is_skin in parts:
        vertices.append(p)
        triangles.append(tri + first)
        weights.append(w)
        skin.append(np.full(len(p), is_skin))
        first += len(p)
    p = np.concatenate(vertices)
    is_skin = np.concatenate(skin)
    expr = expression_offsets(p, np.where(is_skin, "skin", "other"))
    index, shape, pos = [], [], []
    for e in range(expression_count):
        nz = np.flatnonzero((np.abs(expr[e]).max(1) > 2e-5) & is_skin)
        index.append(nz)
        shape.append(np.full(len(nz), e))
        pos.append(expr[e, nz])
    return {"mesh_vertices": p.astype(np.float32), "mesh_triangles": np.concatenate(triangles).astype(np.int32),
            "mesh_skin_weights": np.concatenate(weights).astype(np.float32),
            "mesh_blend_index": np.concatenate(index).astype(np.int32),
            "mesh_blend_shape": np.concatenate(shape).astype(np.int32),
            "mesh_blend_pos": np.concatenate(pos).astype(np.float32)}
