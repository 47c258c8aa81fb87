"""Per-photo and per-set checks of a capture set: each names the photo and what to do.

Frames: working-image pixels (see :mod:`.phase`).  Every check raises
:class:`~lenticalib.core.errors.CaptureError` with the photo (or the captures folder) as source.
"""

from __future__ import annotations

import math

import cv2
import numpy as np

from ...core.errors import CaptureError
from . import model
from ..patterns.capture_sets import CaptureSet

MAX_CLIPPED_FRACTION = 0.02
MIN_PANEL_FRACTION = 0.04


def check_photo_steps(group, predicted_cycles: np.ndarray, mask: np.ndarray, capture: CaptureSet,
                       what: str) -> None:
    """Each photo of a group must show its own phase step of the predicted fringe, as clearly as
    the others.

    A photo is compared with the mean of the *other* photos of its group, ``I_k - mean_j I_j =
    (K/(K-1)) B cos(Phi + theta_k)`` for a right photo, so a blank, blurred or swapped photo
    cannot hide behind a group average it is part of.  When every photo of the group is off,
    the fault is the set's (another pattern set, a moved camera), not one photo's.
    """
    patterns = capture.patterns.group(group.name)
    sel = mask & np.isfinite(predicted_cycles)
    stride = max(1, int(sel.sum() // 400_000))
    index = np.flatnonzero(sel)[::stride]
    carrier = np.exp(-2j * math.pi * predicted_cycles.ravel()[index])
    values = [p.luma.ravel()[index].astype(np.float32) for p in group.photos]
    total = np.sum(values, axis=0)
    k = len(values)
    amps, steps = [], []
    for value, pattern in zip(values, patterns):
        others = (total - value) / (k - 1)
        q = complex(np.mean((value - others) * carrier))
        amps.append(abs(q))
        steps.append(abs(float(model.wrap(math.atan2(q.imag, q.real) / (2 * math.pi) - pattern.step / pattern.steps))))
    reference = float(np.median(amps))
    if all(step > 0.11 for step in steps) or reference <= 0:
        raise CaptureError(f"no photo of group {group.name} shows its pattern where the other groups say it "
                           f"should be {what}".rstrip(), source=str(capture.directory / "captures"),
                           hint="the photos belong to another pattern set, or the camera moved between "
                                "groups; photograph this folder's patterns with the camera on a tripod")
    for photo, pattern, amp, step in zip(group.photos, patterns, amps, steps):
        if amp < 0.6 * reference or step > 0.11:
            raise CaptureError(f"does not show pattern {pattern.name} clearly (fringe contrast {amp / reference:.2f} "
                               f"of its group's, phase off by {step * 360:.0f} degrees) {what}".rstrip(),
                               source=str(photo.path),
                               hint=f"show {pattern.file} full screen, keep the camera still and in focus, "
                                    "and photograph it again")


def check_distinct(group, capture: CaptureSet) -> None:
    """Two photos of one phase-shift group must differ (a pattern photographed twice, or a copy)."""

    small = [cv2.resize(p.luma.astype(np.float32), None, fx=0.25, fy=0.25, interpolation=cv2.INTER_AREA)
             for p in group.photos]
    pairs = [(i, j) for i in range(len(small)) for j in range(i + 1, len(small))]
    energy = [float(np.mean((small[i] - small[j]) ** 2)) for i, j in pairs]
    level = float(np.mean([np.mean(s ** 2) for s in small]))
    if max(energy) < 0.01 * level:
        return  # hardly any fringes in any photo (blur, no panel): later checks name that
    # a visible fringe makes two different steps differ by ~0.1 level; a duplicate by noise only
    same = [e < min(0.002 * level, 0.05 * max(energy)) for e in energy]
    for (i, j), e, is_same in zip(pairs, energy, same):
        if is_same:
            raise CaptureError(f"shows the same pattern as {group.photos[i].path.name}", source=str(group.photos[j].path),
                               hint=f"photograph {capture.patterns.group(group.name)[j].file} (each phase step is a "
                                    "different image)")


def check_clipping(groups: list, mask: np.ndarray) -> None:

    for group in groups:
        for photo in group.photos:
            clipped = photo.clipped
            if clipped.shape != mask.shape:
                clipped = cv2.resize(clipped, mask.shape[::-1], interpolation=cv2.INTER_AREA)
            fraction = float(clipped[mask].mean())
            if fraction > MAX_CLIPPED_FRACTION:
                raise CaptureError(f"is overexposed: {100 * fraction:.0f}% of the panel is clipped",
                                   source=str(photo.path),
                                   hint="lower the exposure (or ISO) until no part of the panel is pure white, "
                                        "and retake every photo with that exposure")


def mask_checks(mask: np.ndarray, capture: CaptureSet) -> None:
    frac = float(mask.mean())
    first = capture.photo(capture.patterns.group("x1")[0].name)
    if frac < MIN_PANEL_FRACTION:
        raise CaptureError(f"the panel was not found ({100 * frac:.1f}% of the frame shows fringes)",
                           source=str(first.parent),
                           hint="fill most of the frame with the panel, show the patterns full screen, "
                                "and check that the photos are of the patterns")
    edge = np.concatenate([mask[0], mask[-1], mask[:, 0], mask[:, -1]])
    if edge.mean() > 0.10:
        raise CaptureError("the panel is cut off by the edge of the photos", source=str(first.parent),
                           hint="step back or zoom out so the whole panel is inside every photo")
