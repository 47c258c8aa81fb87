"""Guided capture: show every calibration pattern on the panel, photograph it, check it at once.

For a pattern folder written by ``lenticalib patterns`` (or one whose PNGs are gone: they
are drawn from ``patterns.json``), :func:`capture_set` shows each pattern in manifest order
through a presenter (:mod:`lenticalib.render.present`), waits for the panel to settle,
triggers a capture camera (:mod:`.cameras`) and files the photo as
``DIR/captures/NAME.jpg``.  Each photo gets the checks the fit would make of it alone at once
-- readable, big enough, the same size as the others, not black, not clipped, different from
the other steps of its group -- and is retaken on the spot when it fails (the rejected photo
is kept in ``DIR/rejected/`` to look at), rather than discovered after the whole set.

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

from ..errors import CameraError, CaptureError, InputError, LenticalibError
from .captures import PHOTO_SUFFIXES, check_exposure, load_photo

CAPTURE_FOLDER = "captures"
REJECTED_FOLDER = "rejected"
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


def photo_problem(name: str, path: Path, size: tuple[int, int] | None, others: list[np.ndarray]) -> str | None:
    """Why the photo at ``path`` would fail the fit on its own, or None.

    ``size``: (width, height) the set's photos have (None for the first); ``others``: small
    luma images of the photos already taken in the same group (a repeated step shows the
    panel did not change in time).
    """
    try:
        photo = load_photo(name, path, max_width=CHECK_WIDTH)
        check_exposure(photo)
    except LenticalibError as exc:
        return exc.message
    if size is not None and (photo.shape[1], photo.shape[0]) != tuple(size):
        return (f"is {photo.shape[1]}x{photo.shape[0]} pixels, the other photos are {size[0]}x{size[1]} "
                "(zoom or resolution changed)")
    bright = photo.luma > 0.5 * float(np.percentile(photo.luma, 99))
    if bright.any() and float(photo.clipped[bright].mean()) > MAX_CLIPPED:
        return f"is overexposed ({100 * float(photo.clipped[bright].mean()):.0f}% of the bright part clipped)"
    small = _small(photo.luma)
    level = float(np.mean(small ** 2))
    for other in others:
        if other.shape == small.shape and float(np.mean((other - small) ** 2)) < 0.002 * level:
            return ("shows the same image as the previous step (the panel had not changed yet, or its fringes "
                    "are not visible: check focus)")
    return None


def _small(luma: np.ndarray) -> np.ndarray:
    import cv2

    return cv2.resize(luma.astype(np.float32), None, fx=0.25, fy=0.25, interpolation=cv2.INTER_AREA)


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
    from ..render.slides import slides_from_path
    from .patterns import read_pattern_folder

    start = time.perf_counter()
    directory = Path(directory)
    pattern_set = read_pattern_folder(directory)
    if tuple(presenter.size) != (pattern_set.width, pattern_set.height):
        raise InputError(f"the patterns are for a {pattern_set.width}x{pattern_set.height} panel but the display "
                         f"is {presenter.size[0]}x{presenter.size[1]}", source=str(directory),
                         hint="capture on the panel's own monitor (--display), at its native mode")
    captures = _prepared_folder(directory, pattern_set.names)
    slides = {s.name: s for s in slides_from_path(directory)[0]}
    report = CaptureReport(settings=list(camera.settings()))
    size: tuple[int, int] | None = None
    group_smalls: dict[str, list[np.ndarray]] = {}
    for pattern in pattern_set.patterns:
        others = group_smalls.setdefault(pattern.group, [])
        old = existing_photo(captures, pattern.name)
        if old is not None and restart:
            _reject(directory, old, pattern.name)
            old = None
        if old is not None and photo_problem(pattern.name, old, size, others) is None:
            report.kept.append(pattern.name)
            size, small = _size_and_small(pattern.name, old)
            others.append(small)
            if progress:
                progress(f"{pattern.name}: kept {old.name}")
            continue
        if old is not None:
            _reject(directory, old, pattern.name)
        raster = slides[pattern.name].load()
        presenter.show(raster, source=slides[pattern.name].source)
        shown = presenter.read_back() if camera.kind == "sim" else raster
        problem = None
        for attempt in range(retakes + 1):
            sleep(settle * (1 + attempt))  # a repeated step: give the panel longer
            path = camera.capture(pattern.name, shown, captures / pattern.name)
            problem = photo_problem(pattern.name, path, size, others)
            if problem is None:
                break
            report.retakes[pattern.name] = report.retakes.get(pattern.name, 0) + 1
            _reject(directory, path, pattern.name)
            if notify:
                notify(f"{path.name} {problem}: retaking it")
        if problem is not None:
            raise CaptureError(f"{problem}; rejected {retakes + 1} times", source=str(captures / f"{pattern.name}.jpg"),
                               hint=f"the rejected photos are in {directory / REJECTED_FOLDER}; fix the camera "
                                    "(exposure, focus, position) and run the capture again: it resumes here")
        report.taken.append(pattern.name)
        size, small = _size_and_small(pattern.name, path)
        others.append(small)
        if progress:
            progress(f"{pattern.name}: {path.name}")
    report.seconds = time.perf_counter() - start
    return report


def _size_and_small(name: str, path: Path) -> tuple[tuple[int, int], np.ndarray]:
    photo = load_photo(name, path, max_width=CHECK_WIDTH)
    return (photo.shape[1], photo.shape[0]), _small(photo.luma)


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
