"""View inputs: a folder of N images, or a quilt image (tiles, view 0 bottom-left).

Quilt convention (Looking Glass): ``cols x rows`` tiles of equal size; view 0 is the bottom-left
tile, views run left to right, then bottom to top.  The grid is read from the common file-name
suffix ``_qs{cols}x{rows}a{aspect}`` (e.g. ``scene_qs8x4a1.7778.png``) or given explicitly.
"""

from __future__ import annotations

import os
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ...core.errors import ImageError
from ...core.files.imageio import IMAGE_SUFFIXES, read_image
from ...core.profile import MAX_VIEWS
from ...core.sizes import parse_pair

_QUILT_SUFFIX = re.compile(r"_qs(\d+)x(\d+)a(\d+(?:\.\d+)?)", re.IGNORECASE)


@dataclass(frozen=True)
class QuiltGrid:
    """A quilt layout: ``cols`` x ``rows`` tiles; ``aspect`` (tile width / height) if known."""

    cols: int
    rows: int
    aspect: float | None = None

    @property
    def tiles(self) -> int:
        return self.cols * self.rows


def parse_quilt_name(name: str) -> QuiltGrid | None:
    """The grid in a ``..._qs{cols}x{rows}a{aspect}...`` file name, or None."""
    match = _QUILT_SUFFIX.search(Path(name).name)
    if not match:
        return None
    cols, rows, aspect = int(match.group(1)), int(match.group(2)), float(match.group(3))
    if cols < 1 or rows < 1 or aspect <= 0:
        raise ImageError(f"quilt suffix {match.group(0)!r} has an empty grid or aspect", source=name)
    return QuiltGrid(cols, rows, aspect)


def parse_grid(text: str, source: str = "grid") -> QuiltGrid:
    """``"8x4"`` -> QuiltGrid(8, 4); ImageError naming ``source`` otherwise."""
    cols, rows = parse_pair(text, source, 1, MAX_VIEWS, form="COLSxROWS", unit="tiles", example="8x4",
                            error=ImageError)
    return QuiltGrid(cols, rows)


def split_quilt(quilt: np.ndarray, grid: QuiltGrid, source: str = "quilt") -> np.ndarray:
    """Tiles of ``quilt`` ``(H, W, 3)`` as views ``(cols*rows, H/rows, W/cols, 3)``, view 0 bottom-left."""
    height, width = quilt.shape[:2]
    if width % grid.cols or height % grid.rows:
        raise ImageError(f"a {width}x{height} quilt does not divide into {grid.cols}x{grid.rows} tiles",
                         source=source, hint="check the grid (file-name suffix _qsCOLSxROWS or `grid`)")
    tw, th = width // grid.cols, height // grid.rows
    tiles = quilt.reshape(grid.rows, th, grid.cols, tw, 3)[::-1]  # tile rows from the bottom
    return np.ascontiguousarray(tiles.transpose(0, 2, 1, 3, 4).reshape(grid.tiles, th, tw, 3))


def make_quilt(views: np.ndarray, grid: QuiltGrid) -> np.ndarray:
    """Inverse of :func:`split_quilt`: views ``(cols*rows, h, w, 3)`` -> quilt ``(rows*h, cols*w, 3)``."""
    n, th, tw, ch = views.shape
    if n != grid.tiles:
        raise ImageError(f"{n} views do not fill a {grid.cols}x{grid.rows} quilt", source="views")
    tiles = views.reshape(grid.rows, grid.cols, th, tw, ch)[::-1]
    return np.ascontiguousarray(tiles.transpose(0, 2, 1, 3, 4).reshape(grid.rows * th, grid.cols * tw, ch))


def load_quilt(path: str | os.PathLike, views: int, grid: QuiltGrid | None = None) -> tuple[np.ndarray, QuiltGrid]:
    """Read a quilt and split it into ``views`` views; the grid comes from ``grid`` or the file name.

    Returns ``(views (N, H/rows, W/cols, 3), grid)``.  The file is read first, so a missing or
    unreadable file is reported as such rather than as a grid problem.
    """
    src = str(path)
    quilt = read_image(path)
    named = parse_quilt_name(src)
    grid = grid or named
    if grid is None:
        raise ImageError("quilt grid unknown", source=src,
                         hint="name the file with a _qsCOLSxROWSaASPECT suffix or pass `grid` COLSxROWS")
    if grid.aspect is None and named is not None:
        grid = QuiltGrid(grid.cols, grid.rows, named.aspect)
    if grid.tiles != views:
        raise ImageError(f"quilt has {grid.cols}x{grid.rows} = {grid.tiles} tiles, the profile has {views} views",
                         source=src, hint="use a quilt rendered for this panel's view count")
    return split_quilt(quilt, grid, source=src), grid


def natural_key(path: Path):
    """Sort key of file names with numbers in numeric order (``frame-2`` before ``frame-10``)."""
    return [int(part) if part.isdigit() else part.lower() for part in re.split(r"(\d+)", path.name)]


def load_view_folder(folder: str | os.PathLike, views: int) -> np.ndarray:
    """Read the images of ``folder`` as views ``(N, H_v, W_v, 3)``, in natural file-name order.

    Natural order compares digit runs as numbers, so ``view2`` sorts before ``view10``.
    """
    root = Path(folder)
    if not root.exists():
        raise ImageError("no such folder", source=str(root), hint="give the folder of the view images")
    if not root.is_dir():
        raise ImageError("is a file, not a folder of views", source=str(root),
                         hint="give the folder of the view images; a quilt image goes in as `quilt`")
    files = sorted((f for f in root.iterdir() if f.is_file() and f.suffix.lower() in IMAGE_SUFFIXES
                    and not f.name.startswith(".")), key=natural_key)
    if len(files) != views:
        raise ImageError(f"found {len(files)} images, the profile has {views} views", source=str(root),
                         hint="put exactly one image per view in the folder")
    first = read_image(files[0])
    stack = np.empty((views,) + first.shape, dtype=first.dtype)
    stack[0] = first
    for i, f in enumerate(files[1:], start=1):
        img = read_image(f, expected_size=(first.shape[1], first.shape[0]), what=files[0].name,
                         hint="all views must have one size")
        if img.dtype != first.dtype:
            raise ImageError(f"has {img.dtype} pixels, {files[0].name} has {first.dtype}", source=str(f),
                             hint="all views must have one bit depth")
        stack[i] = img
    return stack
