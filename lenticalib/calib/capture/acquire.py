"""Guided capture: show every calibration pattern on the panel, photograph it, check it at once.

For a pattern folder written by ``lenticalib patterns`` (or one whose PNGs are gone: they
are drawn from ``patterns.json``), :func:`capture_set` shows each pattern in manifest order
through a presenter (:mod:`lenticalib.render.present.window`), waits for the panel to settle,
triggers a capture camera (:mod:`.cameras`) and files the photo as
``DIR/captures/NAME.jpg``.  Each photo gets the checks the fit would make of it alone at once
-- readable, big enough, the same size as the others, not black, not clipped, changed from
the other steps of its group -- and is retaken on the spot when it fails (the rejected photo
is kept in ``DIR/rejected/`` to look at), rather than discovered after the whole set.

"Changed" is measured against the camera's own noise, not a fixed threshold: the first photo
of the set is taken twice (the second is kept as ``DIR/repeat/NAME.jpg``), and what two photos
of one unchanged panel differ by -- noise, JPEG, a drift of exposure, shake -- is the yardstick
(:func:`change_energy`).  A photo that differs from an earlier step of its group by less than
``UNCHANGED_FACTOR`` times that shows the previous pattern (the camera fired before the panel
changed).  Every step of a group changes the panel a lot -- a fine fringe moved by a third of
its period, a band of views moved across the panel -- but may change the photo's light little
(a fine fringe is averaged away in a small copy of the photo, a dark band moves little light),
so the comparison is made at the check width, on the square root of the light (shot noise
then has one size at every level).  Of a crosstalk set only steps the patterns say the camera
sees differently are compared: a band is seen only where it passes the fitted camera's view
(:func:`~.crosstalk.patterns.seen_columns`), and two bands seen nowhere give the same dark photo.
The manual camera (the user presses the shutter, and may take a while) takes no repeat: for it
only an identical photo counts as unchanged.

Resuming: photos already in ``captures/`` that pass the checks are kept, so an interrupted
capture goes on where it stopped.  Photos are written atomically by the cameras, so an
interruption never leaves half a photo under a pattern's name.
"""

from __future__ import annotations

import dataclasses
import os
import shutil
import time
from pathlib import Path
from typing import Callable

import numpy as np

from ...core.errors import CameraError, CaptureError, InputError, LenticalibError
from ...core.pattern_sets import read_pattern_folder
from ...core.slides import slides_from_path
from ..patterns.capture_sets import PHOTO_SUFFIXES, check_exposure, load_photo

CAPTURE_FOLDER = "captures"
REJECTED_FOLDER = "rejected"
REPEAT_FOLDER = "repeat"
REPEAT_SUFFIX = ".repeat"  # the repeat photo's pattern name: NAME.repeat (the virtual camera draws fresh noise)
UNCHANGED_FACTOR = 4.0  # a photo changed less than this many times two photos of one pattern differ: unchanged
LEVEL_FLOOR = 0.01  # linear light added before the square root (read noise dominates below it)
EXACT = 1e-12  # change energy of two identical photos (rounding only)
MIN_SEEN_CHANGE = 0.01  # share of the panel's columns two crosstalk patterns must be seen differently in
VIRTUAL_HINT = ("the virtual camera photographs what the presenter shows: run the capture again with "
                "`display` none (it resumes here), and report the rejected photos if it happens again")
MAX_CLIPPED = 0.02  # of the bright part of the photo (the fit refuses more than 2 % of the panel)
CHECK_WIDTH = 800  # photos are checked at this width (fast; the fit works at up to 2560)


@dataclasses.dataclass
class CaptureReport:
    """What a capture run did: ``taken`` and ``kept`` (resumed) pattern names, ``retakes``
    (name -> how many photos were rejected), ``settings`` (what the camera locked and what not),
    ``seconds``."""

    taken: list[str] = dataclasses.field(default_factory=list)
    kept: list[str] = dataclasses.field(default_factory=list)
    retakes: dict[str, int] = dataclasses.field(default_factory=dict)
    settings: list[str] = dataclasses.field(default_factory=list)
    seconds: float = 0.0


def existing_photo(captures: Path, name: str) -> Path | None:
    """The photo already filed for pattern ``name`` (any photo suffix), or None."""
    for suffix in PHOTO_SUFFIXES:
        for candidate in (captures / f"{name}{suffix}", captures / f"{name}{suffix.upper()}"):
            if candidate.is_file():
                return candidate
    return None


@dataclasses.dataclass(frozen=True)
class Problem:
    """Why a photo was rejected: ``message`` (what is wrong with it) and ``hint`` (what to do)."""

    message: str
    hint: str


def photo_problem(name: str, path: Path, size: tuple[int, int] | None, others: list[np.ndarray],
                  noise: float = 0.0, camera_kind: str = "") -> Problem | None:
    """Why the photo at ``path`` would fail the fit on its own, or None.

    ``size``: (width, height) the set's photos have (None for the first); ``others``: check
    images (:func:`check_image`) of the photos already taken in the same group; ``noise``: the
    change energy between two photos of one unchanged panel (:func:`change_energy`; 0: only an
    identical photo counts as unchanged); ``camera_kind``: the camera's kind, for the hints.
    """
    return _examine(name, path, size, others, noise, camera_kind)[0]


def _examine(name, path, size, others, noise, camera_kind) -> tuple[Problem | None, tuple[int, int], np.ndarray | None]:
    """:func:`photo_problem`, and the photo's (width, height) and check image (None if unreadable)."""
    camera_hint = (VIRTUAL_HINT if camera_kind == "sim" else
                   "fix the camera (exposure, focus, position) and run the capture again: it resumes here")
    try:
        photo = load_photo(name, path, max_width=CHECK_WIDTH)
        check_exposure(photo)
    except LenticalibError as exc:
        return Problem(exc.message, camera_hint), (0, 0), None
    taken = (photo.shape[1], photo.shape[0])
    if size is not None and taken != tuple(size):
        return Problem(f"is {taken[0]}x{taken[1]} pixels, the other photos are {size[0]}x{size[1]} "
                       "(zoom or resolution changed)", camera_hint), taken, None
    bright = photo.luma > 0.5 * float(np.percentile(photo.luma, 99))
    if bright.any() and float(photo.clipped[bright].mean()) > MAX_CLIPPED:
        return Problem(f"is overexposed ({100 * float(photo.clipped[bright].mean()):.0f}% of the bright part "
                       "clipped)", camera_hint), taken, None
    image = check_image(photo)
    for other in others:
        if other.shape == image.shape and change_energy(other, image) <= max(UNCHANGED_FACTOR * noise, EXACT):
            return Problem(_unchanged_message(noise), _unchanged_hint(camera_kind)), taken, image
    return None, taken, image


def _unchanged_message(noise: float) -> str:
    if noise > 0:
        return ("shows the same image as an earlier step of its group (it differs from it no more than two photos "
                "of one pattern do: the panel had not changed yet when the camera fired)")
    return "is the same image as an earlier step of its group (an identical photo)"


def _unchanged_hint(camera_kind: str) -> str:
    if camera_kind == "sim":
        return VIRTUAL_HINT
    if camera_kind == "manual":
        return "photograph each pattern after it appears on the panel, and save each photo once"
    return ("give the panel longer to change before the camera fires (--settle), and run the capture again: it "
            "resumes here")


def check_image(photo) -> np.ndarray:
    """The image a photo's change is measured on: ``sqrt(luma + LEVEL_FLOOR)``, float64 ``(h, w)``.

    ``photo``: a :class:`~.captures.Photo` loaded at CHECK_WIDTH (linear-light luma in 0..1).  Shot
    noise has a variance proportional to the light; after the square root it is about the same at
    every level, so one noise measure serves a dark band and a bright fringe.
    """
    return np.sqrt(photo.luma.astype(np.float64) + LEVEL_FLOOR)


def change_energy(before: np.ndarray, after: np.ndarray) -> float:
    """How much ``after`` changed from ``before`` beyond a change of exposure: the mean square of
    ``after - (g before + o)`` with gain ``g`` and offset ``o`` fitted by least squares.

    Both are check images (:func:`check_image`) of one shape ``(h, w)``.  Two photos of one
    unchanged panel differ by their noise alone; two phase steps of a fringe, or two positions of
    a band, by much more.
    """
    a = before.ravel() - before.mean()
    b = after.ravel() - after.mean()
    aa = float(a @ a)
    gain = float(a @ b) / aa if aa > 0 else 0.0
    return float(np.mean((b - gain * a) ** 2))


def capture_set(directory: str | os.PathLike, presenter, camera, *, settle: float = 0.5, retakes: int = 2,
                restart: bool = False, progress: Callable[[str], None] | None = None,
                notify: Callable[[str], None] | None = None,
                sleep: Callable[[float], None] = time.sleep) -> CaptureReport:
    """Show and photograph every pattern of ``directory``; see the module docstring.

    ``presenter``: an opened presenter of the pattern set's size; ``camera``: an opened capture
    camera; ``settle``: seconds between showing a pattern and triggering; ``retakes``: photos
    rejected per pattern before giving up (CaptureError naming the photo); ``restart``: take
    every photo again.  ``progress(message)`` is called once per pattern, ``notify(message)`` for
    each rejected photo.
    """
    start = time.perf_counter()
    directory = Path(directory)
    pattern_set = read_pattern_folder(directory)
    if tuple(presenter.size) != (pattern_set.width, pattern_set.height):
        raise InputError(f"the patterns are for a {pattern_set.width}x{pattern_set.height} panel but the display "
                         f"is {presenter.size[0]}x{presenter.size[1]}", source=str(directory),
                         hint="capture on the panel's own monitor (`display`), at its native mode")
    captures = _prepared_folder(directory, pattern_set.names)
    slides = {s.name: s for s in slides_from_path(directory)[0]}
    report = CaptureReport(settings=list(camera.settings()))
    size: tuple[int, int] | None = None
    noise: float | None = 0.0 if camera.kind == "manual" else None  # None: not measured yet
    group_images: dict[str, list[tuple[np.ndarray | None, np.ndarray]]] = {}
    for pattern in pattern_set.patterns:
        seen = _seen(pattern_set, pattern)
        others = [image for other_seen, image in group_images.setdefault(pattern.group, [])
                  if seen is None or float(np.mean(seen != other_seen)) >= MIN_SEEN_CHANGE]
        old = existing_photo(captures, pattern.name)
        if old is not None and restart:
            _reject(directory, old, pattern.name)
            old = None
        shown = None
        problem, taken, image = (_examine(pattern.name, old, size, others, noise or 0.0, camera.kind)
                                 if old is not None else (None, None, None))
        if old is not None and problem is None:
            report.kept.append(pattern.name)
            path = old
            if progress:
                progress(f"{pattern.name}: kept {old.name}")
        else:
            if old is not None:
                _reject(directory, old, pattern.name)
            shown = _show(presenter, camera, slides[pattern.name])
            for attempt in range(retakes + 1):
                sleep(settle * (1 + attempt))  # a repeated step: give the panel longer
                path = camera.capture(pattern.name, shown, captures / pattern.name)
                problem, taken, image = _examine(pattern.name, path, size, others, noise or 0.0, camera.kind)
                if problem is None:
                    break
                report.retakes[pattern.name] = report.retakes.get(pattern.name, 0) + 1
                _reject(directory, path, pattern.name)
                if notify:
                    notify(f"{path.name} {problem.message}: retaking it")
            if problem is not None:
                raise CaptureError(f"{problem.message}; rejected {retakes + 1} times",
                                   source=str(captures / f"{pattern.name}.jpg"),
                                   hint=f"the rejected photos are in {directory / REJECTED_FOLDER}; {problem.hint}")
            report.taken.append(pattern.name)
            if progress:
                progress(f"{pattern.name}: {path.name}")
        size = taken
        group_images[pattern.group].append((seen, image))
        if noise is None:
            noise = _measure_noise(directory, pattern.name, path, image, taken, slides[pattern.name], presenter,
                                   camera, shown, settle, sleep, fresh=restart or shown is not None)
    report.seconds = time.perf_counter() - start
    return report


def _seen(pattern_set, pattern) -> np.ndarray | None:
    """Where the camera sees ``pattern`` lit: :func:`~.crosstalk.patterns.seen_columns` for a crosstalk
    set; None for calibration fringes (every step of a group changes the whole panel)."""
    if not hasattr(pattern_set, "bands"):
        return None
    from ..patterns.crosstalk_patterns import seen_columns

    return seen_columns(pattern_set, pattern)


def _show(presenter, camera, slide) -> np.ndarray:
    """Put ``slide`` on the panel; the raster the camera is given (read back for the virtual camera)."""
    raster = slide.load()
    presenter.show(raster, source=slide.source)
    return presenter.read_back() if camera.kind == "sim" else raster


def _measure_noise(directory: Path, name: str, photo: Path, image: np.ndarray, taken: tuple[int, int], slide,
                   presenter, camera, shown, settle: float, sleep: Callable[[float], None], fresh: bool) -> float:
    """The change energy between the photo of pattern ``name`` (its check image ``image``, its
    size ``taken``) and its repeat ``DIR/repeat/NAME.jpg``: the camera's noise.

    An earlier repeat is used when the photo was kept (``fresh`` False); otherwise it goes to
    ``rejected/`` and a new one is taken of the pattern, shown again if it no longer is
    (``shown`` None).  CaptureError naming the repeat when it fails the checks of a photo.
    """
    folder = directory / REPEAT_FOLDER
    repeat_name = name + REPEAT_SUFFIX
    repeat = existing_photo(folder, name) if folder.is_dir() else None
    if repeat is not None and fresh:
        _reject(directory, repeat, repeat_name)
        repeat = None
    if repeat is None:
        if shown is None:
            shown = _show(presenter, camera, slide)
        sleep(settle)
        repeat = camera.capture(repeat_name, shown, folder / name)
    problem, _, second = _examine(name, repeat, taken, [], 0.0, camera.kind)
    if problem is not None:
        raise CaptureError(f"{problem.message} (the second photo of {name}, which measures the camera's noise)",
                           source=str(repeat), hint=problem.hint)
    return change_energy(image, second)


def _prepared_folder(directory: Path, names: list[str]) -> Path:
    """``DIR/captures`` (created), after checking it holds only photos named like the patterns."""
    captures = directory / CAPTURE_FOLDER
    if captures.exists() and not captures.is_dir():
        raise InputError("is not a folder", source=str(captures), hint="move the file away")
    try:
        captures.mkdir(exist_ok=True)
    except OSError as exc:
        raise InputError(f"cannot create: {exc.strerror}", source=str(captures),
                         hint="choose a pattern folder you may write to") from None
    if not os.access(captures, os.W_OK):
        raise InputError("is not writable", source=str(captures), hint="choose a pattern folder you may write to")
    foreign = sorted(p.name for p in captures.iterdir()
                     if not (p.is_file() and p.stem in names and p.suffix.lower() in PHOTO_SUFFIXES)
                     and not p.name.startswith("."))
    if foreign:
        raise InputError(f"holds files that are not photos of these patterns: {', '.join(foreign[:5])}",
                         source=str(captures), hint="move them away; the fit accepts only NAME.jpg per pattern")
    return captures


def _reject(directory: Path, path: Path, name: str) -> Path:
    """Move a photo out of ``captures/`` into ``rejected/NAME-K.ext`` (kept for the user)."""
    folder = directory / REJECTED_FOLDER
    folder.mkdir(exist_ok=True)
    k = 1
    while (folder / f"{name}-{k}{path.suffix}").exists():
        k += 1
    target = folder / f"{name}-{k}{path.suffix}"
    shutil.move(str(path), target)
    return target


def wait_for_key(presenter, name: str, announce: Callable[[str], None] = print) -> None:
    """For the manual camera without a watched folder: wait for space/enter on the panel's
    window after the user has taken the photo; escape stops the run (it resumes later)."""
    announce(f"photograph pattern {name} now, save it as captures/{name}.jpg, then press space on the panel")
    while True:
        for key in presenter.keys(timeout=0.25):
            if key in ("space", "enter"):
                return
            if key in ("escape", "q"):
                raise CameraError("capture stopped by the user", source=name,
                                  hint="run the same command again to go on from this pattern")
