"""Pattern folders written whole: what ``lenticalib patterns`` and ``lenticalib crosstalk patterns`` run.

Each function checks its arguments and the folder first (:func:`lenticalib.core.files.outputs.check_output_folder`),
then designs and writes the patterns and ``patterns.json``; a failed or interrupted run puts an
earlier pattern set of the folder back as it was (:func:`lenticalib.core.files.outputs.restored_on_failure`).
The direction check pattern (:func:`write_direction_pattern`) is one raster in a folder.

Errors name the argument at fault by its parameter name (``source="width"``, ``"views"``,
``"sweep"``); a command-line front end maps them to its flags.
"""

from __future__ import annotations

import math
import os
from pathlib import Path
from typing import Callable

import numpy as np

from ...core import pattern_sets
from ...core.errors import InputError
from ...core.files.imageio import check_image_output, write_image
from ...core.files.outputs import Inputs, check_output_folder, restored_on_failure
from ...core.profile import MAX_VIEWS, PanelProfile
from ...core.sizes import MAX_SIDE, MIN_PANEL_SIDE
from ..patterns import calibration_patterns as patterns_module



def _write(folder: Path, pattern_set, progress: Callable[..., None] | None,
           progress_total: Callable[[int], None] | None) -> None:
    if progress_total is not None:
        progress_total(len(pattern_set.patterns))

    written = ([folder / p.file for p in pattern_set.patterns] + [folder / pattern_sets.MANIFEST_NAME]
               if folder.exists() else [folder])

    def each(items):
        for item in items:
            yield item
            if progress is not None:
                progress()

    with restored_on_failure(written, "patterns"):
        pattern_sets.write_patterns(folder, pattern_set, progress=each(pattern_set.patterns))


def write_calibration_patterns(output: str | os.PathLike, width: int = 3840, height: int = 2160, views: int = 32,
                               progress: Callable[..., None] | None = None,
                               progress_total: Callable[[int], None] | None = None, cells: bool = False):
    """Write the calibration patterns of a ``width`` x ``height`` panel with ``views`` views into the
    folder ``output`` (``progress`` once per pattern, ``progress_total`` once before; ``cells``: with
    the cell patterns, :data:`~.patterns.CELL_GROUPS`); returns the :class:`~.patterns.PatternSet`.
    InputError naming the argument or the folder before any work."""
    for field, value in (("width", width), ("height", height)):
        if not MIN_PANEL_SIDE <= value <= MAX_SIDE:
            raise InputError(f"{value} pixels is out of range", source=field,
                             hint=f"give the panel raster size in pixels, {MIN_PANEL_SIDE}..{MAX_SIDE}")
    if not 2 <= views <= MAX_VIEWS:
        raise InputError(f"{views} views is out of range", source="views", hint=f"use 2..{MAX_VIEWS}")
    folder = check_output_folder(output, "patterns", inputs=())  # drawn from the arguments alone
    pattern_set = patterns_module.design_patterns(width, height, views, cells=cells)
    _write(folder, pattern_set, progress, progress_total)
    return pattern_set


def write_crosstalk_pattern_folder(profile: PanelProfile, output: str | os.PathLike, sweep: float | None = None,
                                   progress: Callable[..., None] | None = None,
                                   progress_total: Callable[[int], None] | None = None, *, inputs: Inputs):
    """Write the crosstalk patterns of ``profile`` (band sweeps over ``sweep`` columns, default
    :func:`~.crosstalk.patterns.default_sweep`) into the folder ``output``; returns the
    :class:`~.crosstalk.patterns.CrosstalkPatternSet`.  ``inputs``: the files the caller read
    (the profile's file), never written over (:mod:`lenticalib.core.files.outputs`)."""
    from ..patterns.crosstalk_patterns import default_sweep, design_crosstalk_patterns

    if sweep is not None and not (math.isfinite(sweep) and 4 * profile.views <= sweep <= 4 * profile.width):
        raise InputError(f"sweep {sweep} pixels is out of range", source="sweep",
                         hint=f"use {4 * profile.views}..{4 * profile.width} pixels (default {default_sweep(profile):g})")
    folder = check_output_folder(output, "crosstalk patterns", inputs=inputs)
    pattern_set = design_crosstalk_patterns(profile, sweep)
    _write(folder, pattern_set, progress, progress_total)
    return pattern_set


def write_direction_pattern(profile: PanelProfile, output: str | os.PathLike, encode: Callable[..., np.ndarray], *,
                            inputs: Inputs) -> Path:
    """Write the LEFT/RIGHT check raster of ``profile`` (:func:`~.direction.direction_raster`, drawn
    with the encoder entry point ``encode`` the caller passes: the calibration layer does not import
    the render layer) as ``output/direction.png``; a new folder is made only once the raster is
    ready.  ``inputs``: the files the caller read (the profile's file), never written over.  Returns its path."""
    from ..routing.direction import DIRECTION_PATTERN_NAME, direction_raster

    folder = check_output_folder(output, "direction pattern", inputs=inputs)
    target = folder / DIRECTION_PATTERN_NAME
    if folder.exists():
        check_image_output(target, what="direction pattern", inputs=inputs)
    raster = direction_raster(profile, encode)
    folder.mkdir(exist_ok=True)
    write_image(target, raster)
    return target
