"""The ``student:`` control source: a student driver predicting the avatar's controls live.

    student:PATH?camera=K          frames of camera K (OpenCV index 0..MAX_CAMERA_INDEX), the newest one each time
    student:PATH?video=FILE        a video played in real time (looping), as if it were a camera
    ...&device=cuda                the network on a GPU (default cpu)

The spec is split, not URL-decoded: PATH is everything before the first ``?``, options are
separated by ``&`` and each is ``NAME=VALUE`` taken literally (``video=clip+1.avi`` opens
``clip+1.avi``; ``%20`` is three characters), so a video whose path holds ``&`` cannot be named
here (link it under another name).  An option given twice, an unknown one or an empty value is
refused.  The camera index is ASCII digits, 0..:data:`MAX_CAMERA_INDEX` (99): OpenCV reads an
index of 100 or more as a backend choice (200 + K: camera K through V4L2) and a negative one as
"any camera", and some of its backends crash on such indices, so they never reach it.

:meth:`StudentControls.latest` predicts from the newest frame the grabbing thread delivered, so
its time is the student's (crop and network): the live loop counts it in its drive stage.  When
no new frame came since the last call (a camera slower than the loop, or one that stopped
delivering) the last controls are repeated, never waited for; each such stretch is reported once
as a warning (:meth:`take_warnings`) and counted in :meth:`summary`.  Every problem with the
spec, the student file, its layout, the camera or the video is one InputError naming
``controls`` before the first frame.
"""

from __future__ import annotations

import numpy as np

from ...core.errors import InputError
from ...core.files.fields import short_repr
from .frames import MAX_CAMERA_INDEX, CameraFrames
from .predict import StudentPredictor
from .student_file import load_student

PREFIX = "student:"
HINT = "use student:student.pt?camera=0 or student:student.pt?video=FILE"


def parse_student_spec(spec: str) -> tuple[str, dict]:
    """(student path, {"camera": int} or {"video": path}, plus "device") from a ``student:`` spec
    (module docstring: split at the first '?', then at '&' and '=', nothing decoded)."""
    body = spec[len(PREFIX):]
    path, _, query = body.partition("?")
    params: dict[str, str] = {}
    for item in query.split("&") if query else ():
        name, equals, value = item.partition("=")
        if name not in ("camera", "video", "device"):
            raise InputError(f"bad student source: unknown option {short_repr(name)}", source="controls", hint=HINT)
        if not equals or not value:
            raise InputError(f"bad student source: option {name!r} has no value", source="controls", hint=HINT)
        if name in params:
            raise InputError(f"bad student source: option {name!r} is given twice", source="controls", hint=HINT)
        params[name] = value
    if not path or ("camera" in params) == ("video" in params):
        raise InputError(f"bad student source {short_repr(spec, 60)}: give the student file and one of camera= "
                         "and video=", source="controls", hint=HINT)
    out = {"device": params.get("device", "cpu")}
    if "camera" in params:
        text = params["camera"]
        if not (text.isascii() and text.isdigit() and len(text) <= len(str(MAX_CAMERA_INDEX)) and int(text) <= MAX_CAMERA_INDEX):
            raise InputError(f"camera {short_repr(text)} is not a camera index 0..{MAX_CAMERA_INDEX}",
                             source="controls", hint=HINT)
        out["camera"] = int(text)
    else:
        out["video"] = params["video"]
    return path, out


class StudentControls:
    """A live control source (``latest(now)``, ``close()``, ``summary()``, ``take_warnings()``)."""

    def __init__(self, spec: str, layout):
        path, params = parse_student_spec(spec)
        try:
            student = load_student(path)
            student.check_layout(layout, path)
            self.predictor = StudentPredictor(student, params["device"])
        except InputError as exc:
            raise InputError(f"{exc.source}: {exc.message}", source="controls", hint=exc.hint) from None
        self.layout = layout
        self.frames = CameraFrames(params.get("camera", params.get("video")))
        self._last_number = -1
        self._controls = student.mean.copy()
        self.predicted = 0
        self.repeated = 0
        self._stalled = False
        self._warnings: list[str] = []
        self.ms = []

    def latest(self, now: float = 0.0) -> tuple[float, np.ndarray]:
        number, rgb = self.frames.latest()
        if number == self._last_number:
            self.repeated += 1
            if not self._stalled:
                self._stalled = True
                self._warnings.append(f"the {'video' if self.frames.is_video else 'camera'} delivered no new frame: "
                                      "repeating the last controls")
            return float(now), self._controls.copy()
        self._stalled = False
        self._last_number = number
        self._controls = self.predictor.predict(rgb)
        self.predicted += 1
        self.ms.append(1e3 * self.predictor.seconds)
        return float(now), self._controls.copy()

    def take_warnings(self) -> list[str]:
        out, self._warnings = self._warnings, []
        return out

    def close(self) -> None:
        self.frames.close()

    def summary(self) -> str:
        ms = f", {np.median(self.ms):.1f} ms a prediction (median)" if self.ms else ""
        return (f"student: {self.predicted} frames predicted{ms}, {self.repeated} loop frames repeated the last "
                f"controls (no new camera frame), {self.frames.failures} camera reads failed")


def open_student_source(spec: str, layout, names=None) -> StudentControls:
    """The ``student`` control source (:mod:`lenticalib.render.controls.sources`): ``spec`` is
    ``student:PATH?camera=K|video=FILE[&device=D]``."""
    return StudentControls(spec, layout)
