"""A student driver at work: frames in, controls out.

:class:`StudentPredictor` turns one RGB frame into a control vector (D,) float32 in the rig's
units: the crop rule applied (a tracker keeps its state from frame to frame), the network run on
CPU or GPU, the output de-normalised with the subject's statistics (components that did not vary
in training are their mean).  :func:`predict_controls` runs it over a video or a folder and writes
the controls as a CSV that ``--controls`` reads (:func:`~lenticalib.render.controls.records.write_controls_csv`).
"""

from __future__ import annotations

import os
import re
import time

import numpy as np

from ...core.errors import InputError
from ...core.files.fields import short_repr
from ...core.files.outputs import check_output_file
from ..controls.records import write_controls_csv
from .crop import CropTracker, to_input
from .frames import open_frames
from .student_file import Student, load_student


class StudentPredictor:
    """``predict(rgb)`` -> controls (D,) float32; ``seconds`` of the last prediction (crop + network)."""

    def __init__(self, student: Student, device: str = "cpu"):
        import torch

        from ..gpu.torch_devices import device_unavailable

        # a student runs on the CPU or a CUDA GPU: 'meta', 'mps' or 'cpu:1' would fail at the first frame
        if not re.fullmatch(r"cpu|cuda(:[0-9]{1,2})?", str(device)):
            raise InputError(f"{short_repr(device)} is not cpu, cuda or cuda:K", source="device",
                             hint="use cpu, or a CUDA device torch can see")
        why = device_unavailable(device)
        if why:
            raise InputError(why, source="device", hint="use cpu, or a CUDA device torch can see")
        self.student = student
        self.device = torch.device(device)
        self.network = student.network.to(self.device).eval()
        self.tracker = CropTracker(student.crop)
        self.seconds = 0.0

    def predict(self, rgb: np.ndarray) -> np.ndarray:
        import torch

        start = time.perf_counter()
        x = torch.from_numpy(to_input(rgb, self.tracker.box(rgb), self.student.input_size))[None].to(self.device)
        with torch.inference_mode():
            out = self.network(x)[0].float().cpu().numpy()
        s = self.student
        self.seconds = time.perf_counter() - start
        return (s.mean + s.std * out * s.active).astype(np.float32)


def predict_controls(student: str | os.PathLike, frames: str | os.PathLike, output: str | os.PathLike, *,
                     device: str = "cpu", step=None) -> dict:
    """Predict every frame of ``frames`` with the student in ``student`` and write ``output`` (CSV);
    returns {"frames", "output", "ms_per_frame" (median), "seconds"}."""
    start = time.perf_counter()
    output = check_output_file(output, "control file", example="controls.csv", inputs=(student, frames))
    if not str(output).lower().endswith(".csv"):
        raise InputError("the predicted controls are written as CSV", source=str(output), hint="name it *.csv")
    loaded = load_student(student)
    source = open_frames(frames)
    predictor = StudentPredictor(loaded, device)
    t, rows, ms = [], [], []
    for k, time_s, rgb in source:
        rows.append(predictor.predict(rgb))
        t.append(time_s)
        ms.append(1e3 * predictor.seconds)
        if step is not None:
            step()
    write_controls_csv(output, np.asarray(t), np.stack(rows), loaded.layout, loaded.control_names)
    return {"frames": len(rows), "output": str(output), "ms_per_frame": float(np.median(ms)),
            "seconds": time.perf_counter() - start}
