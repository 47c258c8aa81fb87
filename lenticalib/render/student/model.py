"""The student network: MobileNetV3-Small features, global average pooling, a two-layer head.

Input float32 (B, 3, S, S), ImageNet-normalised crops (:func:`.crop.to_input`); output (B, D),
the normalised control vector ((controls - mean) / std per component, :mod:`.student_file`).
The backbone is torchvision's ``mobilenet_v3_small`` built without weights; its ``features``
take the user's weights file when given (a torchvision ``mobilenet_v3_small`` state dict, as
``torch.save(model.state_dict())`` writes it; never downloaded), and are trained from scratch
otherwise.  Head: Linear(576, HIDDEN), Hardswish, Dropout(DROPOUT), Linear(HIDDEN, D).

LIMITS.  The input side S is :data:`MIN_INPUT_SIZE`..:data:`MAX_INPUT_SIZE` pixels (224 is the
backbone's own; above 512 a batch of crops takes gigabytes and the features see no more of a
face); D is at most :data:`MAX_CONTROLS` (a rig's layouts hold tens to hundreds).  A weights file
is a torch zip checked from its central directory before torch inflates anything
(:data:`WEIGHTS_ZIP`: torchvision's mobilenet_v3_small state dict is 9.7 MiB in 250 members with
a 36 KiB pickle; a student file, :mod:`.student_file`, at most 9 MiB).
"""

from __future__ import annotations

import os

from ...core.files.arrayfile import MIB, ZipLimits, open_zip
from ...core.errors import InputError

MIN_INPUT_SIZE = 32
MAX_INPUT_SIZE = 512
MAX_CONTROLS = 4096  # components a student predicts: its head's last layer is 256 x D
# a torch file of MobileNetV3-Small weights (a backbone's, or a student's with its head): bytes
# inflated in all, entries, and bytes of its pickle (unpickled, 1 MiB of one-byte opcodes made 82 MiB of objects)
WEIGHTS_ZIP = ZipLimits(total=32 * MIB, members=1024, pickle=1 * MIB)

HIDDEN = 256
DROPOUT = 0.1
FEATURES = 576  # channels of mobilenet_v3_small's last feature map


def build_student(outputs: int, backbone_weights: str | os.PathLike | None = None):
    """The network (a torch ``nn.Module``) for ``outputs`` controls; ``backbone_weights`` a file of
    torchvision mobilenet_v3_small weights (InputError naming ``backbone_weights`` when it is not one)."""
    import torch
    import torchvision
    from torch import nn

    class Student(nn.Module):
        def __init__(self):
            super().__init__()
            self.features = torchvision.models.mobilenet_v3_small(weights=None).features
            self.pool = nn.AdaptiveAvgPool2d(1)
            self.head = nn.Sequential(nn.Linear(FEATURES, HIDDEN), nn.Hardswish(), nn.Dropout(DROPOUT),
                                      nn.Linear(HIDDEN, outputs))

        def forward(self, x):
            return self.head(torch.flatten(self.pool(self.features(x)), 1))

    if isinstance(outputs, bool) or not isinstance(outputs, int) or not 1 <= outputs <= MAX_CONTROLS:
        raise InputError(f"{outputs!r} controls: a student predicts 1..{MAX_CONTROLS}", source="layout")
    state = None if backbone_weights is None else load_weights(backbone_weights, "backbone weights file")
    net = Student()
    if state is not None:
        if not isinstance(state, dict):
            raise InputError("is not a state dict of weights", source=str(backbone_weights))
        features = {k[len("features."):]: v for k, v in state.items() if isinstance(k, str) and k.startswith("features.")}
        try:
            net.features.load_state_dict(features, strict=True)
        except (RuntimeError, TypeError, ValueError, AttributeError):
            raise InputError("is not a torchvision mobilenet_v3_small state dict (its features do not match)",
                             source=str(backbone_weights)) from None
    return net


def load_weights(path: str | os.PathLike, what: str,
                 hint: str = "save torchvision's mobilenet_v3_small weights with torch.save(model.state_dict())"):
    """What ``torch.load(path, weights_only=True)`` gives (no pickled code), the file first checked
    as a zip within :data:`WEIGHTS_ZIP`; one InputError naming ``path`` (``what``: the kind of file,
    ``hint``: what to give instead)."""
    import torch

    source = str(path)
    with open_zip(path, WEIGHTS_ZIP, what=what, source=source, hint=hint) as fh:
        try:
            return torch.load(fh, map_location="cpu", weights_only=True)
        except Exception as exc:  # noqa: BLE001  (torch raises RuntimeError, UnpicklingError, zip errors ...)
            reason = (str(exc).splitlines() or [""])[0][:80] or type(exc).__name__
            raise InputError(f"not a {what} torch can read ({type(exc).__name__}: {reason})", source=source,
                             hint=hint) from None
