"""Raster sizes: the one ``WxH`` parser, the one set of size limits, the one raster-size check.

Every size lenticalib takes from a user (a panel raster ``--panel 3840x2160``, a camera
``--resolution 4000x3000``, a view ``--view-size 960x540``, an emulated panel
``emu://bench?panel=1920x1080``) is read by :func:`parse_size`; every raster is checked against
the panel it is meant for by :func:`check_raster`.  Sizes are ``(width, height)`` in pixels;
arrays are ``(height, width, 3)``.

LIMITS.  :data:`MAX_SIDE` (16384 pixels) is the largest side of any raster lenticalib makes or
reads: panel rasters and profiles, views, camera photos.  It admits an 8K panel (7680 x 4320),
every Looking Glass panel (the largest, 65-inch, is 7680 x 4320) and the 16K panels announced,
and it is the side of :data:`lenticalib.core.files.imageio.MAX_IMAGE_PIXELS` (16384 x 16384), the
largest image lenticalib reads, so a raster any command writes is one every command reads.
The smallest sides are set by what the work needs: :data:`MIN_PANEL_SIDE` (64) pixels hold the
calibration patterns' coarsest period; :data:`MIN_CAMERA_SIDE` (240) is the smallest camera
(QVGA) whose photos resolve a pattern at all.
"""

from __future__ import annotations

import re
from typing import Any

import numpy as np

from .errors import ImageError, InputError

MAX_SIDE = 16384  # pixels per side of any raster, panel, view or photo (module docstring)
MIN_PANEL_SIDE = 64  # pixels per side of the smallest panel the calibration patterns are drawn for
MIN_CAMERA_SIDE = 240  # pixels per side of the smallest camera photo

_SIZE = re.compile(r"\s*(\d{1,9})\s*[xX]\s*(\d{1,9})\s*")


def size_problem(width: Any, height: Any, low: int = 1, high: int = MAX_SIDE) -> str | None:
    """Why ``width`` x ``height`` is no size in ``low..high`` pixels per side, else None."""
    for value in (width, height):
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
            return f"{value!r} is not a whole number of pixels"
    if not (low <= width <= high and low <= height <= high):
        return f"{width}x{height} is out of range"
    return None


def check_sides(width: Any, height: Any, source: str, low: int = 1, high: int = MAX_SIDE) -> tuple[int, int]:
    """``(width, height)`` as ints when each is a whole number in ``low..high`` pixels; else one
    InputError naming ``source`` and the allowed range."""
    problem = size_problem(width, height, low, high)
    if problem is not None:
        raise InputError(problem, source=source, hint=f"use {low}..{high} pixels per side")
    return int(width), int(height)


def parse_pair(text: Any, source: str, low: int, high: int, *, form: str, unit: str, example: str,
               error: type[InputError] = InputError) -> tuple[int, int]:
    """``"AxB"`` -> ``(A, B)``, each a whole number ``low..high`` of ``unit``: the one parser of every
    ``AxB`` lenticalib reads (raster sizes in pixels, quilt grids in tiles, boards in inner corners).

    ``form`` (``"WIDTHxHEIGHT"``) and ``example`` (``"3840x2160"``) say how to write it.  Anything
    else is one ``error`` naming ``source`` and the allowed range.
    """
    match = _SIZE.fullmatch(text) if isinstance(text, str) else None
    if match is None:
        raise error(f"must be {form} in {unit}, e.g. {example}, got {text!r}", source=source,
                    hint=f"use {low}..{high} {unit} per side")
    a, b = int(match[1]), int(match[2])
    if not (low <= a <= high and low <= b <= high):
        raise error(f"{a}x{b} is out of range", source=source, hint=f"use {low}..{high} {unit} per side")
    return a, b


def parse_size(value: Any, source: str, low: int = 1, high: int = MAX_SIDE,
               example: str = "3840x2160") -> tuple[int, int]:
    """``"WxH"`` (or a ``(w, h)`` pair) -> ``(width, height)`` in pixels, each ``low..high``.

    Anything else is one InputError naming ``source`` (the option, URL parameter or field the
    size came from) and the allowed range.
    """
    if isinstance(value, str):
        return parse_pair(value, source, low, high, form="WIDTHxHEIGHT", unit="pixels", example=example)
    else:
        try:
            pair = tuple(value)
        except TypeError:
            pair = ()
        if len(pair) != 2:
            raise InputError(f"must be WIDTHxHEIGHT in pixels, e.g. {example}, got {value!r}", source=source,
                             hint=f"use {low}..{high} pixels per side")
    return check_sides(pair[0], pair[1], source, low, high)


def check_raster(raster: Any, width: int | None, height: int | None, source: str, what: str = "the panel",
                 hint: str | None = None, *, max_bits: int | None = None,
                 error: type[InputError] = ImageError) -> np.ndarray:
    """``raster`` as a C-contiguous ``(height, width, 3)`` RGB array: the one raster check.

    ``raster``: uint8 ``(H, W, 3)`` -- or uint16 when ``max_bits`` (the bits per channel of the
    display it goes to) is 10 or more; ``width``, ``height``: the size in pixels it must have
    (None: any size of at least 1 x 1); ``what`` names the panel it must fit, ``hint`` says what
    to do.  Anything else is one ``error`` (ImageError unless the caller's inputs are not images:
    a camera's ``shown`` raster is an InputError) naming ``source``.
    """
    try:
        array = np.asarray(raster)
    except (TypeError, ValueError):  # a ragged list, say
        array = None
    shape = getattr(array, "shape", None)
    dtype = getattr(array, "dtype", type(raster).__name__)
    if max_bits is not None and array is not None:  # a raster for a display of max_bits per channel
        if array.ndim != 3 or array.shape[2] != 3:
            raise error(f"is not an RGB image (shape {array.shape})", source=source,
                        hint="show an RGB raster made by 'lenticalib encode' or 'lenticalib patterns'")
        if array.dtype == np.uint16 and max_bits < 10:
            raise error(f"is 16-bit but the display shows {max_bits} bits per channel", source=source,
                        hint="show an 8-bit raster, or set the display to 10-bit colour")
        if array.dtype not in (np.uint8, np.uint16):
            raise error(f"has sample type {array.dtype}; the panel takes 8-bit (or 16-bit) integers", source=source)
    elif (array is None or array.dtype != np.uint8 or array.ndim != 3 or array.shape[2] != 3
          or array.shape[0] < 1 or array.shape[1] < 1):
        raise error(f"a raster must be 8-bit RGB (H, W, 3), got {dtype} {shape}", source=source, hint=hint)
    if width is not None and height is not None:
        check_raster_size((array.shape[1], array.shape[0]), (width, height), source, what, hint, error=error)
    return np.ascontiguousarray(array)


def check_raster_size(size: tuple[int, int], expected_size: tuple[int, int], source: str, what: str,
                      hint: str | None = None, *, error: type[InputError] = ImageError) -> None:
    """``error`` (ImageError) naming ``source`` when an image of ``size`` (W, H) is not
    ``expected_size`` (W, H), the size of ``what`` (e.g. "the simulated panel")."""
    if tuple(size) != tuple(expected_size):
        raise error(f"is {size[0]}x{size[1]} pixels, {what} is {expected_size[0]}x{expected_size[1]}",
                         source=source, hint=hint or f"give a {expected_size[0]}x{expected_size[1]} image")
