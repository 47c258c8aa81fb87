"""``simulate_folder``: photograph a pattern folder on a virtual panel -- what ``lenticalib simulate`` runs.

A folder with ``patterns.json`` (from ``lenticalib patterns`` or ``lenticalib crosstalk patterns``)
is photographed pattern by pattern (:func:`lenticalib.sim.capture.simulate_capture_set`): a random
but plausible panel and camera (or the scene of ``scene``), ``DIR/captures/NAME.jpg``,
``DIR/truth.json``, ``DIR/simulation.json`` and, for crosstalk patterns, ``DIR/crosstalk-truth.json``.
A folder from ``lenticalib camera patterns`` (``board.json`` of a panel board, no patterns.json) is
photographed as a camera-calibration set instead (:func:`lenticalib.sim.board_set.simulate_board_set`).

Every option is checked, and the folder found writable, before the first photo is taken.  The
results are all or nothing: a run that fails (or is interrupted) removes what it wrote and puts
an earlier simulation of the folder back as it was (:func:`lenticalib.core.files.outputs.restored_on_failure`).

Errors name the argument at fault by its parameter name (``source="slant"``; in text
```seed``` ...); a command-line front end maps them to its flags.
"""

from __future__ import annotations

import dataclasses
import math
import os
import secrets
import time
from pathlib import Path
from typing import Callable

from ..calib.patterns.capture_sets import MIN_PHOTO_PIXELS
from ..calib.intrinsics.board import MANIFEST_NAME as BOARD_MANIFEST, PANEL_IMAGE, PATTERNS, read_board
from ..calib.intrinsics.report import REPORT_FILES
from ..core.files.documents import read_json_file
from ..core.errors import InputError
from ..core.files.outputs import check_output_file, check_output_folder, restored_on_failure, staged_folder
from ..core.pattern_sets import MANIFEST_NAME, read_pattern_folder
from ..core.sizes import MAX_SIDE, MIN_CAMERA_SIDE, check_sides

MAX_PIXELS = 64_000_000  # camera pixels in all (the simulator holds several float images of this size)
MAX_SEED = 2 ** 63 - 1


def check_seed(seed: int | None) -> None:
    """InputError naming ``seed`` unless it is None (draw one) or 0..MAX_SEED."""
    if seed is not None and not 0 <= seed <= MAX_SEED:
        raise InputError(f"seed {seed} is out of range", source="seed", hint=f"use 0..{MAX_SEED}")


def check_board_photos(photos: int) -> None:
    """InputError naming ``photos`` unless a board set of that many photos can be simulated (3..500)."""
    if not 3 <= photos <= 500:
        raise InputError(f"{photos} photos is out of range", source="photos", hint="use 3..500 (15-30 is typical)")
DEFAULT_SUBSAMPLES = 3
BOARD_SUBSAMPLES = 2
BOARD_RESOLUTION = (1600, 1200)


@dataclasses.dataclass(frozen=True)
class SimulationOptions:
    """The scene and camera of a simulation.

    ``seed`` (default: a fresh one, recorded in simulation.json); ``resolution`` (width, height)
    camera pixels (default 4000x3000, 1600x1200 for a board); ``scene``: a simulation.json or scene
    JSON to reuse (not combinable with seed, resolution, slant, period, order, distance_mm,
    conditions); ``slant`` C_r (pixels per row), ``period`` Delta_r (subpixels), ``order`` 'RGB' or
    'BGR', ``distance_mm``; ``jpeg_quality`` 1..100; ``subsamples`` rays per pixel side 1..16;
    ``conditions`` 'standard' or 'hard'; ``raw``: 16-bit linear PNG photos; ``photos``: the number of
    board photos for a camera board folder, 3..500; ``layout``: the panel's subpixel layout, 'RGB',
    'BGR', a name of :data:`~.layouts.NAMED_LAYOUTS` or a JSON layout file (:func:`~.layouts.resolve_layout`;
    not combinable with ``order``).
    """

    seed: int | None = None
    resolution: tuple[int, int] | None = None
    scene: str | os.PathLike | None = None
    slant: float | None = None
    period: float | None = None
    order: str | None = None
    distance_mm: float | None = None
    jpeg_quality: int | None = None
    subsamples: int | None = None
    conditions: str = "standard"
    raw: bool = False
    photos: int = 24
    layout: str | None = None

    def check(self) -> None:
        """InputError naming the field of any option out of range."""
        if self.slant is not None and not (math.isfinite(self.slant) and abs(self.slant) < 1.5):
            raise InputError(f"slant {self.slant} is out of range", source="slant",
                             hint="give C_r in pixels per row, |C_r| < 1.5 (typical panels 0.1..0.35)")
        if self.period is not None and not (math.isfinite(self.period) and 2.0 <= self.period <= 200.0):
            raise InputError(f"period {self.period} is out of range", source="period",
                             hint="give Delta_r in subpixels, 2..200 (typical panels 14..24)")
        if self.distance_mm is not None and not (math.isfinite(self.distance_mm) and 100.0 <= self.distance_mm <= 10000.0):
            raise InputError(f"distance {self.distance_mm} is out of range", source="distance_mm",
                             hint="give the camera distance in mm, 100..10000 (typical 450..800)")
        if self.jpeg_quality is not None and not 1 <= self.jpeg_quality <= 100:
            raise InputError(f"JPEG quality {self.jpeg_quality} is out of range", source="jpeg_quality",
                             hint="use 1..100")
        check_seed(self.seed)
        if self.layout is not None:
            if self.order is not None:
                raise InputError("cannot be combined with `order`", source="layout",
                                 hint="a layout fixes where every channel sits (RGB and BGR are layouts too)")
            self.resolved_layout()
        if self.resolution is not None:
            check_resolution(*self.resolution, "resolution")
        if self.subsamples is not None and not 1 <= self.subsamples <= 16:
            raise InputError(f"{self.subsamples} subsamples is out of range", source="subsamples", hint="use 1..16")


    def resolved_layout(self):
        """``(order, SubpixelLayout or None)`` of ``layout`` (InputError naming ``layout``), or
        ``(order, None)`` without one."""
        from .layouts import resolve_layout

        if self.layout is None:
            return self.order, None
        return resolve_layout(self.layout, "layout")


@dataclasses.dataclass
class SimulationRun:
    """What :func:`simulate_folder` wrote: ``kind`` ('patterns' or 'board'), ``directory``,
    ``summary`` (:func:`~.capture.simulate_capture_set`'s summary with ``seconds``, or the board
    set's record), ``scene`` (the :class:`~.scene.Scene` of a pattern folder, None for a board),
    ``seed``, ``resolution`` (width, height), ``photos`` (the number taken), ``seconds``."""

    kind: str
    directory: Path
    summary: dict
    scene: object | None
    seed: int
    resolution: tuple[int, int]
    photos: int
    seconds: float


def check_resolution(width: int, height: int, source: str) -> None:
    """InputError naming ``source`` unless a ``width`` x ``height`` camera makes photos the fit takes.

    The lower limit is the fit's own (:data:`lenticalib.calib.patterns.capture_sets.MIN_PHOTO_PIXELS`), so a
    simulated set is never refused by the fit for its size; the upper limits bound memory.
    """
    pixels = width * height
    if pixels < MIN_PHOTO_PIXELS:
        raise InputError(f"a {width}x{height} camera ({pixels / 1e6:.2f} megapixels) is below the "
                         f"{MIN_PHOTO_PIXELS / 1e6:g} megapixel the fit needs", source=source,
                         hint=f"give at least {MIN_PHOTO_PIXELS / 1e6:g} megapixel, e.g. 1250x800; the default is "
                              "4000x3000")
    if not (1 <= width <= MAX_SIDE and 1 <= height <= MAX_SIDE) or pixels > MAX_PIXELS:
        raise InputError(f"a {width}x{height} camera is too large to simulate", source=source,
                         hint=f"use at most {MAX_SIDE} pixels per side and {MAX_PIXELS / 1e6:g} megapixels")


def build_scene(options: SimulationOptions, pattern_set):
    """The scene ``options`` ask for: loaded from ``options.scene``, else drawn by :func:`~.scene.random_scene`."""
    from .scene import Scene, random_scene

    o = options
    if o.scene:
        clashing = [f"`{name}`" for name, value in (("seed", o.seed), ("resolution", o.resolution),
                                                    ("slant", o.slant), ("period", o.period), ("order", o.order),
                                                    ("distance_mm", o.distance_mm), ("layout", o.layout),
                                                    ("conditions", None if o.conditions == "standard" else o.conditions))
                    if value is not None]
        if clashing:
            raise InputError(f"cannot be combined with {', '.join(clashing)}", source="scene",
                             hint="the scene file fixes the panel and the camera; drop those options")
        data = read_json_file(o.scene, "scene", "check the scene path")
        scene = Scene.from_dict(data, source=str(o.scene))
        check_resolution(scene.camera.width, scene.camera.height, str(o.scene))
        if scene.seed is not None and not 0 <= scene.seed <= MAX_SEED:
            raise InputError(f"seed {scene.seed} is out of range (0..{MAX_SEED})", source=str(o.scene))
        changes = {}
        if o.jpeg_quality is not None:
            changes["jpeg_quality"] = o.jpeg_quality
        if o.subsamples is not None and o.subsamples != scene.camera.subsamples:
            changes["subsamples"] = o.subsamples
        return scene.replace_camera(**changes) if changes else scene
    seed = o.seed if o.seed is not None else secrets.randbelow(2 ** 31)
    order, layout = o.resolved_layout()
    return random_scene(seed, width=pattern_set.width, height=pattern_set.height, resolution=o.resolution,
                        period=o.period, slant=o.slant, order=order, layout=layout, distance=o.distance_mm,
                        jpeg_quality=o.jpeg_quality, conditions=o.conditions,
                        subsamples=DEFAULT_SUBSAMPLES if o.subsamples is None else o.subsamples)


def is_board_folder(directory: str | os.PathLike) -> bool:
    """Whether ``directory`` is a 'camera patterns' folder (board.json, no patterns.json)."""
    folder = Path(directory)
    return (folder / "board.json").is_file() and not (folder / "patterns.json").exists()


def _check_outputs(directory, pattern_set, o: SimulationOptions) -> list[Path]:
    """The paths a pattern simulation writes, refused before any work when they cannot (or must not) be
    written: none of them may be what it reads (the manifest and the patterns of ``pattern_set``, the
    scene and layout files of ``o``)."""
    from .capture import CAPTURE_FOLDER, CROSSTALK_TRUTH_NAME, SIMULATION_NAME, TRUTH_NAME

    folder = Path(directory)
    inputs = (folder / MANIFEST_NAME, *(folder / p.file for p in pattern_set.patterns), o.scene, o.layout)
    captures = check_output_folder(folder / CAPTURE_FOLDER, "simulated photos", inputs=inputs)
    simulation = check_output_file(folder / SIMULATION_NAME, "simulation record", inputs=inputs)
    truth = check_output_file(folder / TRUTH_NAME, "true profile", inputs=inputs)
    crosstalk_truth = check_output_file(folder / CROSSTALK_TRUTH_NAME, "true crosstalk", inputs=inputs)
    # simulate_capture_set refuses this too; checked here so that real photos are never even copied
    if captures.is_dir() and any(captures.iterdir()) and not simulation.exists():
        raise InputError("holds files that the simulator did not write (real photos?)", source=str(captures),
                         hint="simulate into a fresh copy of the pattern folder")
    return [captures, simulation, truth, crosstalk_truth]


def simulate_folder(directory: str | os.PathLike, options: SimulationOptions | None = None, *,
                    progress: Callable[..., None] | None = None,
                    progress_total: Callable[[int], None] | None = None) -> SimulationRun:
    """Photograph the patterns (or the camera board) of ``directory`` (module docstring).

    ``progress`` is called once per photo, ``progress_total`` once before with their number.
    Returns :class:`SimulationRun`; every user error comes before the first photo.
    """
    from .capture import simulate_capture_set

    o = options or SimulationOptions()
    o.check()
    if is_board_folder(directory):
        return _simulate_board(Path(directory), o, progress, progress_total)
    pattern_set = read_pattern_folder(directory)
    scene = build_scene(o, pattern_set)
    written = _check_outputs(directory, pattern_set, o)
    if progress_total is not None:
        progress_total(len(pattern_set.patterns))

    def each(items):
        for item in items:
            yield item
            if progress is not None:
                progress()

    start = time.perf_counter()
    with restored_on_failure(written, "simulation"):
        summary = simulate_capture_set(directory, scene, raw=o.raw, progress=each)
    summary["seconds"] = round(time.perf_counter() - start, 2)
    cam = scene.camera
    return SimulationRun("patterns", Path(directory), summary, scene, scene.seed, (cam.width, cam.height),
                         summary["photos"], summary["seconds"])


def _simulate_board(folder: Path, o: SimulationOptions, progress, progress_total) -> SimulationRun:
    """Photograph the panel board of a 'camera patterns' folder."""
    from .board_set import CAPTURE_FOLDER, SIMULATION_NAME, TRUTH_NAME, simulate_board_set

    board = read_board(folder / "board.json")
    if board.kind != "panel":
        raise InputError("is a printed board's folder", source=str(folder / "board.json"),
                         hint="simulate the panel board folder (the one with board.png); a printed board is "
                              "simulated as a set of its own (simulate_camera_set, kind 'print')")
    ignored = [f"`{name}`" for name, value in (("scene", o.scene), ("slant", o.slant), ("period", o.period),
                                               ("order", o.order), ("layout", o.layout), ("distance_mm", o.distance_mm),
                                               ("raw", o.raw or None)) if value is not None]
    if ignored:
        raise InputError(f"does not apply to a camera board folder: {', '.join(ignored)}", source=str(folder),
                         hint="the board folder fixes the panel; the camera moves around it")
    check_board_photos(o.photos)
    resolution = o.resolution or BOARD_RESOLUTION
    inputs = (folder / BOARD_MANIFEST, folder / PANEL_IMAGE)  # what the simulation reads
    captures = check_output_folder(folder / CAPTURE_FOLDER, "simulated photos", inputs=inputs)
    written = [captures, check_output_file(folder / SIMULATION_NAME, "simulation record", inputs=inputs),
               check_output_file(folder / TRUTH_NAME, "true camera model", inputs=inputs)]
    if captures.is_dir() and any(captures.iterdir()) and not (folder / SIMULATION_NAME).exists():
        raise InputError("holds files that the simulator did not write (real photos?)", source=str(captures),
                         hint="simulate into a fresh 'camera patterns' folder")
    seed = o.seed if o.seed is not None else secrets.randbelow(2 ** 31)
    if progress_total is not None:
        progress_total(o.photos)
    start = time.perf_counter()
    with restored_on_failure(written, "simulation"):
        doc = simulate_board_set(folder, kind="panel", seed=seed, photos=o.photos, resolution=resolution,
                                 conditions=o.conditions, subsamples=o.subsamples or BOARD_SUBSAMPLES,
                                 progress=progress, board=board)
    seconds = round(time.perf_counter() - start, 2)
    return SimulationRun("board", folder, doc, None, seed, tuple(resolution), o.photos, seconds)


CAMERA_SET_EXTRA = ("report", "camera.cameramodel")  # what the suggested next step writes into the folder


def simulate_camera_set(directory: str | os.PathLike, *, kind: str = "panel", seed: int | None = None,
                        photos: int = 24, resolution: tuple[int, int] = BOARD_RESOLUTION,
                        conditions: str = "standard", subsamples: int = BOARD_SUBSAMPLES,
                        progress: Callable[..., None] | None = None, pattern: str = "chessboard") -> SimulationRun:
    """A synthetic camera-calibration set in ``directory`` (new, or one this function wrote before;
    staged, whole or not at all): ``photos`` photos of a ``kind`` ('panel' or 'print') board by a
    known camera of ``resolution`` (:data:`~lenticalib.core.sizes.MIN_CAMERA_SIDE`..:data:`~lenticalib.core.sizes.MAX_SIDE` pixels per side), ``DIR/truth.cameramodel`` and the
    board poses in ``DIR/simulation.json`` (:func:`~.board_set.simulate_board_set`); ``pattern``
    "chessboard" or "charuco" (then some boards run off the frame).  ``progress`` once per photo.
    InputError naming the argument before any photo."""
    from .board_set import CAPTURE_FOLDER, CONTENTS, simulate_board_set

    check_sides(*resolution, "resolution", MIN_CAMERA_SIDE)
    check_board_photos(photos)
    if not 1 <= subsamples <= 8:
        raise InputError(f"{subsamples} subsamples is out of range", source="subsamples", hint="use 1..8")
    check_seed(seed)
    if pattern not in PATTERNS:
        raise InputError(f"unknown board pattern {pattern!r}", source="pattern", hint="use " + " or ".join(PATTERNS))
    contents = (CONTENTS + CAMERA_SET_EXTRA + (f"{CAPTURE_FOLDER}/board-[0-9][0-9]*.jpg",)
                + tuple(f"report/{name}" for name in REPORT_FILES))
    check_output_folder(directory, "camera simulation", contents, inputs=())  # drawn from the arguments alone
    seed = seed if seed is not None else secrets.randbelow(2 ** 31)
    start = time.perf_counter()
    with staged_folder(directory, "camera simulation", contents, inputs=()) as stage:
        doc = simulate_board_set(stage, kind=kind, seed=seed, photos=photos, resolution=tuple(resolution),
                                 conditions=conditions, subsamples=subsamples, progress=progress, pattern=pattern)
    seconds = round(time.perf_counter() - start, 2)
    return SimulationRun("board", Path(directory), doc, None, seed, tuple(resolution), photos, seconds)
