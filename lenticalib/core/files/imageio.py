"""Reading and writing images as RGB numpy arrays, with clear errors and atomic writes.

Arrays are ``(H, W, 3)`` RGB in uint8, uint16 or float32 (OpenCV's BGR order is converted
at this boundary only).  Grey images are expanded to RGB; an alpha channel is dropped.

SIZE LIMIT.  An image is refused before decoding when its header states more than
:data:`MAX_IMAGE_PIXELS` (16384 x 16384, 268 megapixels: :data:`lenticalib.core.sizes.MAX_SIDE`
squared, the largest raster 'lenticalib patterns' writes, and above any camera photo, 100-150
megapixels for medium format): the size is read from the header (Pillow reads it without
decoding; an ``.npy``'s from its header), so a small file claiming a huge image costs no memory.  The error names the file, its size and the limit.
A file Pillow does not recognise is left to OpenCV, whose own limit is 2^30 pixels.

OpenCV is imported through :func:`cv2_quiet`, which silences OpenCV's own logging once: its
``[ WARN ... ]`` lines about a corrupt file would otherwise reach stderr beside our one-line
error.  Output paths are checked before the work with :func:`check_image_output`.
"""

from __future__ import annotations

import dataclasses
import io
import os
import struct
from pathlib import Path

import numpy as np

from .atomic import write_bytes_atomic
from ..errors import ImageError, InputError
from .input_files import check_input, open_input
from .outputs import Inputs, check_output_file
from ..sizes import MAX_SIDE, check_raster_size

MAX_IMAGE_PIXELS = MAX_SIDE * MAX_SIDE  # module docstring; the largest raster of :mod:`.sizes`
MAX_IMAGE_FILE_BYTES = 4 << 30  # an image file: 16384 x 16384 RGB float32 uncompressed is 3 GiB
IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".tif", ".tiff", ".bmp", ".webp", ".npy")
WRITE_FORMATS = {".png": (np.uint8, np.uint16), ".tif": (np.uint8, np.uint16, np.float32),
                 ".tiff": (np.uint8, np.uint16, np.float32), ".npy": None}


def cv2_quiet():
    """The ``cv2`` module, with OpenCV's logging turned off (errors are reported by lenticalib)."""
    import cv2

    global _CV2_SILENCED
    if not _CV2_SILENCED:
        cv2.utils.logging.setLogLevel(cv2.utils.logging.LOG_LEVEL_SILENT)
        _CV2_SILENCED = True
    return cv2


_CV2_SILENCED = False


def open_image_header(path: str | os.PathLike):
    """``path`` opened lazily by Pillow: size, mode and metadata read, no pixel decoded; or None
    when no Pillow plugin recognises the file.  The caller closes it.

    Pillow's own decompression-bomb check is not applied: its limit (179 megapixels) is below
    :data:`MAX_IMAGE_PIXELS`, which :func:`check_image_pixels` enforces instead.  OSError when
    the file cannot be read.  An empty or cut file that a plugin's check trips over is None too.
    """
    from PIL import Image

    with open_input(path, "image", MAX_IMAGE_FILE_BYTES, "give an image file", ImageError) as fh:  # no FIFO
        prefix = fh.read(16)
    Image.init()
    for fmt in Image.ID:  # Image.open's loop, without the bomb check
        factory, accept = Image.OPEN[fmt]
        try:
            result = not accept or accept(prefix)
        except (IndexError, ValueError, struct.error):  # a check that reads past a short prefix (BMP's)
            continue
        if not result or isinstance(result, str):
            continue
        try:
            return factory(os.fspath(path))
        except (SyntaxError, IndexError, TypeError, ValueError, EOFError, OSError, struct.error):
            continue
    return None


def check_image_pixels(width: int, height: int, source: str) -> None:
    """ImageError naming ``source`` when a ``width`` x ``height`` image exceeds :data:`MAX_IMAGE_PIXELS`."""
    if width * height > MAX_IMAGE_PIXELS:
        raise ImageError(f"is {width}x{height} pixels ({width * height / 1e6:.0f} megapixels), over the limit of "
                         f"{MAX_IMAGE_PIXELS / 1e6:.0f} megapixels ({int(MAX_IMAGE_PIXELS ** 0.5)} x "
                         f"{int(MAX_IMAGE_PIXELS ** 0.5)})", source=source,
                         hint=f"scale the image down; lenticalib reads images of up to {MAX_SIDE} x {MAX_SIDE} pixels")


GREY_MODES = frozenset({"1", "L", "LA", "I", "I;16", "I;16B", "I;16L", "I;16N", "F"})  # Pillow's one-channel modes


@dataclasses.dataclass(frozen=True)
class ImageHeader:
    """What an image's header states: ``size`` (width, height), and whether it is ``grey`` (one channel)."""

    size: tuple[int, int]
    grey: bool


def read_header(path: str | os.PathLike, *, camera_orientation: bool = False) -> ImageHeader | None:
    """The :class:`ImageHeader` of an image, no pixel decoded; None when no Pillow plugin recognises
    the file or it cannot be read, empty or cut short (:func:`read_image` then reports it).

    ``camera_orientation``: the size after the turn its EXIF orientation asks for (JPEG photos).
    ImageError when the header states more than :data:`MAX_IMAGE_PIXELS`.
    """
    try:
        img = open_image_header(path)
    except OSError:
        return None
    if img is None:
        return None
    with img:
        width, height = img.size
        check_image_pixels(width, height, str(path))
        turned = camera_orientation and img.format == "JPEG" and img.getexif().get(0x0112, 1) in (5, 6, 7, 8)
        return ImageHeader((height, width) if turned else (width, height), img.mode in GREY_MODES)


def header_size(path: str | os.PathLike, *, camera_orientation: bool = False) -> tuple[int, int] | None:
    """``(width, height)`` of an image as its header states it (:func:`read_header`); None where it
    cannot be read."""
    header = read_header(path, camera_orientation=camera_orientation)
    return None if header is None else header.size


def _check_header(p: Path, camera_orientation: bool, expected_size: tuple[int, int] | None, what: str,
                  hint: str | None) -> None:
    """Refuse, before decoding, an image over :data:`MAX_IMAGE_PIXELS` or not of ``expected_size``."""
    size = header_size(p, camera_orientation=camera_orientation)
    if size is not None and expected_size is not None:
        check_raster_size(size, expected_size, str(p), what, hint)


def check_image_output(path: str | os.PathLike, dtype=None, what: str = "output image", *, inputs: Inputs,
                       example: str = "image.png") -> Path:
    """Refuse, before any work, an image path that :func:`write_image` could not write.

    Checks the path itself (:func:`lenticalib.core.files.outputs.check_output_file`: not a folder, parent
    folder existing and writable, not one of the command's ``inputs``), the suffix (``.png``,
    ``.tif``, ``.tiff``, ``.npy``) and that ``dtype`` (when given) fits that format.  Returns the path.
    ``example``: the file name (with a suffix it takes) a hint suggests inside a folder given by mistake.
    """
    p = check_output_file(path, what, example, inputs=inputs)
    suffix = p.suffix.lower()
    if suffix not in WRITE_FORMATS:
        raise ImageError(f"cannot write {suffix or 'files without a suffix'}", source=str(p),
                         hint="name the output .png, .tif or .npy")
    allowed = WRITE_FORMATS[suffix]
    if dtype is not None and allowed is not None:
        dtype = np.dtype(dtype)
        if dtype == np.float64:
            dtype = np.dtype(np.float32)
        if dtype.type not in allowed:
            raise ImageError(f"{suffix} cannot hold {dtype} pixels", source=str(p),
                             hint="write float rasters as .tif or .npy")
    return p


def read_image(path: str | os.PathLike, *, camera_orientation: bool = False,
               expected_size: tuple[int, int] | None = None, what: str = "the expected size",
               hint: str | None = None) -> np.ndarray:
    """Read an image file as ``(H, W, 3)`` RGB (uint8, uint16 or float32).  ``.npy`` is loaded as is.

    ``camera_orientation``: turn the image as its EXIF orientation says (camera photos).
    ``expected_size``: ``(W, H)`` the image must have, checked from the header before any pixel
    is decoded (so a wrong, huge image costs no memory); ``what`` names that size in the
    message (e.g. ``"the panel"``), ``hint`` what to do (default: give an image of that size).
    """
    cv2 = cv2_quiet()
    p = Path(path)
    if not p.exists():
        raise ImageError("no such file", source=str(p), hint="check the path")
    if p.is_dir():
        raise ImageError("is a folder, not an image", source=str(p), hint="give an image file")
    check_input(p, "image", MAX_IMAGE_FILE_BYTES, "give an image file", ImageError)  # a FIFO or device: at once
    if p.suffix.lower() == ".npy":
        from .arrayfile import load_npy

        def pixels(header):
            if len(header.shape) in (2, 3):
                check_image_pixels(header.shape[1], header.shape[0], str(p))
                if expected_size is not None:
                    check_raster_size((header.shape[1], header.shape[0]), expected_size, str(p), what, hint)

        try:
            img = load_npy(p, check=pixels, source=str(p))
        except ImageError:
            raise
        except InputError as exc:
            raise ImageError(exc.message, source=str(p), hint=exc.hint) from None
    else:
        try:
            data = np.fromfile(p, dtype=np.uint8)
        except OSError as exc:
            raise ImageError(f"cannot read: {exc.strerror}", source=str(p)) from None
        flags = cv2.IMREAD_COLOR | cv2.IMREAD_ANYDEPTH if camera_orientation else cv2.IMREAD_UNCHANGED
        if not data.size:
            raise ImageError("is empty (0 bytes), not an image", source=str(p), hint="use PNG, TIFF or JPEG")
        _check_header(p, camera_orientation, expected_size, what, hint)
        try:
            img = cv2.imdecode(data, flags)
        except cv2.error:  # e.g. a header promising more pixels than OpenCV accepts
            img = None
        if img is None:
            raise ImageError("not a readable image (corrupt or unsupported format)", source=str(p),
                             hint="use PNG, TIFF or JPEG")
        if img.ndim == 3 and img.shape[2] == 4:
            img = img[:, :, :3]
        if img.ndim == 3 and img.shape[2] == 3:
            img = img[:, :, ::-1]
    if img.ndim == 2:
        img = np.repeat(img[:, :, None], 3, axis=2)
    if img.ndim != 3 or img.shape[2] not in (3, 4):
        raise ImageError(f"expected an RGB image, got an array of shape {img.shape}", source=str(p))
    img = img[:, :, :3]
    if img.dtype == np.float64:
        img = img.astype(np.float32)
    if img.dtype not in (np.uint8, np.uint16, np.float32):
        raise ImageError(f"unsupported pixel type {img.dtype}", source=str(p),
                         hint="use 8- or 16-bit integer or 32-bit float images")
    if expected_size is not None:  # formats Pillow does not know, or a header that lied
        check_raster_size((img.shape[1], img.shape[0]), expected_size, str(p), what, hint)
    return np.ascontiguousarray(img)


def write_image(path: str | os.PathLike, image: np.ndarray) -> Path:
    """Write ``(H, W, 3)`` RGB atomically; the format follows the suffix (.png, .tif, .npy)."""
    cv2 = cv2_quiet()
    p = check_image_output(path, image.dtype, inputs=())  # the command checked its inputs before the work
    suffix = p.suffix.lower()
    if suffix == ".npy":
        buf = io.BytesIO()
        np.save(buf, image, allow_pickle=False)
        return write_bytes_atomic(p, buf.getvalue())
    if image.dtype == np.float64:
        image = image.astype(np.float32)
    ok, encoded = cv2.imencode(suffix, np.ascontiguousarray(image[:, :, ::-1]))
    if not ok:
        raise ImageError("image encoding failed", source=str(p))
    return write_bytes_atomic(p, encoded.tobytes())
