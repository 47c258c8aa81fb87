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

import array
import dataclasses
import os
from pathlib import Path

import numpy as np

from ...core.errors import InputError
from ...core.files.input_files import MIB, bounded_lines, open_input
from .ply import check_ply_counts

# A mesh fits an avatar when the boxes around both overlap by at least this share of the smaller
# box's volume and their diagonals differ by less than this factor (a mesh in millimetres for an
# avatar in metres differs by 1000).
MIN_BOX_OVERLAP = 0.5
MAX_SIZE_RATIO = 2.0

# LIMITS of a mesh file (docs/input-limits.md): a FLAME head has 5023 vertices and 9976 triangles,
# a dense head scan some 10^5; the mesh only masks where the avatar's surface is.
MAX_MESH_BYTES = 128 * MIB  # an OBJ of a million vertices and two million faces with normals and UVs
MAX_MESH_VERTICES = 1_000_000
MAX_MESH_TRIANGLES = 2_000_000  # after polygons are split into fans
MAX_OBJ_LINE = 64 * 1024  # bytes of one OBJ line (a face of some 10 000 corners)
MAX_POLYGON_ROWS = 500_000  # PLY faces read one by one (mixed sizes, ASCII): some 450 bytes each


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
    t = t.astype(np.int64, copy=False)
    if t.min() < 0 or t.max() >= len(v):
        raise InputError(f"a triangle uses vertex {int(t.max() if t.max() >= len(v) else t.min())}, but the mesh "
                         f"has {len(v)} vertices", source=source)
    if not np.isfinite(v[np.unique(t)]).all():
        raise InputError("a mesh vertex is not a finite number", source=source)
    return TriangleMesh(v, t, source)


def load_mesh_file(path: str | os.PathLike) -> TriangleMesh:
    """The triangles of an OBJ or PLY file (module docstring); one InputError naming the file.

    The file must be a regular file of at most :data:`MAX_MESH_BYTES` (checked before it is read);
    its vertices and triangles are counted against :data:`MAX_MESH_VERTICES` and
    :data:`MAX_MESH_TRIANGLES` before they are stored (a PLY's from its header, after its counts are
    checked against the file's size; an OBJ's as its lines are read, each at most
    :data:`MAX_OBJ_LINE` bytes), so a small file claiming millions of faces costs no memory.
    """
    p = Path(path)
    source = str(p)
    suffix = p.suffix.lower()
    hint = "give the avatar's mesh as an .obj or .ply file"
    if suffix not in (".obj", ".ply"):
        if not os.path.lexists(p):
            raise InputError("no such mesh file", source=source, hint=hint)
        raise InputError(f"mesh files must be .obj or .ply, not {suffix or 'no suffix'!r}", source=source)
    if not os.path.lexists(p):
        raise InputError("no such mesh file", source=source, hint=hint)
    with open_input(p, "mesh", MAX_MESH_BYTES, hint) as fh:
        try:
            if suffix == ".obj":
                return _load_obj(fh, source)
            return _load_ply(fh, source)
        except OSError as exc:
            raise InputError(f"cannot read: {exc.strerror or exc}", source=source) from None


def _too_many(count: int | None, limit: int, what: str, source: str) -> InputError:
    """The error for a mesh of ``count`` (None: more than ``limit``, counted so far) ``what``."""
    text = (f"the mesh has more than {limit} {what}, the most a diagnostic mesh may have" if count is None
            else f"the mesh has {count} {what}, more than the {limit} a diagnostic mesh may have")
    return InputError(text, source=source, hint="decimate the mesh; a FLAME head has 9976 triangles")


def _load_obj(fh, source: str) -> TriangleMesh:
    """An OBJ read line by line into flat arrays (8 bytes a number, not Python objects per value)."""
    vertices = array.array("d")
    triangles = array.array("q")
    for number, raw in bounded_lines(fh, MAX_OBJ_LINE, source, why="longer than any OBJ line of a mesh (a face "
                                     "of thousands of corners?)"):
        parts = raw.split()
        if not parts:
            continue
        if parts[0] == b"v":
            if len(vertices) >= 3 * MAX_MESH_VERTICES:
                raise _too_many(None, MAX_MESH_VERTICES, "vertices", source)
            try:
                vertices.extend((float(parts[1]), float(parts[2]), float(parts[3])))
            except (IndexError, ValueError):
                raise InputError(f"line {number}: a vertex needs three numbers", source=source) from None
        elif parts[0] == b"f":
            try:
                corners = [int(c.split(b"/")[0]) for c in parts[1:]]
            except ValueError:
                raise InputError(f"line {number}: a face's vertex indices are not whole numbers",
                                 source=source) from None
            if len(corners) < 3 or 0 in corners:
                raise InputError(f"line {number}: a face needs three or more vertex indices "
                                 "(1-based, or negative from the end)", source=source)
            if len(triangles) + 3 * (len(corners) - 2) > 3 * MAX_MESH_TRIANGLES:
                raise _too_many(None, MAX_MESH_TRIANGLES, "triangles", source)
            n = len(vertices) // 3
            idx = [c - 1 if c > 0 else n + c for c in corners]
            for k in range(1, len(idx) - 1):
                triangles.extend((idx[0], idx[k], idx[k + 1]))
    return check_mesh(np.frombuffer(vertices, dtype=np.float64).reshape(-1, 3),
                      np.frombuffer(triangles, dtype=np.int64).reshape(-1, 3), source)


def fan_triangles(corners: np.ndarray, lengths: np.ndarray) -> np.ndarray:
    """(F, 3) int64 triangles of polygons split into fans: ``corners`` (sum(lengths),) the vertex
    indices of every polygon in turn, ``lengths`` (P,) each polygon's corner count (>= 3)."""
    lengths = np.asarray(lengths, np.int64)
    starts = np.cumsum(lengths) - lengths
    fans = lengths - 2
    polygon = np.repeat(np.arange(len(lengths)), fans)
    k = np.arange(int(fans.sum())) - np.repeat(np.cumsum(fans) - fans, fans)  # 0 .. n-3 within each fan
    first = starts[polygon]
    corners = np.asarray(corners, np.int64)
    return np.stack([corners[first], corners[first + k + 1], corners[first + k + 2]], axis=1)


def _read_ply(fh, source: str, known_list_len: dict):
    """plyfile's reading of ``fh``: with ``known_list_len`` (lists of one length, memory-mapped), None
    when that fails (a face of another length: the caller reads row by row, which names any damage);
    without, one InputError for anything unreadable."""
    import plyfile

    fh.seek(0)
    try:
        return plyfile.PlyData.read(fh, mmap=bool(known_list_len), known_list_len=known_list_len)
    except Exception as exc:  # plyfile raises its own PlyParseError and ValueError/struct errors on bad data
        if known_list_len:  # lists of other lengths ("unexpected list length", "early end-of-file")
            return None
        raise InputError(f"not a readable PLY file ({' '.join(str(exc).split())})", source=source) from None


def _load_ply(fh, source: str) -> TriangleMesh:
    elements = check_ply_counts(fh, source, "PLY mesh")
    if elements is None:
        raise InputError("not a readable PLY mesh (no 'ply' header ending in 'end_header' with element counts "
                         "and known property types)", source=source)
    counts = {e.name: e for e in elements}
    if "vertex" in counts and counts["vertex"].count > MAX_MESH_VERTICES:
        raise _too_many(counts["vertex"].count, MAX_MESH_VERTICES, "vertices", source)
    faces = counts["face"].count if "face" in counts else 0
    if faces > MAX_MESH_TRIANGLES:
        raise _too_many(faces, MAX_MESH_TRIANGLES, "faces", source)
    fh.seek(0)
    ascii_ply = b"format ascii" in fh.read(4096).split(b"end_header")[0]
    # faces of one size (triangles, quads) in a binary file are read as one array mapped from the file;
    # faces of mixed sizes and ASCII files as plyfile's rows, some 450 bytes a face, so fewer of them
    lists = counts["face"].lists if "face" in counts else ()
    ply = None
    for size in () if ascii_ply or not lists else (3, 4):
        ply = _read_ply(fh, source, {"face": {name: size for name in lists}})
        if ply is not None:
            break
    if ply is None:
        if faces > MAX_POLYGON_ROWS:
            raise InputError(f"the mesh has {faces} faces {'in ASCII' if ascii_ply else 'of mixed sizes'}, more than "
                             f"the {MAX_POLYGON_ROWS} read that way", source=source,
                             hint="save it as binary PLY of triangles (or OBJ), or decimate it")
        ply = _read_ply(fh, source, {})
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
    lists = face[key]
    if lists.dtype != object:  # read as one (F, n) array: triangles, or quads split in two
        corners = np.asarray(lists, dtype=np.int64)
        if corners.shape[1] == 3:
            return check_mesh(vertices, corners, source)
        return check_mesh(vertices, fan_triangles(corners.ravel(), np.full(len(corners), corners.shape[1])), source)
    lengths = np.fromiter((len(c) for c in lists), dtype=np.int64, count=len(lists))
    if (lengths < 3).any():
        raise InputError("a PLY face has fewer than three vertices", source=source)
    if int((lengths - 2).sum()) > MAX_MESH_TRIANGLES:
        raise _too_many(int((lengths - 2).sum()), MAX_MESH_TRIANGLES, "triangles", source)
    return check_mesh(vertices, fan_triangles(np.concatenate(list(lists)), lengths), source)


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
