"""Drawing the boards of :mod:`.board`: the panel raster and the printable sheet (PDF and PNG).

Panel raster: uint8 ``(H, W, 3)`` RGB at the panel's size; the squares' edges are ramps
``board.edge_px`` panel pixels wide, linear in light and centred on the pixel edges (why: see
:mod:`.board`).  Printable sheet: the page in millimetres (matplotlib, Agg), squares at their true
size, the square size printed on it and a 100 mm scale bar to check the printer's scale.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from ...core.atomic import write_bytes_atomic
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
        base = ph - PAGE_MARGIN - 6.0
        bar_x = PAGE_MARGIN + 4.0
        ax.plot([bar_x, bar_x + 100.0], [base, base], color="black", lw=1.2, solid_capstyle="butt")
        for k in range(11):
            tick = 3.0 if k % 5 == 0 else 1.5
            ax.plot([bar_x + 10 * k] * 2, [base, base - tick], color="black", lw=0.8)
        for k, label in ((0, "0"), (5, "50"), (10, "100 mm")):
            ax.text(bar_x + 10 * k, base + 1.2, label, ha="center", va="top", fontsize=8)
        ax.text(bar_x + 106.0, base - 1.0,
                f"lenticalib camera board: {board.cols} x {board.rows} inner corners, squares {s:.2f} mm\n"
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
