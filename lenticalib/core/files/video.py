"""Opening a video file through OpenCV, bounded before any frame is decoded.

:func:`open_video` is the one place a video *file* reaches ``cv2.VideoCapture``: the path must
be a regular file of at most :data:`MAX_VIDEO_BYTES` (:func:`lenticalib.core.files.input_files.check_input`:
a FIFO, device or socket is refused at once instead of OpenCV waiting on it), and the frame size
and frame count its container states must be within the raster limits of :mod:`lenticalib.core.sizes`
(:data:`~lenticalib.core.sizes.MAX_SIDE` pixels a side, :data:`~lenticalib.core.files.imageio.MAX_IMAGE_PIXELS`
a frame) and :data:`MAX_VIDEO_FRAMES`, checked before the first frame is read, so a small file
claiming 100000 x 100000 frames costs no memory.  Sizes are (width, height) pixels; a container
that states no frame count (0) is let through (its frames are then counted as they are read).
"""

from __future__ import annotations

import os

from ..errors import InputError
from .imageio import check_image_pixels, cv2_quiet
from .input_files import GIB, check_input
from ..sizes import MAX_SIDE

MAX_VIDEO_BYTES = 64 * GIB  # a video file: two hours of 4K at 60 Mbit/s is some 55 GiB
MAX_VIDEO_FRAMES = 1_000_000  # frames a container may state: 9 hours at 30 fps
VIDEO_HINT = "give a video file (e.g. H.264 .mp4 or MJPEG .avi) or a folder of frames"


def open_video(path: str | os.PathLike, what: str = "video"):
    """A ``cv2.VideoCapture`` of the video file ``path``, opened, its stated frame size and count
    within the limits (module docstring); one InputError naming the file otherwise.  The caller
    releases it."""
    source = os.fspath(path)
    check_input(path, what, MAX_VIDEO_BYTES, VIDEO_HINT)
    cv2 = cv2_quiet()
    cap = cv2.VideoCapture(source)
    try:
        if not cap.isOpened():
            raise InputError(f"OpenCV cannot open or decode this {what}", source=source,
                             hint="convert it (e.g. to H.264 .mp4 or MJPEG .avi), or give a folder of frames")
        check_video_header(cap, source)
    except BaseException:
        cap.release()
        raise
    return cap


def check_video_header(cap, source: str) -> None:
    """InputError naming ``source`` when the frame size or frame count an opened
    ``cv2.VideoCapture`` states is beyond the limits (module docstring)."""
    import math

    cv2 = cv2_quiet()
    width, height = cap.get(cv2.CAP_PROP_FRAME_WIDTH), cap.get(cv2.CAP_PROP_FRAME_HEIGHT)
    count = cap.get(cv2.CAP_PROP_FRAME_COUNT)
    if not all(math.isfinite(v) for v in (width, height, count)):
        raise InputError("the video's header states no usable frame size or count", source=source, hint=VIDEO_HINT)
    width, height, count = int(width), int(height), int(count)
    if width > MAX_SIDE or height > MAX_SIDE:
        raise InputError(f"its frames are {width}x{height} pixels, more than {MAX_SIDE} a side", source=source,
                         hint=f"scale the video down; lenticalib reads frames of up to {MAX_SIDE} x {MAX_SIDE} pixels")
    check_image_pixels(width, height, source)
    if count > MAX_VIDEO_FRAMES:
        raise InputError(f"the video states {count} frames, more than the {MAX_VIDEO_FRAMES} any video here has",
                         source=source, hint="cut the video")
