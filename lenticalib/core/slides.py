"""What ``lenticalib show`` and ``lenticalib capture`` step through: one image, a pattern set in
manifest order, or a folder.

A *slide* is a named raster that is loaded when it is shown (a 4K raster is 25 MB; a pattern
set is 23 of them).  Pattern sets are shown from their PNGs, or drawn from the manifest when
the PNGs are not there (a capture set keeps only ``patterns.json`` and the photos).
"""

from __future__ import annotations

import dataclasses
import time
from pathlib import Path
from typing import Callable

import numpy as np

from .errors import ImageError
from .files.imageio import read_image
from .pattern_sets import MANIFEST_NAME, read_pattern_folder

IMAGE_SUFFIXES = (".png", ".tif", ".tiff", ".npy", ".jpg", ".jpeg", ".bmp")
NEXT_KEYS = {"space", "right", "down", "page_down", "enter"}
PREVIOUS_KEYS = {"left", "up", "page_up", "backspace"}
QUIT_KEYS = {"escape", "q"}


@dataclasses.dataclass(frozen=True)
class Slide:
    """``name`` (the pattern name, or the file name), ``source`` (a path, for messages) and
    ``load()`` -> (height, width, 3) uint8/uint16 RGB raster."""

    name: str
    source: str
    load: Callable[[], np.ndarray]


def slides_from_path(path: str | Path) -> tuple[list[Slide], tuple[int, int]]:
    """(slides, (width, height) they all have) for an image file, a pattern folder or an image
    folder; ImageError / InputError naming the path for anything else."""
    p = Path(path)
    if not p.exists():
        raise ImageError("no such file or folder", source=str(p), hint="give an image or a folder of images")
    if p.is_file():
        raster = read_image(p)
        return [Slide(p.name, str(p), lambda: raster)], (raster.shape[1], raster.shape[0])
    if (p / MANIFEST_NAME).exists():
        pattern_set = read_pattern_folder(p)
        slides = []
        for pattern in pattern_set.patterns:
            png = p / pattern.file
            if png.exists():
                slides.append(Slide(pattern.name, str(png), lambda png=png: read_image(
                    png, expected_size=(pattern_set.width, pattern_set.height), what="the pattern set's panel")))
            else:
                slides.append(Slide(pattern.name, f"{p / MANIFEST_NAME} ({pattern.name})",
                                    lambda pattern=pattern: pattern_set.render(pattern)))
        return slides, (pattern_set.width, pattern_set.height)
    files = sorted(f for f in p.iterdir() if f.is_file() and f.suffix.lower() in IMAGE_SUFFIXES)
    if not files:
        raise ImageError("holds no images", source=str(p),
                         hint=f"give a folder with {', '.join(IMAGE_SUFFIXES)} files, or a pattern folder")
    first = read_image(files[0])
    size = (first.shape[1], first.shape[0])
    return [Slide(f.name, str(f), lambda f=f: read_image(f, expected_size=size, what=files[0].name)) for f in files], size


def run_slideshow(presenter, slides: list[Slide], interval: float | None = None, loop: bool = False,
                  on_show: Callable[[int, Slide], None] | None = None, clock=time.monotonic) -> int:
    """Show ``slides`` on an opened ``presenter``; returns how many slides were shown.

    Keys: space, right, down, page down, enter -> next; left, up, page up, backspace ->
    previous; escape or q -> quit.  With ``interval`` (seconds) the show also advances by
    itself.  Stepping past the last slide ends the show (or wraps with ``loop``).  A raster
    that is not the presenter's size ends it with ImageError naming the file.
    """
    index, shown = 0, 0
    while 0 <= index < len(slides):
        slide = slides[index]
        presenter.show(slide.load(), source=slide.source)
        shown += 1
        if on_show is not None:
            on_show(index, slide)
        step = _wait_for_step(presenter, interval, clock)
        if step == 0:
            break
        index += step
        if loop:
            index %= len(slides)
        else:
            index = max(index, 0) if step < 0 else index
    return shown


def _wait_for_step(presenter, interval: float | None, clock) -> int:
    """+1 (next), -1 (previous) or 0 (quit), from the keys, or +1 once ``interval`` has passed."""
    deadline = None if interval is None else clock() + interval
    while True:
        remaining = 0.25 if deadline is None else max(0.0, min(0.25, deadline - clock()))
        for key in presenter.keys(timeout=remaining):
            if key in QUIT_KEYS:
                return 0
            if key in NEXT_KEYS:
                return 1
            if key in PREVIOUS_KEYS:
                return -1
        if deadline is not None and clock() >= deadline:
            return 1
