"""Triangle meshes of avatars: the surface an avatar's Gaussians should stay on, read from OBJ or PLY.

The LentiAvatar side-view diagnostics (:mod:`.diagnose`) measure how much of a rendered view
lies outside the avatar's mesh.  FLAME-based avatars carry their mesh (a rig file holds it, see
:mod:`.rig_mesh`); for a static 3DGS PLY the user gives it as a file, in the avatar's frame and
units.

    vertices   (V, 3) float64   world units (the avatar's frame)
    triangles  (F, 3) int64     vertex indices, 0-based; F >= 1

:func:`load_mesh_file` reads Wavefront OBJ (``v`` and ``f`` lines; polygons are split into a
fan of triangles; ``f 1/2/3`` and negative, relative indices are understood) and PLY (a
``vertex`` element with x, y, z and a ``face`` element with ``vertex_indices`` or
``vertex_index``, through plyfile, ASCII or binary).  Every problem is one InputError naming
the file.  :func:`check_mesh_fits` compares a mesh's box with the avatar's Gaussians' box, so a
mesh of another avatar (or in other units) is refused before anything is rendered.
"""

from __future__ import annotations

import dataclasses
import os
from pathlib import Path

import numpy as np

from ..core.errors import InputError

# A mesh fits an avatar when the boxes around both overlap by at least this share of the smaller
# box's volume and their diagonals differ by less than this factor (a mesh in millimetres for an
# avatar in metres differs by 1000).
MIN_BOX_OVERLAP = 0.5
MAX_SIZE_RATIO = 2.0


@dataclasses.dataclass(frozen=True)
class TriangleMesh:
    """A triangle mesh: ``vertices`` (V, 3) float64 world units, ``triangles`` (F, 3) int64, and
    ``source``, where it came from (the file)."""

    vertices: np.ndarray
    triangles: np.ndarray
    source: str = "mesh"


def check_mesh(vertices, triangles, source: str) -> TriangleMesh:
    """A :class:`TriangleMesh` from array-likes; one InputError naming ``source`` when there is no
    triangle, an index is out of range, a vertex is not finite or the shapes are wrong."""
    v = np.asarray(vertices, dtype=np.float64)
    t = np.asarray(triangles)
    if v.ndim != 2 or v.shape[1] != 3:
        raise InputError(f"mesh vertices have shape {v.shape}, expected (V, 3)", source=source)
    if t.size == 0:
        raise InputError("the mesh has no triangles", source=source,
                         hint="give a surface mesh (OBJ or PLY with faces), not a point cloud")
    if t.ndim != 2 or t.shape[1] != 3 or t.dtype.kind not in "iu":
        raise InputError(f"mesh triangles have shape {t.shape} dtype {t.dtype}, expected (F, 3) integers",
                         source=source)
    t = t.astype(np.int64)
    if t.min() < 0 or t.max() >= len(v):
        raise InputError(f"a triangle uses vertex {int(t.max() if t.max() >= len(v) else t.min())}, but the mesh "
                         f"has {len(v)} vertices", source=source)
    if not np.isfinite(v[np.unique(t)]).all():
        raise InputError("a mesh vertex is not a finite number", source=source)
    return TriangleMesh(v, t, source)


def load_mesh_file(path: str | os.PathLike) -> TriangleMesh:
    """The triangles of an OBJ or PLY file (module docstring); one InputError naming the file."""
    p = Path(path)
    source = str(p)
    if not p.is_file():
        raise InputError("no such mesh file" if not p.exists() else "is not a file", source=source,
                         hint="give the avatar's mesh as an .obj or .ply file")
    suffix = p.suffix.lower()
    if suffix == ".obj":
        return _load_obj(p, source)
    if suffix == ".ply":
        return _load_ply(p, source)
    raise InputError(f"mesh files must be .obj or .ply, not {suffix or 'no suffix'!r}", source=source)


def _load_obj(p: Path, source: str) -> TriangleMesh:
    vertices: list[tuple[float, float, float]] = []
    triangles: list[tuple[int, int, int]] = []
    try:
        with open(p, encoding="utf-8", errors="replace") as fh:
            for number, line in enumerate(fh, 1):
                parts = line.split()
                if not parts:
                    continue
                if parts[0] == "v":
                    try:
                        vertices.append((float(parts[1]), float(parts[2]), float(parts[3])))
                    except (IndexError, ValueError):
                        raise InputError(f"line {number}: a vertex needs three numbers", source=source) from None
                elif parts[0] == "f":
                    try:
                        corners = [int(c.split("/")[0]) for c in parts[1:]]
                    except ValueError:
                        raise InputError(f"line {number}: a face's vertex indices are not whole numbers",
                                         source=source) from None
                    if len(corners) < 3 or 0 in corners:
                        raise InputError(f"line {number}: a face needs three or more vertex indices "
                                         "(1-based, or negative from the end)", source=source)
                    n = len(vertices)
                    idx = [c - 1 if c > 0 else n + c for c in corners]
                    triangles.extend((idx[0], idx[k], idx[k + 1]) for k in range(1, len(idx) - 1))
    except OSError as exc:
        raise InputError(f"cannot read: {exc.strerror}", source=source) from None
    return check_mesh(np.array(vertices, dtype=np.float64).reshape(-1, 3),
                      np.array(triangles, dtype=np.int64).reshape(-1, 3), source)


def _load_ply(p: Path, source: str) -> TriangleMesh:
    import plyfile

    try:
        ply = plyfile.PlyData.read(str(p))
    except OSError as exc:
        raise InputError(f"cannot read: {exc.strerror}", source=source) from None
    except Exception as exc:  # plyfile raises its own PlyParseError and ValueError/struct errors on bad data
        raise InputError(f"not a readable PLY file ({exc})", source=source) from None
    names = [e.name for e in ply.elements]
    if "vertex" not in names:
        raise InputError("the PLY file has no 'vertex' element", source=source)
    vertex = ply["vertex"].data
    missing = [k for k in "xyz" if k not in vertex.dtype.names]
    if missing:
        raise InputError(f"the PLY vertices have no {', '.join(missing)}", source=source)
    vertices = np.stack([np.asarray(vertex[k], dtype=np.float64) for k in "xyz"], 1)
    if "face" not in names or len(ply["face"].data) == 0:
        return check_mesh(vertices, np.zeros((0, 3), np.int64), source)
    face = ply["face"].data
    key = next((k for k in ("vertex_indices", "vertex_index") if k in face.dtype.names), None)
    if key is None:
        raise InputError("the PLY faces have no 'vertex_indices' list", source=source)
    triangles = []
    for corners in face[key]:
        c = np.asarray(corners, dtype=np.int64)
        if len(c) < 3:
            raise InputError("a PLY face has fewer than three vertices", source=source)
        triangles.extend((c[0], c[k], c[k + 1]) for k in range(1, len(c) - 1))
    return check_mesh(vertices, np.array(triangles, dtype=np.int64).reshape(-1, 3), source)


def check_mesh_fits(mesh_box: tuple[np.ndarray, np.ndarray], avatar_box: tuple[np.ndarray, np.ndarray],
                    source: str) -> None:
    """InputError naming ``source`` unless the mesh's box and the avatar's box (each (min, max)
    (3,), world units) overlap by :data:`MIN_BOX_OVERLAP` of the smaller one and their diagonals
    are within :data:`MAX_SIZE_RATIO` of each other: the mesh is another avatar's, or in other
    units or another frame."""
    (a0, a1), (b0, b1) = (np.asarray(x, np.float64) for x in mesh_box), (np.asarray(x, np.float64) for x in avatar_box)
    size_a, size_b = a1 - a0, b1 - b0
    diag_a, diag_b = float(np.linalg.norm(size_a)), float(np.linalg.norm(size_b))
    # a flat box (a mesh in a plane) still has a volume for the overlap: pad by 1 % of the diagonal
    pad = 0.01 * max(diag_a, diag_b, 1e-12)
    inter = np.clip(np.minimum(a1, b1) - np.maximum(a0, b0) + pad, 0, None).prod()
    smaller = min((size_a + pad).prod(), (size_b + pad).prod())
    ratio = max(diag_a, diag_b) / max(min(diag_a, diag_b), 1e-12)
    if inter < MIN_BOX_OVERLAP * smaller or ratio > MAX_SIZE_RATIO:
        def box(lo, hi):
            return "[" + ", ".join(f"{x:.3g}..{y:.3g}" for x, y in zip(lo, hi)) + "]"

        raise InputError(f"the mesh's box {box(a0, a1)} does not fit the avatar's {box(b0, b1)} "
                         f"({100 * inter / smaller:.0f} % overlap, sizes differ {ratio:.2g} times)", source=source,
                         hint="give the mesh of this avatar, in its frame and units")
