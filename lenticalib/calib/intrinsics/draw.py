"""Drawing the boards of :mod:`.board`: the panel raster and the printable sheet (PDF and PNG).

Panel raster: uint8 ``(H, W, 3)`` RGB at the panel's size; the squares' edges are ramps
``board.edge_px`` panel pixels wide, linear in light and centred on the pixel edges (why: see
:mod:`.board`).  Printable sheet: the page in millimetres (matplotlib, Agg), squares at their true
size, the square size printed on it and a 100 mm scale bar to check the printer's scale.

ChArUco boards (:attr:`.board.Board.charuco`): the same squares with the ArUco markers in the white
squares (:meth:`.board.Board.marker_bits`).  On the panel the hard-edged board (every edge on a
pixel edge) is filtered with a box ``edge_px`` wide along each axis: across one edge that is the
same linear ramp as the chessboard's; the markers' edges get a ramp ``marker_edge_px`` wide (at
most half a marker cell: the markers only identify the corners, which lie on the squares' edges).
"""

from __future__ import annotations

import math
import os
from pathlib import Path

import numpy as np

from ...core.files.atomic import write_bytes_atomic
from ...core.colour import srgb_encode8
from ...core.errors import InputError
from .board import PAGE_MARGIN, PRINT_DPI, PRINT_PDF, PRINT_PNG, Board


def panel_raster(board: Board) -> np.ndarray:
    """The panel board as the panel shows it: uint8 ``(H, W, 3)`` RGB, white margin, black squares.

    Edges are ramps ``board.edge_px`` panel pixels wide, linear in light (sRGB-encoded), centred on
    the pixel edges where the squares meet, so every corner stays a point of symmetry (see the
    module docstring); 0 draws hard edges.
    """
    if board.panel is None:
        raise InputError("is not a panel board", source="board", hint="make one with 'lenticalib camera patterns'")
    if board.charuco:
        return srgb_encode8(1.0 - _charuco_blackness(board))[:, :, None].repeat(3, axis=2)
    w, h, s = int(board.panel["width"]), int(board.panel["height"]), int(board.square_px)
    x0, y0 = board.origin_px[0] - s, board.origin_px[1] - s
    soft = 0.5 * float(board.edge_px or 0)

    def axis(n: int, origin: int, count: int) -> np.ndarray:
        """(count + 1, n): soft indicator of each square along one axis, at the pixel centres."""
        c = np.arange(n, dtype=np.float64) + 0.5 - origin
        k = np.arange(count + 1, dtype=np.float64)[:, None]
        if soft <= 0:
            return ((c >= k * s) & (c < (k + 1) * s)).astype(np.float64)
        return (np.clip(0.5 + (c - k * s) / (2 * soft), 0, 1) * np.clip(0.5 + ((k + 1) * s - c) / (2 * soft), 0, 1))

    bx, by = axis(w, x0, board.cols), axis(h, y0, board.rows)
    ii, jj = np.meshgrid(np.arange(board.rows + 1), np.arange(board.cols + 1), indexing="ij")
    black = ((ii + jj) % 2 == 0).astype(np.float64)  # (rows + 1, cols + 1)
    blackness = by.T @ black @ bx  # (h, w): share of black in light at each pixel centre
    light = 1.0 - blackness
    value = srgb_encode8(light)
    return np.repeat(value[:, :, None], 3, axis=2)


def _box(black: np.ndarray, e: float) -> np.ndarray:
    """``black`` filtered along both axes by the box [c - e/2, c + e/2] about every pixel centre c
    (weights: the share of each whole pixel it covers): a hard edge on a pixel edge becomes the
    linear ramp ``e`` pixels wide of :func:`panel_raster`; ``e`` <= 0 leaves it hard."""
    from scipy.ndimage import correlate1d

    if e <= 0:
        return black
    half = e / 2.0
    k = np.arange(-math.ceil(half - 0.5), math.ceil(half - 0.5) + 1, dtype=np.float64)
    weights = np.clip(np.minimum(k + 0.5, half) - np.maximum(k - 0.5, -half), 0.0, None) / e
    return correlate1d(correlate1d(black, weights, axis=0, mode="nearest"), weights, axis=1, mode="nearest")


def _charuco_blackness(board: Board) -> np.ndarray:
    """float64 ``(H, W)``: share of black in light at every panel pixel of a ChArUco panel board:
    the squares with ramps ``edge_px`` wide, the markers with ramps ``marker_edge_px`` wide."""
    w, h, s = int(board.panel["width"]), int(board.panel["height"]), int(board.square_px)
    x0, y0 = board.origin_px[0] - s, board.origin_px[1] - s
    bits = board.marker_bits()
    n = bits.shape[1]
    cell = int(board.marker_px) // n
    inset = (s - cell * n) // 2
    ids = board.marker_ids()
    squares, markers = np.zeros((h, w)), np.zeros((h, w))
    for i in range(board.rows + 1):
        for j in range(board.cols + 1):
            y, x = y0 + i * s, x0 + j * s
            if ids[i, j] < 0:
                squares[y:y + s, x:x + s] = 1.0
            else:
                marker = np.kron(bits[ids[i, j]].astype(np.float64), np.ones((cell, cell)))
                markers[y + inset:y + inset + cell * n, x + inset:x + inset + cell * n] = marker
    return _box(squares, float(board.edge_px or 0)) + _box(markers, float(board.marker_edge_px))


def write_print_sheet(board: Board, folder: str | os.PathLike) -> list[Path]:
    """Write the printable board into ``folder``: ``board-print.pdf`` (vector) and ``board-print.png``
    (300 dpi), the squares at their true size, with the square size and a 100 mm scale bar."""
    import io

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.patches import Rectangle

    pw, ph = float(board.paper["width_mm"]), float(board.paper["height_mm"])
    s = board.square_mm
    fig = plt.figure(figsize=(pw / 25.4, ph / 25.4))
    written = []
    try:
        ax = fig.add_axes((0, 0, 1, 1))
        ax.set_xlim(0, pw)
        ax.set_ylim(ph, 0)
        ax.set_axis_off()
        x0, y0 = board.origin_mm[0] - s, board.origin_mm[1] - s
        for i in range(board.rows + 1):
            for j in range(board.cols + 1):
                if (i + j) % 2 == 0:
                    ax.add_patch(Rectangle((x0 + j * s, y0 + i * s), s, s, facecolor="black", edgecolor="none",
                                           antialiased=True))
        if board.charuco:
            _draw_markers(ax, board, x0, y0)
        base = ph - PAGE_MARGIN - 6.0
        bar_x = PAGE_MARGIN + 4.0
        ax.plot([bar_x, bar_x + 100.0], [base, base], color="black", lw=1.2, solid_capstyle="butt")
        for k in range(11):
            tick = 3.0 if k % 5 == 0 else 1.5
            ax.plot([bar_x + 10 * k] * 2, [base, base - tick], color="black", lw=0.8)
        for k, label in ((0, "0"), (5, "50"), (10, "100 mm")):
            ax.text(bar_x + 10 * k, base + 1.2, label, ha="center", va="top", fontsize=8)
        what = (f"ChArUco {board.cols + 1} x {board.rows + 1} squares ({board.dictionary}), squares {s:.2f} mm, "
                f"markers {board.marker_mm:.2f} mm" if board.charuco else
                f"{board.cols} x {board.rows} inner corners, squares {s:.2f} mm")
        ax.text(bar_x + 106.0, base - 1.0,
                f"lenticalib camera board: {what}\n"
                "print at 100 % (no 'fit to page'); the bar must measure 100 mm, each square "
                f"{s:.2f} mm; keep the sheet flat",
                ha="left", va="center", fontsize=8)
        for fmt, name, dpi in (("pdf", PRINT_PDF, None), ("png", PRINT_PNG, PRINT_DPI)):
            buf = io.BytesIO()
            fig.savefig(buf, format=fmt, dpi=dpi or 72)
            written.append(write_bytes_atomic(Path(folder) / name, buf.getvalue()))
    finally:
        plt.close(fig)
    return written


def _draw_markers(ax, board: Board, x0: float, y0: float) -> None:
    """The ArUco markers of a ChArUco board on the sheet's axes (mm), one rectangle per run of black
    cells along a row; ``(x0, y0)``: the top-left corner of square (0, 0) on the sheet."""
    from matplotlib.patches import Rectangle

    s, m = board.square_mm, float(board.marker_mm)
    bits = board.marker_bits()
    n = bits.shape[1]
    cell = m / n
    inset = (s - m) / 2
    ids = board.marker_ids()
    for (i, j), k in np.ndenumerate(ids):
        if k < 0:
            continue
        for r in range(n):
            row = bits[k, r]
            c = 0
            while c < n:
                if not row[c]:
                    c += 1
                    continue
                start = c
                while c < n and row[c]:
                    c += 1
                ax.add_patch(Rectangle((x0 + j * s + inset + start * cell, y0 + i * s + inset + r * cell),
                                       (c - start) * cell, cell, facecolor="black", edgecolor="none",
                                       antialiased=True))
