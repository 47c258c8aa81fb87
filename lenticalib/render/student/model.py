"""The student network: MobileNetV3-Small features, global average pooling, a two-layer head.

Input float32 (B, 3, S, S), ImageNet-normalised crops (:func:`.crop.to_input`); output (B, D),
the normalised control vector ((controls - mean) / std per component, :mod:`.student_file`).
The backbone is torchvision's ``mobilenet_v3_small`` built without weights; its ``features``
take the user's weights file when given (a torchvision ``mobilenet_v3_small`` state dict, as
``torch.save(model.state_dict())`` writes it; never downloaded), and are trained from scratch
otherwise.  Head: Linear(576, HIDDEN), Hardswish, Dropout(DROPOUT), Linear(HIDDEN, D).
"""

from __future__ import annotations

import os

from ...core.errors import InputError

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

    net = Student()
    if backbone_weights is not None:
        try:
            state = torch.load(backbone_weights, map_location="cpu", weights_only=True)
        except (OSError, RuntimeError, ValueError) as exc:
            raise InputError(f"cannot read backbone weights: {exc}", source=str(backbone_weights)) from None
        if not isinstance(state, dict):
            raise InputError("is not a state dict of weights", source=str(backbone_weights))
        features = {k[len("features."):]: v for k, v in state.items() if k.startswith("features.")}
        try:
            net.features.load_state_dict(features, strict=True)
        except RuntimeError:
            raise InputError("is not a torchvision mobilenet_v3_small state dict (its features do not match)",
                             source=str(backbone_weights)) from None
    return net
