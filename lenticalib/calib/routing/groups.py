"""Photo groups of a capture set: loaded, registered against camera shake, demodulated.

Frames: working-image pixels (see :mod:`.phase`).  A *group* is the K phase steps of one
pattern (``x0`` ... ``f22``); its complex fringe ``z`` and mean image ``dc`` are (h, w) maps.
Every photo is aligned on the patterns' registration frame (:mod:`.register`) before its
group is demodulated, so shake between photos -- within a group too -- is undone.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from ...core.errors import CaptureError
from ..patterns import phase, register
from ..patterns.capture_sets import CaptureSet, Photo, check_exposure, load_photo
from .checks import check_distinct
from ..patterns.calibration_patterns import frame_width

def group_photos(capture: CaptureSet, group: str, shape: tuple[int, int] | None, progress,
                  keep_rgb: bool = False) -> list[Photo]:
    photos = []
    for pattern in capture.patterns.group(group):
        if progress:
            progress(f"reading {capture.photo(pattern.name).name}")
        photo = load_photo(pattern.name, capture.photo(pattern.name), keep_rgb=keep_rgb)
        shape = shape or photo.shape
        if photo.shape != shape:
            raise CaptureError(f"is {photo.shape[1]}x{photo.shape[0]} pixels, the other photos are "
                               f"{shape[1]}x{shape[0]}", source=str(photo.path),
                               hint="take every photo with the same camera, zoom and orientation")
        check_exposure(photo)
        photos.append(photo)
    return photos


@dataclasses.dataclass
class Group:
    name: str
    period: float
    z: np.ndarray
    dc: np.ndarray
    photos: list[Photo]
    sigma: float = 0.0  # Gaussian (working pixels) the complex fringe was averaged with
    cycles: np.ndarray | None = None  # phase (cycles) after the photometric correction, if any

    def phase(self) -> np.ndarray:
        """The group's phase in cycles, [0, 1): corrected if a correction was made."""
        return self.cycles if self.cycles is not None else phase.phase_cycles(self.z)


@dataclasses.dataclass
class Registration:
    """Per-photo registration state: the reference (from group x1) and what was measured."""

    reference: register.Reference | None = None
    made: bool = False  # the reference was attempted (on group x1)
    shifts: dict = dataclasses.field(default_factory=dict)  # photo name -> shift in photo pixels
    warnings: list = dataclasses.field(default_factory=list)

    def undo_shake(self, photos: list[Photo], capture: CaptureSet) -> None:
        """Measure every photo's shift against the reference and resample its luma to undo it.

        Raises CaptureError only for a shift that is large (> MAX_PHOTO_SHIFT), clearly measured
        (> 5 sigma) and explains most of the outline's change (it removes more than half the
        unshifted residual); a shift that cannot be measured becomes a warning.
        """
        if self.reference is None:
            return
        for photo in photos:
            shift = self.reference.measure(photo.luma)
            scale = photo.scale
            self.shifts[photo.name] = {"dx": shift.dx / scale, "dy": shift.dy / scale,
                                       "sigma": shift.sigma / scale if math.isfinite(shift.sigma) else None,
                                       "measured": shift.measured}
            if not shift.measured:
                self.warnings.append(f"camera motion of photo {photo.path.name} could not be measured "
                                     f"({shift.note}); it is not corrected")
                continue
            if shift.size > MAX_PHOTO_SHIFT and shift.size > 5 * shift.sigma and shift.improvement > 0.5:
                raise CaptureError(f"the camera moved between photos: this photo is shifted by "
                                   f"{shift.size / scale:.1f} pixels (+- {shift.sigma / scale:.2f}) against group x1",
                                   source=str(photo.path),
                                   hint="put the camera on a tripod, use a remote or timer release, and retake the set")
            photo.luma = register.shift_image(photo.luma, shift.dx, shift.dy)


def demodulate_group(capture: CaptureSet, name: str, shape, progress, registration: Registration) -> Group:
    photos = group_photos(capture, name, shape, progress)
    patterns = capture.patterns.group(name)
    if len(photos) > 1:
        check_distinct(Group(name, patterns[0].period, None, None, photos), capture)
    pat = patterns[0]
    sigma = 0.0
    extent = 3 * capture.patterns.width if pat.axis == "x" else capture.patterns.height
    if pat.period < extent / 4:
        # many fringes across the panel: every step has the same mean light, so differences in
        # mean between the photos are exposure changes (phone auto-exposure); undo them
        means = [float(np.mean(p.luma, dtype=np.float64)) for p in photos]
        target = float(np.mean(means))
        for p, m in zip(photos, means):
            if m > 0:
                p.luma = p.luma * np.float32(target / m)
    if not registration.made:
        frame = frame_width(capture.patterns.height) / capture.patterns.height
        z_raw, dc_raw = phase.demodulate([p.luma for p in photos], [p.theta for p in patterns])
        registration.reference = register.Reference.from_mean_image(dc_raw, z_raw, frame)
        registration.made = True
        if registration.reference is None:
            registration.warnings.append(f"camera motion between photos could not be measured (no fringes "
                                         f"found in group {name}); it is not corrected")
    registration.undo_shake(photos, capture)
    z, dc = phase.demodulate([p.luma for p in photos], [p.theta for p in patterns])
    if pat.group[0] in "xy":
        # A camera pixel may see no lit (green) subpixel; average the complex fringe over an
        # eighth of a fringe (the panel spans at least ~half the frame), which keeps the phase.
        frame = z.shape[1] if pat.axis == "x" else z.shape[0]
        sigma = min(frame / 300.0, pat.period / extent * 0.5 * frame / 8.0)
        z = phase.smooth_complex(z, sigma)
    for p in photos:  # keep memory bounded: luma is needed only for the per-photo checks
        p.luma = p.luma.astype(np.float16)
    return Group(name, patterns[0].period, z, dc, photos, sigma if sigma >= 0.5 else 0.0)


MAX_PHOTO_SHIFT = 3.0  # working pixels: a bigger, clearly measured shift is a moved camera, not shake
