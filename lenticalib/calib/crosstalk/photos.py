"""Reading the crosstalk photos: linear light at working resolution, the panel's lit area,
registration on its outline, and the camera's tone curve from the black, white and half photos
(:mod:`.tone`; ``docs/crosstalk.md``).

Frames: photo pixels -> working pixels (area-averaged by an integer factor so that the working
image is about ``WORKING_WIDTH`` pixels across).  Light: linear, R + G + B.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ...core.colour import srgb_decode
from ...core.errors import CaptureError
from ...core.files.imageio import read_header, read_image
from . import dark, tiles, tone
from .photometry import lit_region, working

WORKING_WIDTH = 1000  # working pixels across (about)
MAX_CLIPPED = 0.02
MAX_SHIFT = 3.0  # working pixels: a larger, clearly measured shift is a moved camera


def linear_channels(raw: np.ndarray, mode: str, path: Path, lut: np.ndarray | None = None
                    ) -> tuple[np.ndarray, np.ndarray]:
    """(float32 (h, w, 3) linear light per channel, bool (h, w) clipped) of one photo; ``lut``
    (float32 (256,)): the light of each 8-bit code of an "srgb" photo (the camera's measured tone
    curve, :mod:`.tone`), plain sRGB decoding when None."""
    if raw.ndim != 3 or raw.shape[2] < 3:
        raise CaptureError("is not an RGB photo", source=str(path), hint="save the photos in colour")
    raw = raw[:, :, :3]
    if raw.dtype == np.uint8:
        if mode == "linear":
            lut = np.arange(256, dtype=np.float32) / np.float32(255.0)
        elif lut is None:
            lut = tone.decode_lut()
        return lut[raw], raw.max(axis=2) >= 250
    top = 65535.0 if raw.dtype == np.uint16 else 1.0
    value = raw.astype(np.float32) / np.float32(top)
    linear = value if mode == "linear" else srgb_decode(value).astype(np.float32)
    return linear, value.max(axis=2) >= 250 / 255


def load_all(capture, pattern_set, mode, progress, lut=None):
    """Working-resolution linear luma of every photo, the white photo's clipped map, factor and the
    channels' noise sigma where the camera clips dark pixels at 0 (None: it does not; measured on
    the black photo, read first, and undone in every photo: :mod:`.dark`) (``lut``: the tone curve
    of 8-bit "srgb" photos, :func:`linear_channels`)."""
    from ..patterns.capture_sets import check_photo_size

    luma: dict[str, np.ndarray] = {}
    clipped = None
    size = None
    factor = 1
    noise = None
    names = ["black"] + [p.name for p in pattern_set.patterns if p.name != "black"]
    _check_headers(capture, names)
    kind = None
    for name in names:
        path = capture.photo(name)
        raw = read_image(path, camera_orientation=True)
        h, w = raw.shape[:2]
        if size is None:
            check_photo_size(path, w, h)
            size = (w, h)
            factor = max(1, int(round(w / WORKING_WIDTH)))
        elif (w, h) != size:
            raise CaptureError(f"is {w}x{h} pixels, the other photos {size[0]}x{size[1]}", source=str(path),
                               hint="take every photo of the set with the same camera settings, without cropping")
        this = _encoding_kind(raw)
        if kind is None:
            kind = this
            if mode == "linear" and raw.dtype == np.uint8:
                raise CaptureError("is an 8-bit photo, but `photos` linear is for 16-bit linear light from a raw "
                                   "converter", source=str(path),
                                   hint="measure camera JPEGs with `photos` srgb (the default), or convert the RAW "
                                        "files to 16-bit linear TIFF/PNG (dcraw -4 -T, rawpy, darktable)")
        elif this != kind:
            raise CaptureError(f"is {this}, the photo of {names[0]} {kind}", source=str(path),
                               hint="take every photo of the set the same way: all camera JPEGs, or all 16-bit from "
                                    "the same raw converter settings")
        channels, clip = linear_channels(raw, mode, path, lut)
        if name == "black":
            noise = dark.clipping_noise(channels, raw[:, :, :3] == 0)
        if noise is not None:
            channels = dark.unclip(channels, noise)
        luma[name] = working(channels.sum(axis=2, dtype=np.float32), factor)
        if name == "white":
            clipped = working(clip.astype(np.float32), factor)
        if progress:
            progress(f"read {path.name}")
    return luma, clipped, factor, noise


def _check_headers(capture, names: list[str]) -> None:
    """CaptureError naming a photo whose header states another size, or another colour (greyscale
    against colour), than the photo of ``names[0]``: before any photo is decoded."""
    headers = {name: read_header(capture.photo(name), camera_orientation=True) for name in names}
    first = headers[names[0]]
    words = {True: "greyscale", False: "colour"}
    for name, header in headers.items():  # a photo of another size or colour is named before any is decoded
        if first is None or header is None:
            continue  # unreadable: read_image names it
        if header.size != first.size:
            raise CaptureError(f"is {header.size[0]}x{header.size[1]} pixels, the photo of {names[0]} "
                               f"{first.size[0]}x{first.size[1]}", source=str(capture.photo(name)),
                               hint="take every photo of the set with the same camera settings, without cropping")
        if header.grey != first.grey:
            raise CaptureError(f"is a {words[header.grey]} photo, the photo of {names[0]} {words[first.grey]}",
                               source=str(capture.photo(name)),
                               hint="take every photo of the set in colour (R + G + B is what is measured)")


def _encoding_kind(raw: np.ndarray) -> str:
    """A photo's sample type in words ("8-bit", "16-bit", "float32")."""
    return {np.dtype(np.uint8): "8-bit", np.dtype(np.uint16): "16-bit"}.get(raw.dtype, str(raw.dtype))


HALF_LEVEL = "level-1in2"  # lights one panel row in two: half of white's light above black, in linear light
LINEAR_SHARE = (0.35, 0.62)  # its share of white's light as measured: below, photos decoded twice; above, not at all


def check_encoding(luma: dict[str, np.ndarray], mask: np.ndarray, mode: str, capture) -> None:
    """CaptureError, before the long work, when the photos are not encoded as ``mode`` says: the
    1-in-2 level photo holds half of white's light above black in linear light (demosaicing of
    resolved rows leaves it a few per cent short); linear photos decoded as sRGB put it near 0.2,
    sRGB-encoded photos taken as linear near 0.73.  Sets without the level photos are not checked."""
    if HALF_LEVEL not in luma:
        return
    lit = float(np.sum((luma["white"] - luma["black"])[mask]))
    if not lit > 0:
        return
    share = float(np.sum((luma[HALF_LEVEL] - luma["black"])[mask])) / lit
    if share < LINEAR_SHARE[0] and mode == "srgb":
        raise CaptureError(f"holds {share:.2f} of white's light after sRGB decoding where it must hold 0.5: the photos "
                           "are linear already", source=str(capture.photo(HALF_LEVEL)),
                           hint="measure 16-bit photos from a raw converter with `photos` linear")
    if share > LINEAR_SHARE[1]:
        raise CaptureError(f"holds {share:.2f} of white's light {'as linear light' if mode == 'linear' else 'decoded'}"
                           " where it must hold 0.5: the photos are not encoded as "
                           f"`photos` {mode} says", source=str(capture.photo(HALF_LEVEL)),
                           hint="camera JPEGs and sRGB-encoded photos: `photos` srgb (the default); 16-bit linear "
                                "from a raw converter: `photos` linear" if mode == "linear" else
                                "photograph the set again with the exposure locked, every pattern full screen")


def panel_mask(lit: np.ndarray, white_path: Path) -> np.ndarray:
    """bool: the panel's lit inside (where white clearly exceeds black), the largest blob, closed
    (:func:`.photometry.lit_region`); CaptureError naming the white photo where it is not a panel."""
    if not float(np.percentile(lit, 95)) > 0:
        raise CaptureError("is no brighter than the black photo", source=str(white_path),
                           hint="show white.png full screen on the panel and photograph it")
    mask = lit_region(lit)
    if mask is None:
        raise CaptureError("shows no panel", source=str(white_path), hint="show the patterns full screen")
    if mask.mean() < 0.05:
        raise CaptureError(f"the panel fills only {100 * mask.mean():.1f}% of the photo", source=str(white_path),
                           hint="fill most of the frame with the panel (the same camera position as the fit)")
    edge = np.concatenate([mask[0], mask[-1], mask[:, 0], mask[:, -1]])
    if edge.mean() > 0.02:
        raise CaptureError("the panel is cut off by the edge of the photo", source=str(white_path),
                           hint="step back or zoom out so the whole panel is inside every photo")
    return mask > 0


def register_photos(luma, names, photos, lit, frame_fraction, warnings):
    """Undo shake: every photo aligned to white on the panel outline; CaptureError for a moved camera."""
    from ..patterns import register

    reference = register.Reference.from_mean_image(luma["white"], lit.astype(np.complex64), frame_fraction)
    if reference is None:
        warnings.append("camera motion between photos could not be measured; it is not corrected")
        return {}
    shifts = {}
    for name in names:
        if name == "white":
            continue
        shift = reference.measure(luma[name])
        shifts[name] = {"dx": shift.dx, "dy": shift.dy, "measured": shift.measured}
        if not shift.measured:
            warnings.append(f"camera motion of {photos[name].name} could not be measured ({shift.note})")
            continue
        if shift.size > MAX_SHIFT and shift.size > 5 * shift.sigma and shift.improvement > 0.5:
            raise CaptureError(f"the camera moved: this photo is shifted by {shift.size:.1f} working pixels against "
                               "white", source=str(photos[name]),
                               hint="keep the camera still (tripod, remote release) and retake the set")
        luma[name] = register.shift_image(luma[name], shift.dx, shift.dy)
    return shifts


def measure_tone(capture, warnings: list[str]) -> tone.ToneCurve | None:
    """The camera's tone curve from the 8-bit black, white, half and level photos
    (:func:`.tone.fit_tone_curve`); None, with a warning, where they are not 8-bit or show too
    little to fit (the photos are then decoded as plain sRGB).  CaptureError naming the photo when
    the halves do not add up to white, or a level photo is not its share of white, under the
    fitted curve (photos of other patterns, a moved camera, a changed exposure)."""
    names = tone.PHOTOS + (tone.LEVELS if all(n in capture.patterns.names for n in tone.LEVELS) else ())
    images = {}
    for name in names:
        raw = read_image(capture.photo(name), camera_orientation=True)
        if raw.dtype != np.uint8 or raw.ndim != 3 or raw.shape[2] < 3:
            warnings.append("the photos are not 8-bit colour: decoded as plain sRGB, the tone curve not measured")
            return None
        images[name] = raw[:, :, :3]
    if len({v.shape for v in images.values()}) > 1:
        return None  # the photo-size check of load_all names the odd one
    curve = tone.fit_tone_curve(images, tiles.tile_size(images["white"].shape[1]))
    if curve is None:
        warnings.append("the black, white and half photos show too little to measure the camera's tone curve: the "
                        "photos are decoded as plain sRGB, and the uncertainty allows for a camera that is not")
        return None
    hint = "photograph every pattern of this folder in its own photo, with the camera still and the exposure locked"
    if curve.residual > tone.MAX_RESIDUAL:
        raise CaptureError(f"half-0 and half-1 do not add up to white (relative residual {curve.residual:.2f})",
                           source=str(capture.photo("half-0")), hint=hint)
    for name, residual in zip(tone.LEVELS, curve.level_residuals):
        if abs(residual) > tone.MAX_LEVEL_BIAS:
            k = name.rsplit("in", 1)[1]
            raise CaptureError(f"is not 1/{k} of white's light ({1 + residual:.2f} of it under the tone curve)",
                               source=str(capture.photo(name)), hint=hint)
    if not curve.levels:
        warnings.append("this pattern set has no level patterns (drawn by an older lenticalib): the camera's tone "
                        "curve is a power on sRGB fitted to the half photos alone; for JPEG photos write the patterns "
                        "again with 'lenticalib crosstalk patterns' (three more photos)")
    return curve
