"""Capture sets: one camera photo per test pattern in ``DIR/captures/NAME.{jpg,png,tif}``.

This module finds the photos, checks that they are exactly the ones the manifest asks for,
and loads them as *linear-light luminance* at a bounded working resolution.  Every problem
ends in an :class:`~lenticalib.core.errors.CaptureError` naming the photo and what to do.
"""

from __future__ import annotations

import dataclasses
import os
from pathlib import Path

import numpy as np

from ...core.colour import srgb_decode, srgb_decode_lut
from ...core.errors import CaptureError
from ...core.files.imageio import read_image
from .calibration_patterns import PatternSet, read_manifest

PHOTO_SUFFIXES = (".jpg", ".jpeg", ".png", ".tif", ".tiff")
MAX_WORKING_WIDTH = 2560  # photos wider than this are area-averaged down (linear light)
# The smallest photo the fit accepts (pixels, width x height); the simulator refuses to make
# smaller ones.  At 1 megapixel the panel (60-90 % of the frame) still gets ~4 camera pixels per
# fringe of group x2 (32 panel pixels); below that groups blur into each other.
MIN_PHOTO_PIXELS = 1_000_000
CLIP_LEVEL = 250 / 255  # sRGB-encoded value counted as clipped
IGNORED_NAMES = {"thumbs.db", "desktop.ini"}


@dataclasses.dataclass(frozen=True)
class CaptureSet:
    """A pattern folder with its manifest, the photo path of every pattern (by name) and the first
    photo's (width, height) in pixels as taken (EXIF orientation applied)."""

    directory: Path
    patterns: PatternSet
    photos: dict[str, Path]
    photo_size: tuple[int, int] | None = None

    def photo(self, name: str) -> Path:
        return self.photos[name]

    @property
    def inputs(self) -> list[Path]:
        return [self.directory / "patterns.json"] + [self.photos[n] for n in self.patterns.names]


def open_capture_set(directory: str | os.PathLike) -> CaptureSet:
    """Read ``DIR/patterns.json`` and match ``DIR/captures/*`` to it, one photo per pattern.

    Raises CaptureError for a missing folder, a missing photo, two photos of one pattern,
    a file whose name matches no pattern, or a first photo (in manifest order) smaller than
    MIN_PHOTO_PIXELS.  Hidden files are ignored.
    """
    directory = Path(directory)
    if not directory.is_dir():
        raise CaptureError("is not a folder", source=str(directory),
                           hint="give the folder 'lenticalib patterns' wrote, with the photos in captures/")
    return match_captures(directory, read_manifest(directory))


def match_captures(directory: Path, patterns) -> CaptureSet:
    """The photos of ``directory/captures`` matched to the patterns of ``patterns`` (any pattern
    set with ``names``); the checks of :func:`open_capture_set`."""
    folder = directory / "captures"
    if not folder.is_dir():
        raise CaptureError("no captures folder", source=str(folder),
                           hint="photograph every pattern and put the photos in DIR/captures/ named like "
                                "the patterns (x0-0.png -> captures/x0-0.jpg)")
    names = set(patterns.names)
    photos: dict[str, Path] = {}
    for path in sorted(folder.iterdir()):
        if path.name.startswith(".") or path.name.lower() in IGNORED_NAMES:
            continue
        stem, suffix = path.stem, path.suffix.lower()
        if suffix not in PHOTO_SUFFIXES or stem not in names:
            raise CaptureError("matches no pattern of this set", source=str(path),
                               hint=f"name each photo like its pattern ({patterns.names[0]}.jpg ...) with "
                                    f"suffix {', '.join(PHOTO_SUFFIXES)}; remove other files")
        if stem in photos:
            raise CaptureError(f"is a second photo of pattern {stem} (first: {photos[stem].name})",
                               source=str(path), hint="keep one photo per pattern")
        photos[stem] = path
    missing = [n for n in patterns.names if n not in photos]
    if missing:
        shown = ", ".join(missing[:6]) + (" ..." if len(missing) > 6 else "")
        raise CaptureError(f"{len(missing)} photo(s) missing: {shown}", source=str(folder),
                           hint=f"photograph pattern {missing[0]}.png and save it as "
                                f"captures/{missing[0]}.jpg (or .png/.tif)")
    first = photos[patterns.names[0]]
    raw = read_image(first, camera_orientation=True)
    check_photo_size(first, raw.shape[1], raw.shape[0])
    return CaptureSet(directory, patterns, photos, (int(raw.shape[1]), int(raw.shape[0])))


def check_photo_size(path: Path, width: int, height: int) -> None:
    """CaptureError naming ``path`` if a ``width`` x ``height`` photo is below MIN_PHOTO_PIXELS.

    :func:`open_capture_set` checks the set's first photo (so a set taken at too low a
    resolution is named by its first photo, before the long work); :func:`load_photo` checks
    every photo (so a single small one is named by its own name).
    """
    if width * height < MIN_PHOTO_PIXELS:
        raise CaptureError(f"is only {width}x{height} pixels ({width * height / 1e6:.2f} megapixels); the fit "
                           f"needs photos of at least {MIN_PHOTO_PIXELS / 1e6:g} megapixel", source=str(path),
                           hint="photograph every pattern at the camera's full resolution")


@dataclasses.dataclass
class Photo:
    """One loaded photo.

    ``luma``: float32 (h, w), linear light summed over R, G, B (0..3), at working resolution.
    ``rgb_mean``: float64 (3,), mean linear R, G, B over the frame.  ``clipped``: float32
    (h, w), fraction of clipped sensor pixels per working pixel.  ``scale``: working pixels
    per photo pixel (<= 1).  ``shape``: the photo's own (height, width).
    """

    name: str
    path: Path
    luma: np.ndarray
    rgb: np.ndarray | None
    clipped: np.ndarray
    scale: float
    shape: tuple[int, int]


_DECODE_LUT8 = None


def _linear_rgb(raw: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(linear float32 RGB, clipped float32 mask) of a raw photo; 8-bit through a lookup table."""
    global _DECODE_LUT8
    if raw.dtype == np.uint8:
        if _DECODE_LUT8 is None:
            _DECODE_LUT8 = srgb_decode_lut().astype(np.float32)
        clipped = (raw.max(axis=2) >= round(CLIP_LEVEL * 255)).astype(np.float32)
        return _DECODE_LUT8[raw], clipped
    scale = 65535.0 if raw.dtype == np.uint16 else 1.0
    encoded = raw.astype(np.float32) / np.float32(scale)
    clipped = (encoded.max(axis=2) >= CLIP_LEVEL).astype(np.float32)
    return srgb_decode(encoded).astype(np.float32), clipped


def load_photo(name: str, path: Path, keep_rgb: bool = False, max_width: int = MAX_WORKING_WIDTH) -> Photo:
    """Load, linearise (sRGB) and area-average one photo; CaptureError if it is unusable."""
    import cv2

    raw = read_image(path, camera_orientation=True)
    h, w = raw.shape[:2]
    check_photo_size(path, w, h)
    linear, clipped = _linear_rgb(raw)
    scale = min(1.0, max_width / w)
    if scale < 1.0:
        size = (max(1, round(w * scale)), max(1, round(h * scale)))
        linear = cv2.resize(linear, size, interpolation=cv2.INTER_AREA)
        clipped = cv2.resize(clipped, size, interpolation=cv2.INTER_AREA)
        scale = size[0] / w
    luma = linear.sum(axis=2, dtype=np.float32)
    return Photo(name, path, luma, linear if keep_rgb else None, clipped, scale, (h, w))


def check_exposure(photo: Photo) -> None:
    """CaptureError if the photo is black (nothing bright enough to measure)."""
    bright = float(np.percentile(photo.luma, 99.5))
    if bright < 0.02:
        raise CaptureError("is black or far too dark", source=str(photo.path),
                           hint="check that the pattern is on screen and expose so the panel is bright "
                                "but not clipped")
