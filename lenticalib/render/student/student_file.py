"""The saved student driver (``student.pt``): everything prediction needs, and where it came from.

A ``torch.save`` of plain data (read back with ``weights_only=True``: no pickled code):

    format, format_version   "lenticalib.student-driver", 1
    layout                   [[group, size], ...]: the control layout it predicts (a rig with
                             another layout refuses it)
    control_names            (D,) the components' names
    crop                     the crop rule (:mod:`.crop`)
    input_size               S: the network's input is S x S
    mean, std                (D,) float32 tensors: the teacher controls' statistics;
                             controls = mean + std * output
    active                   (D,) bool tensor: components that varied in training (the others
                             are their mean)
    group_weights            {group: weight} of the loss
    state_dict               the network's weights (:mod:`.model`)
    validation               per-group error on the held-out frames at the best epoch
    provenance               inputs (with SHA-256), options, epochs, seconds, lenticalib version
"""

from __future__ import annotations

import os

from ...core.atomic import write_bytes_atomic
from ...core.documents import FORMATS, check_envelope
from ...core.errors import InputError
from ..rig import ControlLayout

DOCUMENT = FORMATS["lenticalib.student-driver"]


class Student:
    """A loaded student: ``layout``, ``control_names``, ``crop``, ``input_size``, ``mean``, ``std``,
    ``active`` (numpy), ``network`` (eval mode, CPU), ``record`` (the whole file's dict)."""

    def __init__(self, record: dict, network):
        import numpy as np

        self.record = record
        self.layout = ControlLayout(tuple((str(g), int(s)) for g, s in record["layout"]))
        self.control_names = tuple(record["control_names"])
        self.crop = dict(record["crop"])
        self.input_size = int(record["input_size"])
        self.mean = record["mean"].numpy().astype(np.float32)
        self.std = record["std"].numpy().astype(np.float32)
        self.active = record["active"].numpy().astype(bool)
        self.network = network

    def check_layout(self, layout: ControlLayout, source: str) -> None:
        """InputError naming ``source`` when ``layout`` is not the one the student predicts."""
        if tuple(layout.groups) != tuple(self.layout.groups):
            raise InputError(f"the student predicts controls {self.layout.describe()}, the avatar takes "
                             f"{layout.describe()}", source=source,
                             hint="distil a student with this avatar's rig (its control layout)")


def save_student(path: str | os.PathLike, record: dict) -> None:
    """Write ``record`` (module docstring) atomically."""
    import io

    import torch

    buf = io.BytesIO()
    torch.save({**DOCUMENT.envelope(), **record}, buf)
    write_bytes_atomic(path, buf.getvalue())


def load_student(path: str | os.PathLike) -> Student:
    """The student in ``path``, its network built and loaded; one InputError naming the file."""
    import torch

    from .model import build_student

    source = str(path)
    if not os.path.isfile(path):
        raise InputError("no such student file", source=source, hint="make one with 'lenticalib driver distill'")
    try:
        record = torch.load(path, map_location="cpu", weights_only=True)
    except Exception as exc:  # torch raises RuntimeError, UnpicklingError, zipfile errors on a bad file
        raise InputError(f"not a student file torch can read ({type(exc).__name__})", source=source,
                         hint="make one with 'lenticalib driver distill'") from None
    check_envelope(record, DOCUMENT, source)
    missing = [k for k in ("layout", "control_names", "crop", "input_size", "mean", "std", "active", "state_dict")
               if k not in record]
    if missing:
        raise InputError(f"the student file lacks {', '.join(missing)}", source=source)
    dim = sum(int(s) for _, s in record["layout"])
    network = build_student(dim)
    try:
        network.load_state_dict(record["state_dict"])
    except RuntimeError:
        raise InputError("the student's weights do not fit its network", source=source) from None
    network.eval()
    return Student(record, network)
