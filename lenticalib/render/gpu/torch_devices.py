"""Torch devices: whether the one named can be used on this machine, asked without initialising a GPU.

Used by every part that takes ``--device``: the ``torch`` encoder's tables, the ``gsplat``
renderer's availability and the avatar drive (:mod:`.loop`).  Imports torch, so it is asked only
when a torch device is in play.
"""

from __future__ import annotations


def device_unavailable(device) -> str | None:
    """Why torch cannot compute on ``device`` (``"cpu"``, ``"cuda"``, ``"cuda:K"``) here, in one line, or None."""
    import torch

    try:
        device = torch.device(device)
    except (RuntimeError, TypeError):
        return f"{device!r} is not a torch device (cpu, cuda, cuda:K)"
    if device.type == "cuda":
        if not torch.cuda.is_available():
            return f"device {str(device)!r} requested but torch sees no CUDA device"
        if device.index is not None and device.index >= torch.cuda.device_count():
            return f"device {str(device)!r} requested but torch sees {torch.cuda.device_count()} CUDA device(s)"
    return None
