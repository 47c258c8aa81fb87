"""Capture cameras: what ``lenticalib capture`` triggers after showing each test pattern.

    gphoto2    a still camera tethered over USB, through the gphoto2 program      gphoto2, gphoto2:PORT
    opencv     a webcam (UVC) or video stream through OpenCV                       opencv:0, opencv:/dev/video2
    manual     the user presses the shutter; photos arrive in a watched folder,    manual:/folder, manual
               or the user copies each one in place
    sim        the virtual panel of :mod:`lenticalib.sim` photographed by its      sim, sim:SEED
               virtual camera (writes truth.json and simulation.json as well)

Modules: ``base`` (the :class:`~.base.CaptureCamera` contract and the raster and timing checks
every kind shares), ``files`` (a photo put in place: the destination's suffix, atomic moves,
copies and writes), ``gphoto2``, ``opencv`` and ``manual`` (one kind each, as above).  Part of
the calib layer: imports only core and calib.

Every kind is a :class:`~.base.CaptureCamera`: ``open()``, ``settings()`` (what was locked and
what could not be), ``capture(name, shown, destination)`` (one photo, put in place atomically as
``destination`` + suffix), ``close()``; a context manager.  The kinds are a registry of
``"module:Class"`` strings on the package's one loader (:mod:`lenticalib.core.plugins`): a backend
module is imported only when a camera of its kind is made, and the backends import their heavy
dependencies (OpenCV, the simulator) only when a camera opens or captures.  The ``sim`` kind
lives in :mod:`lenticalib.sim.capture_backend` (the simulator sits above this layer; a name in the
table is not an import).  Third-party cameras register through the entry-point group
``lenticalib.capture_cameras`` (name = kind, value = ``module:Class``, a CaptureCamera subclass
constructed as ``Class(target, **options)``).

:func:`make_camera` turns a ``--camera`` spec into a camera without touching any hardware (to
check the argument before the work starts); :func:`open_camera` also opens it.
"""

from __future__ import annotations

from ....core.errors import InputError
from ....core.plugins import Registry
from .base import CaptureCamera

CAMERA_KINDS = Registry("camera kind", {
    "gphoto2": "lenticalib.calib.capture.cameras.gphoto2:Gphoto2Camera",
    "opencv": "lenticalib.calib.capture.cameras.opencv:OpenCVCamera",
    "manual": "lenticalib.calib.capture.cameras.manual:ManualCamera",
    "sim": "lenticalib.sim.capture_backend:SimCamera",
}, "lenticalib.capture_cameras", choices="choose one of {names} (e.g. `camera` opencv:0)")

__all__ = ["CAMERA_KINDS", "CaptureCamera", "make_camera", "open_camera", "parse_spec"]


def parse_spec(spec: str) -> tuple[str, str | None]:
    """``"KIND"`` or ``"KIND:TARGET"`` -> (kind, target or None), split at the first colon.

    InputError naming ``camera`` for an empty spec, an empty target or an unknown kind.
    """
    if not isinstance(spec, str) or not spec.strip():
        raise InputError(f"no camera given ({spec!r})", source="camera",
                         hint=f"choose one of {', '.join(CAMERA_KINDS.names())}")
    kind, colon, target = spec.strip().partition(":")
    kind = kind.strip().lower()
    CAMERA_KINDS.check(kind, "camera")
    if colon and not target.strip():
        raise InputError(f"nothing after the colon in {spec!r}", source="camera",
                         hint=f"write {kind} alone, or {kind}:TARGET")
    return kind, (target if colon else None)


def make_camera(spec: str, **options) -> CaptureCamera:
    """The camera a ``--camera`` spec names, constructed but not opened (no hardware is touched).

    ``options`` are the kind's keyword options (see each module); InputError for a bad spec or
    an option the kind does not take.
    """
    kind, target = parse_spec(spec)
    return CAMERA_KINDS.load(kind, "camera")(target, **options)


def open_camera(spec: str, **options) -> CaptureCamera:
    """:func:`make_camera`, then :meth:`~.base.CaptureCamera.open`: a connected camera.

    Use it as ``with open_camera("opencv:0") as camera: ...`` (entering an open camera does not
    open it again; leaving closes it).  CameraError if the camera cannot be opened.
    """
    camera = make_camera(spec, **options)
    camera.open()
    return camera
