"""The standard 3D Gaussian Splatting PLY file (the layout the INRIA 3DGS code and gsplat write).

One element ``vertex`` with one row per Gaussian and these scalar properties, *raw* (pre-activation)
values, any numeric type (float32 in practice):

    x, y, z                       centre, world units
    nx, ny, nz                    optional, ignored (3DGS writes zeros)
    f_dc_0 .. f_dc_2              SH degree-0 coefficient, R G B
    f_rest_0 .. f_rest_{M-1}      the higher SH coefficients, M = 3 (K - 1) with K = 1, 4, 9, 16
                                  (M = 0, 9, 24, 45), stored channel-major: the K - 1 coefficients
                                  of R, then those of G, then those of B
    opacity                       logit of the opacity
    scale_0 .. scale_2            log of the standard deviations
    rot_0 .. rot_3                quaternion (w, x, y, z), any non-zero length

:func:`load_ply` returns :class:`~.gaussians.Gaussians` with activated values (sigmoid, exp,
normalised quaternion; ``sh[:, 0] = f_dc``, ``sh[:, 1:] = f_rest`` reshaped ``(G, 3, K-1)`` and
transposed).  :func:`save_ply` writes the inverse transforms, binary little-endian float32, without
normals, atomically.

What is accepted: any PLY encoding plyfile reads (binary little- or big-endian, and ASCII, which is
slow for large avatars but unambiguous); other elements (a camera, faces) and other vertex
properties (e.g. a mip-splatting ``filter_3D``) are ignored.  What is refused, each with one
InputError naming the file and the property at fault: not a PLY / a truncated file, no ``vertex``
element or no rows, a missing property, ``f_rest_*`` of a count other than 0, 9, 24 or 45 or not
numbered 0..M-1, a list property where a scalar is expected, a non-finite value, a zero-length
quaternion, a header whose element counts need more bytes than the file holds (checked before
plyfile reads a byte of data, so a header claiming 10^13 vertices costs no memory;
:func:`check_ply_counts`, which mesh PLYs share), and a FIFO, device or a file over
:data:`MAX_AVATAR_PLY_BYTES` (refused before it is read).  Compressed PLYs (SuperSplat's
``packed_position`` chunks) are not this layout.
"""

from __future__ import annotations

import dataclasses
import io
import os
import re

import numpy as np

from ...core.files.atomic import write_bytes_atomic
from ...core.files.documents import binary_kind
from ...core.errors import BackendUnavailableError, InputError
from ...core.files.input_files import GIB, open_input, size_text
from .gaussians import Gaussians

_TYPE_BYTES = {"char": 1, "uchar": 1, "int8": 1, "uint8": 1, "short": 2, "ushort": 2, "int16": 2, "uint16": 2,
               "int": 4, "uint": 4, "int32": 4, "uint32": 4, "float": 4, "float32": 4, "double": 8, "float64": 8}
_MAX_HEADER = 1 << 16  # bytes searched for end_header
MAX_AVATAR_PLY_BYTES = 4 * GIB  # an avatar PLY: 16 M Gaussians of degree-3 SH (the largest 3DGS scenes hold 6 M)
_REST_COUNTS = {0: 1, 9: 4, 24: 9, 45: 16}  # number of f_rest_* -> K
_LAYOUT_HINT = "expected the standard 3DGS layout: x y z f_dc_0..2 f_rest_* opacity scale_0..2 rot_0..3"


def _plyfile():
    try:
        import plyfile
    except ImportError:
        raise BackendUnavailableError("reading and writing PLY avatars needs the plyfile package",
                                      source="plyfile", hint="pip install plyfile") from None
    return plyfile


@dataclasses.dataclass(frozen=True)
class PlyElementCount:
    """One element of a PLY header: ``name``, ``count`` (rows claimed), ``properties`` (names, in
    order) and ``lists`` (the names of its list properties)."""

    name: str
    count: int
    properties: tuple[str, ...]
    lists: tuple[str, ...]


def check_ply_counts(fh, source: str, what: str = "PLY file") -> list[PlyElementCount] | None:
    """Refuse a PLY header whose element counts need more data than the file has after the header;
    the elements it declares, or None for a header this cannot parse (left to plyfile, which
    reports it).  The one check of PLY counts against the file size (avatars and meshes).

    Each row needs at least its scalar properties' bytes plus each list's count (binary), or one
    character and a separator per property (ASCII).  Reads at most the first 64 KiB of ``fh``
    (an open binary file) and leaves it at an unspecified position.
    """
    head = fh.read(_MAX_HEADER)
    end = head.find(b"end_header")
    stop = head.find(b"\n", end) if end >= 0 else -1
    if not head.startswith(b"ply") or stop < 0:
        return None
    data_bytes = os.fstat(fh.fileno()).st_size - (stop + 1)
    ascii_format, elements = False, []  # [name, count, bytes per row, properties per row, names, lists]
    for line in head[:end].decode("ascii", "replace").splitlines():
        words = line.split()
        if len(words) >= 2 and words[0] == "format":
            ascii_format = words[1] == "ascii"
        elif len(words) == 3 and words[0] == "element":
            if not words[2].isdigit():
                return None
            elements.append([words[1], int(words[2]), 0, 0, [], []])
        elif len(words) >= 3 and words[0] == "property" and elements:
            size = _TYPE_BYTES.get(words[2] if words[1] == "list" else words[1])
            if size is None:
                return None
            elements[-1][2] += size
            elements[-1][3] += 1
            elements[-1][4].append(words[-1])
            if words[1] == "list":
                elements[-1][5].append(words[-1])
    need = [count * (2 * props if ascii_format else row) for _, count, row, props, _, _ in elements]
    if sum(need) > data_bytes:
        name, count = elements[need.index(max(need))][:2]
        raise InputError(f"not a readable {what}: the header claims {count} '{name}' rows ({size_text(sum(need))} at "
                         f"least), but the file holds {size_text(data_bytes)} after the header (truncated or corrupt)",
                         source=source)
    return [PlyElementCount(e[0], e[1], tuple(e[4]), tuple(e[5])) for e in elements]


def _column(vertex, name: str, source: str) -> np.ndarray:
    """One scalar property as float64 (G,), refused when missing, a list or non-finite."""
    data = vertex.data
    if data.dtype.names is None or name not in data.dtype.names:
        raise InputError(f"vertex property {name!r} is missing", source=source, hint=_LAYOUT_HINT)
    values = data[name]
    if values.dtype == object or values.dtype.kind not in "iuf":
        raise InputError(f"vertex property {name!r} is not a numeric scalar", source=source,
                         hint=_LAYOUT_HINT)
    with np.errstate(over="ignore"):  # a float64 value beyond float32's range becomes inf: refused
        values32 = values.astype(np.float32)
    bad = ~np.isfinite(values32)
    if bad.any():
        row = int(np.flatnonzero(bad)[0])
        raise InputError(f"vertex property {name!r} is not finite in float32 ({values[row]} in row {row}, "
                         f"{int(bad.sum())} rows in all)", source=source)
    return values32.astype(np.float64)


def _columns(vertex, names: list[str], source: str) -> np.ndarray:
    return np.stack([_column(vertex, name, source) for name in names], axis=1)


def _rest_names(vertex, source: str) -> list[str]:
    """The ``f_rest_*`` property names in index order, checked to be 0..M-1 with M in 0, 9, 24, 45."""
    found = {}
    for name in vertex.data.dtype.names or ():
        match = re.fullmatch(r"f_rest_(\d+)", name)
        if match:
            found[int(match.group(1))] = name
    if len(found) not in _REST_COUNTS:
        raise InputError(f"vertex property 'f_rest_*' has {len(found)} coefficients, expected 0, 9, 24 or 45 "
                         "(SH degree 0-3)", source=source)
    missing = sorted(set(range(len(found))) - set(found))
    if missing:
        raise InputError(f"vertex property 'f_rest_{missing[0]}' is missing (f_rest_* must be numbered "
                         f"0..{len(found) - 1})", source=source)
    return [found[i] for i in range(len(found))]


def _sigmoid(x: np.ndarray) -> np.ndarray:
    e = np.exp(-np.abs(x))
    return np.where(x >= 0, 1.0 / (1.0 + e), e / (1.0 + e))


def load_ply(path: str | os.PathLike) -> Gaussians:
    """The Gaussians stored in the 3DGS PLY file ``path``, activated, numpy float32.

    Raises InputError naming the file (and the property at fault) for anything but the layout in
    the module docstring; BackendUnavailableError when plyfile is not installed.
    """
    plyfile = _plyfile()
    source = os.fspath(path)
    try:
        with open_input(path, "PLY avatar", MAX_AVATAR_PLY_BYTES) as fh:  # a regular file (no FIFO) within the cap
            head = fh.read(16)
            if not head:
                raise InputError("empty file, not a PLY", source=source)
            kind = None if head.startswith(b"ply") else binary_kind(head)
            if kind is not None and kind != "a binary file":  # a binary PLY may hold zeros: only a known signature
                raise InputError(f"is {kind}, not a PLY file", source=source, hint="give the avatar's 3DGS .ply file")
            fh.seek(0)
            check_ply_counts(fh, source)
            fh.seek(0)
            ply = plyfile.PlyData.read(fh, mmap=False)
    except InputError:
        raise
    except OSError as exc:
        raise InputError(f"cannot read: {exc.strerror}", source=source) from None
    except plyfile.PlyParseError as exc:
        raise InputError(f"not a readable PLY file: {_one_line(exc)}", source=source,
                         hint=_LAYOUT_HINT) from None
    except (ValueError, TypeError, UnicodeDecodeError, IndexError) as exc:  # plyfile on odd headers
        raise InputError(f"not a readable PLY file: {_one_line(exc)}", source=source) from None

    if "vertex" not in ply:
        raise InputError("no 'vertex' element", source=source, hint=_LAYOUT_HINT)
    vertex = ply["vertex"]
    if vertex.count == 0:
        raise InputError("the 'vertex' element has no rows (no Gaussians)", source=source)

    means = _columns(vertex, ["x", "y", "z"], source)
    f_dc = _columns(vertex, ["f_dc_0", "f_dc_1", "f_dc_2"], source)
    rest_names = _rest_names(vertex, source)
    f_rest = (_columns(vertex, rest_names, source) if rest_names
              else np.zeros((vertex.count, 0), dtype=np.float64))
    opacity = _column(vertex, "opacity", source)
    log_scales = _columns(vertex, ["scale_0", "scale_1", "scale_2"], source)
    rot = _columns(vertex, ["rot_0", "rot_1", "rot_2", "rot_3"], source)

    norm = np.linalg.norm(rot, axis=1)
    if not (norm > 0).all():
        row = int(np.flatnonzero(~(norm > 0))[0])
        raise InputError(f"vertex property 'rot_0..3' is a zero-length quaternion in row {row}", source=source)
    with np.errstate(over="ignore"):
        scales = np.exp(log_scales).astype(np.float32)
    if not (np.isfinite(scales) & (scales > 0)).all():
        row = int(np.flatnonzero(~(np.isfinite(scales) & (scales > 0)).all(axis=1))[0])
        raise InputError(f"vertex property 'scale_*' is out of float32 range after exp() in row {row}",
                         source=source)

    k = _REST_COUNTS[len(rest_names)]
    sh = np.empty((vertex.count, k, 3), dtype=np.float32)
    sh[:, 0, :] = f_dc
    sh[:, 1:, :] = f_rest.reshape(vertex.count, 3, k - 1).transpose(0, 2, 1)
    f32 = np.float32
    return Gaussians(means=means.astype(f32), quats=(rot / norm[:, None]).astype(f32),
                     scales=scales, opacities=_sigmoid(opacity).astype(f32), sh=sh).validate(source)


def save_ply(path: str | os.PathLike, gaussians: Gaussians) -> None:
    """Write ``gaussians`` (activated, numpy or torch) to ``path`` in the standard 3DGS layout.

    Binary little-endian float32, no normals, raw values (logit opacity, log scales, the quaternion
    as given).  Opacities are clipped to [1e-12, 1 - 2**-24] before the logit so that a float32
    opacity of exactly 0 or 1 stays finite.  The file is replaced atomically.  Raises InputError for
    an empty set, non-finite values, opacities outside [0, 1], non-positive scales or zero-length
    quaternions (naming the field), or an unwritable path.
    """
    plyfile = _plyfile()
    g = gaussians.to_numpy().validate("gaussians")
    if g.count == 0:
        raise InputError("no Gaussians to write", source="gaussians")
    for name in ("means", "quats", "scales", "opacities", "sh"):
        if not np.isfinite(getattr(g, name)).all():
            raise InputError(f"{name} has non-finite values", source="gaussians")
    if (g.opacities < 0).any() or (g.opacities > 1).any():
        raise InputError("opacities must lie in [0, 1]", source="gaussians")
    if not (g.scales > 0).all():
        raise InputError("scales must be > 0", source="gaussians")
    if not (np.linalg.norm(g.quats, axis=1) > 0).all():
        raise InputError("quats has a zero-length quaternion", source="gaussians")

    count, k = g.count, g.sh.shape[1]
    rest = g.sh[:, 1:, :].transpose(0, 2, 1).reshape(count, 3 * (k - 1))
    p = np.clip(g.opacities.astype(np.float64), 1e-12, 1.0 - 2.0**-24)
    names = (["x", "y", "z", "f_dc_0", "f_dc_1", "f_dc_2"] + [f"f_rest_{i}" for i in range(rest.shape[1])]
             + ["opacity", "scale_0", "scale_1", "scale_2", "rot_0", "rot_1", "rot_2", "rot_3"])
    columns = [g.means, g.sh[:, 0, :], rest, np.log(p / (1.0 - p))[:, None],
               np.log(g.scales.astype(np.float64)), g.quats]
    table = np.concatenate([np.asarray(c, dtype=np.float32).reshape(count, -1) for c in columns], axis=1)
    rows = np.empty(count, dtype=[(name, "<f4") for name in names])
    for i, name in enumerate(names):
        rows[name] = table[:, i]
    buffer = io.BytesIO()
    plyfile.PlyData([plyfile.PlyElement.describe(rows, "vertex")], text=False, byte_order="<").write(buffer)
    write_bytes_atomic(path, buffer.getvalue())


def _one_line(exc: BaseException) -> str:
    return " ".join(str(exc).split()) or type(exc).__name__
