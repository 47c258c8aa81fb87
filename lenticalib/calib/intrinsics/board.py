"""The calibration chessboard: its geometry, the panel raster, the printable sheet and ``board.json``.

A board has ``cols x rows`` *inner* corners (OpenCV's ``patternSize``), so ``(cols + 1) x (rows + 1)``
squares of ``square_mm`` millimetres.  Square (0, 0), at the top left as drawn, is black; the
boards lenticalib draws have one odd and one even number of squares, so the pattern is not
symmetric under a half turn and every photo can be labelled the same way (corner (0, 0) is the
top-left inner corner as drawn, whatever the camera's roll; :mod:`.corners`).

Two kinds:

    panel   shown full screen on the panel: a W x H raster (uint8 RGB), white margin, squares of a
            whole number ``square_px`` of panel pixels, centred, filling about 80 % of the panel.
            ``square_mm = square_px * pixel_pitch_mm``; the corners lie in the pixel plane.  The
            edges are ramps ``edge_px`` panel pixels wide (linear in light, centred on the pixel
            edges): across its lenses the sheet shows the pixel plane at one point per lens, so a
            hard edge would appear to jump by whole lens pitches; a ramp over about two lens
            pitches lets the grey levels the lenses show place it between them, and being
            symmetric it leaves every corner a point of symmetry (unmoved).  On one simulated panel
            this lowered the corner error from 0.056 to 0.040 px RMS and the worst from 0.31 to
            0.16 px.
    print   printed on paper (PDF and 300 dpi PNG, landscape), with the square size printed on it
            and a 100 mm scale bar to check that the printer did not scale it.

Two patterns (``pattern``):

    chessboard  plain squares; the whole board must be in a photo (OpenCV's chessboard detector).
    charuco     a ChArUco board (OpenCV's aruco module): the same squares with an ArUco marker of
                ``dictionary`` in every white square, ``marker_mm`` wide and centred, the markers
                numbered row by row over the white squares as OpenCV's ``CharucoBoard`` (4.6 and
                later) numbers them, square (0, 0) black.  Every inner corner is identified by the
                markers around it, so a photo that shows only part of the board is still a valid
                observation: let the board run off the image edges and corners.  On the panel the
                marker cells are whole panel pixels and the square side is even, so the markers
                are exactly centred; their edges get the same soft ramps as the squares'.

Board frame (mm): origin at inner corner (0, 0), x along a row of corners, y down a column,
z into the board; corner (i, j) at ``(j s, i s, 0)`` (:meth:`Board.object_points`, mrcal's
``ref_calibration_object`` layout).

Manifest ``board.json``: ``{"format": "lenticalib.camera-board", "format_version": 1, "kind", "cols", "rows",
"square_mm", ...}`` plus, for a panel board, ``panel`` (width, height, pixel_pitch_mm), ``square_px``,
``origin_px`` (panel pixel coordinates of inner corner (0, 0), pixel edges at whole numbers) and
``edge_px``; for a printed one ``paper`` (name, width_mm, height_mm) and ``origin_mm`` on the sheet.
A ChArUco board adds ``pattern`` ("charuco"), ``dictionary`` (an OpenCV name, e.g. "DICT_4X4_100"),
``squares`` ([cols + 1, rows + 1]), ``marker_mm`` and, on the panel, ``marker_px``; a manifest
without ``pattern`` is a chessboard.
Drawing the boards: :mod:`.draw`.
"""

from __future__ import annotations

import dataclasses
import math
import os
from pathlib import Path
from typing import Any, Mapping

import numpy as np

from ...core.files.documents import FORMATS, check_envelope, read_json_file, write_document
from ...core.errors import InputError
from ...core.sizes import parse_pair
from .charuco import MARKER_SHARE, check_dictionary, default_dictionary, marker_bits_count

DOCUMENT = FORMATS["lenticalib.camera-board"]
MANIFEST_NAME = "board.json"
PANEL_IMAGE = "board.png"
PRINT_FOLDER = "print"
PRINT_PDF = "board-print.pdf"
PRINT_PNG = "board-print.png"
PRINT_DPI = 300
KINDS = ("panel", "print")
PAPERS = {"A4": (297.0, 210.0), "letter": (279.4, 215.9)}  # landscape, mm
PANEL_FILL = 0.8  # share of the panel's width or height the squares fill
MIN_SQUARE_PX = 8  # panel pixels per square
MIN_EDGE_PX = 2  # panel pixels of an edge ramp, at least
MIN_CORNERS = 3  # inner corners per side, at least
MAX_CORNERS = 200  # inner corners per side, at most
PAGE_MARGIN = 12.0  # mm
PAGE_FOOTER = 30.0  # mm below the board for the text and the scale bar
PATTERNS = ("chessboard", "charuco")


@dataclasses.dataclass(frozen=True)
class Board:
    """A chessboard of ``cols x rows`` inner corners and ``square_mm`` squares.

    ``panel``: {"width", "height" (pixels), "pixel_pitch_mm"} for a panel board, else None;
    ``square_px`` and ``origin_px`` (x, y panel pixel coordinates of inner corner (0, 0)) with it.
    ``paper``: {"name", "width_mm", "height_mm"} for a printed board, ``origin_mm`` on the sheet.
    """

    cols: int
    rows: int
    square_mm: float
    kind: str = "print"
    panel: Mapping[str, Any] | None = None
    square_px: int | None = None
    origin_px: tuple[int, int] | None = None
    paper: Mapping[str, Any] | None = None
    origin_mm: tuple[float, float] | None = None
    edge_px: int | None = None
    pattern: str = "chessboard"
    dictionary: str | None = None
    marker_mm: float | None = None
    marker_px: int | None = None

    def __post_init__(self):
        if not (isinstance(self.cols, int) and isinstance(self.rows, int)
                and self.cols >= MIN_CORNERS and self.rows >= MIN_CORNERS):
            raise InputError(f"a board needs at least {MIN_CORNERS}x{MIN_CORNERS} inner corners, got "
                             f"{self.cols}x{self.rows}", source="board")
        if not (isinstance(self.square_mm, (int, float)) and math.isfinite(self.square_mm) and self.square_mm > 0):
            raise InputError(f"square size must be a number > 0 mm, got {self.square_mm!r}", source="board")
        if self.kind not in KINDS:
            raise InputError(f"board kind must be one of {', '.join(KINDS)}, got {self.kind!r}", source="board")
        pitch = (self.panel or {}).get("pixel_pitch_mm")
        if (self.kind == "panel" and isinstance(self.square_px, (int, float)) and isinstance(pitch, (int, float))
                and self.square_px > 0 and pitch > 0
                and abs(self.square_mm - self.square_px * pitch) > 1e-6 * self.square_mm + 1e-9):
            # the squares' size is what the solve scales the world with: two sizes, one of them wrong
            raise InputError(f"square_mm {self.square_mm:g} is not square_px x pixel_pitch_mm "
                             f"({self.square_px} x {pitch:g} = {self.square_px * pitch:g} mm)", source="square_mm",
                             hint="write the board again with 'lenticalib camera patterns' rather than editing board.json")
        if self.pattern not in PATTERNS:
            raise InputError(f"board pattern must be one of {', '.join(PATTERNS)}, got {self.pattern!r}",
                             source="pattern")
        if self.pattern == "charuco":
            check_dictionary(self.dictionary, self.markers)
            if not (isinstance(self.marker_mm, (int, float)) and math.isfinite(self.marker_mm)
                    and 0 < self.marker_mm < self.square_mm):
                raise InputError(f"the marker size must be a number of mm between 0 and the square size "
                                 f"({self.square_mm:g} mm), got {self.marker_mm!r}", source="marker_mm",
                                 hint="give the side of the black ArUco markers in mm (without their white margin)")

    @property
    def charuco(self) -> bool:
        """Whether this is a ChArUco board (corners identified by markers; partial views allowed)."""
        return self.pattern == "charuco"

    @property
    def marker_edge_px(self) -> int:
        """Width of the ramps of a ChArUco panel board's marker edges, panel pixels: the squares'
        ``edge_px`` but at most half a marker cell (at least ``MIN_EDGE_PX``); the markers only
        identify the corners, which lie on the squares' edges."""
        cell = int(self.marker_px or 0) // marker_bits_count(self.dictionary)
        return max(MIN_EDGE_PX, min(int(self.edge_px or 0), cell // 2))

    @property
    def squares(self) -> tuple[int, int]:
        """(columns, rows) of squares: one more than the inner corners each way."""
        return self.cols + 1, self.rows + 1

    @property
    def markers(self) -> int:
        """Number of ArUco markers a ChArUco board of these squares holds (one per white square)."""
        return (self.squares[0] * self.squares[1]) // 2

    def marker_ids(self) -> np.ndarray:
        """int ``(rows + 1, cols + 1)``: the ArUco id in each square, -1 in the black squares (square
        (i, j) is black when i + j is even); ids run row by row, as OpenCV's CharucoBoard has them."""
        ii, jj = np.meshgrid(np.arange(self.rows + 1), np.arange(self.cols + 1), indexing="ij")
        white = (ii + jj) % 2 == 1
        ids = np.full(white.shape, -1, np.int64)
        ids[white] = np.arange(int(white.sum()))
        return ids

    def marker_bits(self) -> np.ndarray:
        """bool ``(markers, n, n)``: True where marker k is black, its black border included (n = the
        dictionary's bits + 2), rows down the marker as drawn."""
        import cv2

        d = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, self.dictionary))
        n = d.markerSize + 2
        return np.stack([cv2.aruco.generateImageMarker(d, k, n, borderBits=1) < 128 for k in range(self.markers)])
    @property
    def symmetric(self) -> bool:
        """True when a half turn maps the pattern onto itself (cols + rows even): the photos then
        cannot tell corner (0, 0) from the opposite one by colour."""
        return (self.cols + self.rows) % 2 == 0 and not self.charuco

    @property
    def size_mm(self) -> tuple[float, float]:
        """(width, height) of the squares, mm: ``((cols + 1) s, (rows + 1) s)``."""
        return (self.cols + 1) * self.square_mm, (self.rows + 1) * self.square_mm

    def object_points(self) -> np.ndarray:
        """Corner positions in the board frame: float64 ``(rows, cols, 3)``, mm; [i, j] = (j s, i s, 0)."""
        jj, ii = np.meshgrid(np.arange(self.cols, dtype=np.float64), np.arange(self.rows, dtype=np.float64))
        return np.stack([jj * self.square_mm, ii * self.square_mm, np.zeros_like(jj)], axis=-1)

    def describe(self) -> str:
        """One line: ``"15x8 inner corners, 34.448 mm squares (panel board)"``."""
        if self.charuco:
            return (f"ChArUco {self.cols + 1}x{self.rows + 1} squares ({self.cols}x{self.rows} inner corners), "
                    f"{self.square_mm:g} mm squares, {self.marker_mm:g} mm {self.dictionary} markers "
                    f"({self.kind} board)")
        return f"{self.cols}x{self.rows} inner corners, {self.square_mm:g} mm squares ({self.kind} board)"

    def to_dict(self) -> dict[str, Any]:
        """The ``board.json`` document."""
        out: dict[str, Any] = {**DOCUMENT.envelope(), "kind": self.kind,
                               "cols": self.cols, "rows": self.rows, "square_mm": float(self.square_mm),
                               "frame": "origin at inner corner (0,0); x along a row of corners, y down a "
                                        "column, z into the board; mm" + (
                                            "; the corners lie in the panel's pixel plane"
                                            if self.kind == "panel" else "")}
        if self.charuco:
            out.update(pattern=self.pattern, dictionary=self.dictionary, squares=list(self.squares),
                       marker_mm=float(self.marker_mm))
            if self.marker_px is not None:
                out["marker_px"] = int(self.marker_px)
        if self.panel is not None:
            out["panel"] = dict(self.panel)
            out["square_px"] = self.square_px
            out["origin_px"] = list(self.origin_px)
            out["edge_px"] = self.edge_px
            out["image"] = PANEL_IMAGE
        if self.paper is not None:
            out["paper"] = dict(self.paper)
            out["origin_mm"] = list(self.origin_mm)
            out["files"] = [PRINT_PDF, PRINT_PNG]
        return out

    @classmethod
    def from_dict(cls, data: Any, source: str = "board.json") -> "Board":
        """Inverse of :meth:`to_dict`; InputError naming ``source`` for anything that is not a board."""
        check_envelope(data, DOCUMENT, source)
        try:
            cols, rows, square = data["cols"], data["rows"], data["square_mm"]
            panel = data.get("panel")
            board = cls(cols=cols, rows=rows, square_mm=square, kind=data.get("kind", "print"),
                        panel=dict(panel) if isinstance(panel, Mapping) else None,
                        square_px=data.get("square_px"),
                        origin_px=tuple(data["origin_px"]) if data.get("origin_px") is not None else None,
                        paper=dict(data["paper"]) if isinstance(data.get("paper"), Mapping) else None,
                        origin_mm=tuple(data["origin_mm"]) if data.get("origin_mm") is not None else None,
                        edge_px=data.get("edge_px"), pattern=data.get("pattern", "chessboard"),
                        dictionary=data.get("dictionary"), marker_mm=data.get("marker_mm"),
                        marker_px=data.get("marker_px"))
        except KeyError as exc:
            raise InputError(f"board manifest lacks the field {exc.args[0]!r}", source=source,
                             hint=REWRITE_HINT) from None
        except InputError as exc:
            raise InputError(exc.message, source=source, hint=exc.hint or REWRITE_HINT) from None
        except (TypeError, ValueError) as exc:
            raise InputError(f"board manifest has a field of the wrong type ({exc})", source=source,
                             hint=REWRITE_HINT) from None
        return board


REWRITE_HINT = ("write the board again with 'lenticalib camera patterns' (it writes board.json), or remove "
                "board.json and describe a board you already have with the calibrate command's board options")


def parse_squares(text: str, source: str = "squares") -> tuple[int, int]:
    """``"15x8"`` -> (15, 8) inner corners; InputError naming ``source`` otherwise."""
    return parse_pair(text, source, MIN_CORNERS, MAX_CORNERS, form="COLSxROWS", unit="inner corners",
                      example="15x8")


def parse_charuco_squares(text: str, source: str = "board_squares") -> tuple[int, int]:
    """``"5x7"`` -> (5, 7) squares of a ChArUco board (columns, rows, as OpenCV's CharucoBoard counts
    them); InputError naming ``source`` otherwise."""
    return parse_pair(text, source, MIN_CORNERS + 1, MAX_CORNERS + 1, form="COLSxROWS", unit="squares",
                      example="5x7")


def _refuse_symmetric(cols: int, rows: int, source: str) -> None:
    if (cols + rows) % 2 == 0:
        raise InputError(f"a {cols}x{rows} board looks the same after a half turn, so photos cannot tell "
                         "its corners apart", source=source,
                         hint=f"use one odd and one even number of inner corners, e.g. {cols}x{rows + 1}")


def panel_board(width: int, height: int, pixel_pitch_mm: float,
                squares: tuple[int, int] | None = None, lens_pitch_px: float | None = None,
                pattern: str = "chessboard", dictionary: str | None = None) -> Board:
    """The board for a ``width x height`` panel of pixel pitch ``pixel_pitch_mm``.

    ``squares``: inner corners (cols, rows); default 9 squares along the shorter side and as
    many along the longer one as keep them square (15x8 inner corners on a 16:9 panel), with
    one count odd and one even.  Square side: the largest whole number of pixels with which the
    squares fill at most ``PANEL_FILL`` of the panel's width and height; centred.

    Edge ramps (``edge_px``, see :func:`.draw.panel_raster`): a twelfth of a square, at least
    ``MIN_EDGE_PX``, and at least two lens pitches when ``lens_pitch_px`` (the horizontal lens pitch
    in panel pixels, a profile's period / 3) is known.

    ``pattern`` "charuco": the squares' side is made even and every white square holds a marker
    of ``dictionary`` (default: :func:`default_dictionary`) about ``MARKER_SHARE`` of a square wide,
    made of whole-pixel cells and exactly centred.  The squares keep their edge ramps (the corners
    lie on them); the markers' ramps are :attr:`Board.marker_edge_px`, at most half a cell, so
    the markers stay readable.  Symmetric counts are allowed (the
    markers tell the corners apart).
    """
    if pattern not in PATTERNS:
        raise InputError(f"unknown board pattern {pattern!r}", source="pattern", hint="use " + " or ".join(PATTERNS))
    charuco = pattern == "charuco"
    if not (isinstance(pixel_pitch_mm, (int, float)) and math.isfinite(pixel_pitch_mm) and pixel_pitch_mm > 0):
        raise InputError(f"pixel pitch must be a number > 0 mm, got {pixel_pitch_mm!r}", source="pixel_pitch_mm")
    if squares is None:
        short, long_ = sorted((width, height))
        n_long = max(round(9 * long_ / short), 4)
        if (n_long + 9) % 2 == 0:
            n_long += 1 if abs(n_long + 1 - 9 * long_ / short) < abs(n_long - 1 - 9 * long_ / short) else -1
        cols_sq, rows_sq = (n_long, 9) if width >= height else (9, n_long)
    else:
        if not charuco:
            _refuse_symmetric(*squares, "squares")
        cols_sq, rows_sq = squares[0] + 1, squares[1] + 1
    square_px = int(math.floor(PANEL_FILL * min(width / cols_sq, height / rows_sq)))
    if charuco:
        square_px -= square_px % 2
    if square_px < MIN_SQUARE_PX:
        raise InputError(f"{cols_sq - 1}x{rows_sq - 1} inner corners leave squares of {square_px} panel pixels "
                         f"on a {width}x{height} panel", source="squares",
                         hint=f"use fewer squares (each needs at least {MIN_SQUARE_PX} pixels)")
    ox = (width - cols_sq * square_px) // 2
    oy = (height - rows_sq * square_px) // 2
    edge = max(MIN_EDGE_PX, round(square_px / 12))
    if lens_pitch_px is not None and math.isfinite(lens_pitch_px) and lens_pitch_px > 0:
        if 2 * lens_pitch_px > square_px // 3:
            # the ramps would be cut to a third of a square and then span less than two lenses
            raise InputError(f"a lens pitch of {lens_pitch_px:.3g} panel pixels needs soft edges of "
                             f"{2 * lens_pitch_px:.3g} pixels, more than a third of the {square_px}-pixel squares",
                             source="lens_pitch_mm",
                             hint="check the lens pitch: a lenticular sheet's is a few panel pixels, the data "
                                  "sheet's horizontal pitch in mm; or use fewer squares")
        edge = max(edge, math.ceil(2 * lens_pitch_px))
    edge = min(edge, square_px // 3)
    square_mm = round(square_px * float(pixel_pitch_mm), 10)
    extra: dict[str, Any] = {}
    if charuco:
        dictionary = check_dictionary(dictionary or default_dictionary((cols_sq * rows_sq) // 2),
                                      (cols_sq * rows_sq) // 2)
        n = marker_bits_count(dictionary)
        cell = int(MARKER_SHARE * square_px / n)
        if n % 2 and cell % 2:
            cell -= 1  # an odd marker in an even square would sit half a pixel off centre
        if cell < 2:
            raise InputError(f"{cols_sq}x{rows_sq} squares of {square_px} panel pixels leave no room for "
                             f"{dictionary} markers", source="squares",
                             hint=f"use fewer squares (a marker needs at least {2 * n} pixels)")
        extra = dict(pattern="charuco", dictionary=dictionary, marker_px=cell * n,
                     marker_mm=round(cell * n * float(pixel_pitch_mm), 10))
    return Board(cols=cols_sq - 1, rows=rows_sq - 1, square_mm=square_mm, kind="panel",
                 panel={"width": int(width), "height": int(height), "pixel_pitch_mm": float(pixel_pitch_mm)},
                 square_px=square_px, origin_px=(ox + square_px, oy + square_px), edge_px=int(edge), **extra)


def print_board(square_mm: float = 20.0, paper: str = "A4", squares: tuple[int, int] | None = None,
                pattern: str = "chessboard", dictionary: str | None = None) -> Board:
    """The printable board: squares of ``square_mm`` on a landscape ``paper`` sheet (A4 or letter).

    ``squares``: inner corners (cols, rows); default as many as fit within the margins and above
    the footer, one count odd and one even.  ``pattern`` "charuco": markers of ``dictionary``
    (default :func:`default_dictionary`), ``MARKER_SHARE`` of a square wide.
    """
    if pattern not in PATTERNS:
        raise InputError(f"unknown board pattern {pattern!r}", source="pattern", hint="use " + " or ".join(PATTERNS))
    if paper not in PAPERS:
        raise InputError(f"unknown paper {paper!r}", source="paper", hint="use " + " or ".join(PAPERS))
    if not (math.isfinite(square_mm) and 3.0 <= square_mm <= 200.0):
        raise InputError(f"{square_mm} mm squares is out of range", source="square_mm",
                         hint="give the printed square size in mm, 3..200 (e.g. 20)")
    pw, ph = PAPERS[paper]
    fit_c = int((pw - 2 * PAGE_MARGIN) // square_mm)
    fit_r = int((ph - 2 * PAGE_MARGIN - PAGE_FOOTER) // square_mm)
    if squares is None:
        cols_sq, rows_sq = fit_c, fit_r
        if (cols_sq + rows_sq) % 2 == 0:
            if cols_sq >= rows_sq:
                cols_sq -= 1
            else:
                rows_sq -= 1
    else:
        if pattern != "charuco":
            _refuse_symmetric(*squares, "squares")
        cols_sq, rows_sq = squares[0] + 1, squares[1] + 1
    if cols_sq > fit_c or rows_sq > fit_r or min(cols_sq, rows_sq) < MIN_CORNERS + 1:
        raise InputError(f"{square_mm:g} mm squares do not make a board of at least {MIN_CORNERS}x{MIN_CORNERS} inner "
                         f"corners that fits on {paper} paper", source="square_mm",
                         hint=f"room for {fit_c - 1}x{fit_r - 1} inner corners at most; use smaller squares")
    bw, bh = cols_sq * square_mm, rows_sq * square_mm
    x0 = (pw - bw) / 2
    y0 = PAGE_MARGIN + (ph - 2 * PAGE_MARGIN - PAGE_FOOTER - bh) / 2
    extra: dict[str, Any] = {}
    if pattern == "charuco":
        markers = (cols_sq * rows_sq) // 2
        extra = dict(pattern="charuco", dictionary=check_dictionary(dictionary or default_dictionary(markers), markers),
                     marker_mm=round(MARKER_SHARE * float(square_mm), 6))
    return Board(cols=cols_sq - 1, rows=rows_sq - 1, square_mm=float(square_mm), kind="print",
                 paper={"name": paper, "width_mm": pw, "height_mm": ph},
                 origin_mm=(round(x0 + square_mm, 6), round(y0 + square_mm, 6)), **extra)


def write_manifest(board: Board, folder: str | os.PathLike) -> Path:
    """Write ``folder/board.json`` (atomically)."""
    return write_document(Path(folder) / MANIFEST_NAME, DOCUMENT, board.to_dict())


def read_board(path: str | os.PathLike) -> Board:
    """Load a ``board.json``; InputError naming the file when it is not one."""
    data = read_json_file(path, DOCUMENT.what, "check the path of board.json")
    return Board.from_dict(data, source=str(path))


def find_board_manifest(photos: list[Path]) -> Path | None:
    """The ``board.json`` of a set of photos: in their common folder or up to two folders above it
    (``DIR/captures/*.jpg`` -> ``DIR/board.json``), as given and, for links, where they point;
    None when there is none."""
    if not photos:
        return None
    # where the photos were given first, then where they lie (photos linked into a folder of
    # their own keep the board.json of the folder they were linked from)
    given = Path(os.path.commonpath([os.path.dirname(os.path.abspath(p)) for p in photos]))
    lying = Path(os.path.commonpath([str(p.resolve().parent) for p in photos]))
    for folder in dict.fromkeys((given, lying)):
        for candidate in (folder, folder.parent, folder.parent.parent):
            manifest = candidate / MANIFEST_NAME
            if manifest.is_file():
                return manifest
    return None
