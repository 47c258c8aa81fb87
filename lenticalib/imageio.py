"""Reading and writing images as RGB numpy arrays, with clear errors and atomic writes.

Arrays are ``(H, W, 3)`` RGB in uint8, uint16 or float32 (OpenCV's BGR order is converted
at this boundary only).  Grey images are expanded to RGB; an alpha channel is dropped.
"""

from __future__ import annotations

import io
import os
from pathlib import Path

import numpy as np

from .atomic import write_bytes_atomic
from .errors import ImageError

IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".tif", ".tiff", ".bmp", ".webp", ".npy")
WRITE_FORMATS = {".png": (np.uint8, np.uint16), ".tif": (np.uint8, np.uint16, np.float32),
                 ".tiff": (np.uint8, np.uint16, np.float32), ".npy": None}


def read_image(path: str | os.PathLike, *, camera_orientation: bool = False) -> np.ndarray:
    """Read an image file as ``(H, W, 3)`` RGB (uint8, uint16 or float32).  ``.npy`` is loaded as is.

    ``camera_orientation``: turn the image as its EXIF orientation says (camera photos).
    """
    import cv2

    p = Path(path)
    if not p.exists():
        raise ImageError("no such file", source=str(p), hint="check the path")
    if p.is_dir():
        raise ImageError("is a folder, not an image", source=str(p))
    if p.suffix.lower() == ".npy":
        try:
            img = np.load(p, allow_pickle=False)
        except (OSError, ValueError) as exc:
            raise ImageError(f"cannot read array: {exc}", source=str(p)) from None
    else:
        try:
            data = np.fromfile(p, dtype=np.uint8)
        except OSError as exc:
            raise ImageError(f"cannot read: {exc.strerror}", source=str(p)) from None
        flags = cv2.IMREAD_COLOR | cv2.IMREAD_ANYDEPTH if camera_orientation else cv2.IMREAD_UNCHANGED
        img = cv2.imdecode(data, flags) if data.size else None
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
    return np.ascontiguousarray(img)


def write_image(path: str | os.PathLike, image: np.ndarray) -> Path:
    """Write ``(H, W, 3)`` RGB atomically; the format follows the suffix (.png, .tif, .npy)."""
    import cv2

    p = Path(path)
    suffix = p.suffix.lower()
    if suffix not in WRITE_FORMATS:
        raise ImageError(f"cannot write {suffix or 'files without a suffix'}", source=str(p),
                         hint="name the output .png, .tif or .npy")
    allowed = WRITE_FORMATS[suffix]
    if suffix == ".npy":
        buf = io.BytesIO()
        np.save(buf, image, allow_pickle=False)
        return write_bytes_atomic(p, buf.getvalue())
    if image.dtype == np.float64:
        image = image.astype(np.float32)
    if image.dtype.type not in allowed:
        raise ImageError(f"{suffix} cannot hold {image.dtype} pixels", source=str(p),
                         hint="write float rasters as .tif or .npy")
    ok, encoded = cv2.imencode(suffix, np.ascontiguousarray(image[:, :, ::-1]))
    if not ok:
        raise ImageError("image encoding failed", source=str(p))
    return write_bytes_atomic(p, encoded.tobytes())
