"""``fit_capture_sets``: the whole fit of ``lenticalib fit`` as one library call.

One capture set gives the profile (:func:`lenticalib.calib.routing.fit.fit_capture_set`).  Two more may
join it:

- ``moved_right``: the same patterns photographed after moving the camera a few centimetres to
  the right (same distance); the difference of the two fits gives the profile's
  ``view_direction`` (:mod:`.direction`), or leaves it unknown with a warning saying why;
- :class:`PhysicalOptions`: a camera model and the panel's pixel pitch give the camera's pose
  in mm and the profile's physical block (:mod:`.physical_fit`); the gap comes from
  ``second_distance`` (the same patterns from another distance, fitted too) or from the data
  sheet (``gap_mm``).

Every option and output path is checked before the first photo is read.  Outputs, when asked
for: the report folder (staged, moved into place complete) and the profile (atomically), so:

- trusted (or ``force``): the report and the profile;
- not trustworthy: the report (it shows why), no profile; :attr:`FitRun.trusted` is False;
- an error: nothing at all; an earlier profile and report stay as they were.

Errors name the argument at fault by its parameter name (``source="pixel_pitch_mm"``, and in
hints ``pixel_pitch_mm``, ``second_distance`` ...); a command-line front end maps them to its flags.
"""

from __future__ import annotations

import dataclasses
import os
from pathlib import Path
from typing import Callable

from ...core.errors import InputError
from ...core.identity import check_same_virtual_panel
from ...core.files.outputs import Inputs, check_output_file, check_output_folder, staged_folder
from ...core.pattern_sets import MANIFEST_NAME
from ...core.physical import LIMITS
from ...core.profile import MAX_VIEWS, PanelProfile, save_profile
from . import fit as fit_module
from ..camera.model_file import CameraModel, load_camera_model
from ..patterns.capture_sets import open_capture_set

ProgressFn = Callable[[str], None]
CAPTURE_FOLDER = "captures"  # DIR/captures: the photos (:mod:`.captures`)

SECOND_DISTANCE_HOW = ("photograph the patterns again from another distance, into a copy of the pattern folder")
MOVED_RIGHT_HOW = ("photograph the patterns again after moving the camera a few centimetres to the right, into a "
                   "copy of the pattern folder")


@dataclasses.dataclass(frozen=True)
class PhysicalOptions:
    """What the fit needs to give the panel's physical constants in mm.

    ``camera_model``: a calibrated camera (a path to an mrcal ``.cameramodel`` or OpenCV
    YAML/JSON, or a loaded :class:`~.camera_file.CameraModel`); ``pixel_pitch_mm``: the panel's
    width in mm over its pixels; the gap from ``second_distance`` (a capture set of the same
    patterns from a distance at least 15 % nearer or farther) or ``gap_mm`` (the data sheet's
    effective lens-to-pixel gap), not both.  All None: no physical block.
    """

    camera_model: CameraModel | str | os.PathLike | None = None
    pixel_pitch_mm: float | None = None
    second_distance: str | os.PathLike | None = None
    gap_mm: float | None = None

    def checked(self, capture_dir: str | os.PathLike) -> "PhysicalOptions":
        """A copy with the camera model loaded, once every field is usable with ``capture_dir``'s
        capture set; InputError naming the field (``source="pixel_pitch_mm"`` ...) otherwise."""
        for key, value in (("pixel_pitch_mm", self.pixel_pitch_mm), ("gap_mm", self.gap_mm)):
            low, high = LIMITS[key]
            if value is not None and not low <= value <= high:
                raise InputError(f"{value:g} mm is out of range", source=key, hint=f"give {low:g}..{high:g} mm")
        needs_camera = [k for k, v in (("pixel_pitch_mm", self.pixel_pitch_mm),
                                       ("second_distance", self.second_distance), ("gap_mm", self.gap_mm))
                        if v is not None]
        if needs_camera and not self.camera_model:
            raise InputError("needs a camera model", source=needs_camera[0],
                             hint="calibrate the camera ('lenticalib camera calibrate ...') and pass camera_model")
        model = self.camera_model
        if model and not isinstance(model, CameraModel):
            model = load_camera_model(model)  # read once for every fit: a broken file is one line now
        if model and self.pixel_pitch_mm is None:
            raise InputError("a camera model gives the camera's pose in mm only with the panel's pixel pitch",
                             source="camera_model", hint="pass pixel_pitch_mm (the panel's width in mm / its pixels)")
        if self.second_distance is not None and self.gap_mm is not None:
            raise InputError("give the gap one way", source="gap_mm", hint="either second_distance or gap_mm")
        if self.second_distance is not None:
            check_second_set(capture_dir, self.second_distance, "second_distance", SECOND_DISTANCE_HOW)
        return dataclasses.replace(self, camera_model=model or None)


@dataclasses.dataclass
class FitRun:
    """What :func:`fit_capture_sets` did.

    ``result``: the fit of ``capture_dir`` (:class:`~.fit.FitResult`: the profile, with its
    ``view_direction`` and physical block when the options asked for them, the quality numbers,
    ``direction`` and ``pose``, ``warnings``, ``problems``); ``summary``: the report's
    ``summary.json`` document (:func:`~.report.fit_summary`); ``profile_path``: where the profile
    goes (None: none asked for), ``profile_written``: whether it was written (a fit that is not
    trustworthy writes none without ``force``); ``report_dir``: the report folder written, or None.
    """

    result: fit_module.FitResult
    summary: dict
    profile_path: Path | None
    profile_written: bool
    report_dir: Path | None

    @property
    def profile(self) -> PanelProfile:
        return self.result.profile

    @property
    def trusted(self) -> bool:
        return self.result.trusted


def check_second_set(capture_dir, other, field: str, how: str) -> None:
    """InputError/CaptureError unless ``other`` is another complete capture set of the same patterns
    as ``capture_dir``; ``field`` names ``other`` in the error, ``how`` is the hint."""
    if os.path.realpath(other) == os.path.realpath(capture_dir):
        raise InputError("is the same capture set as capture_dir", source=field, hint=how)
    first, second = open_capture_set(capture_dir), open_capture_set(other)
    if first.patterns.set_id != second.patterns.set_id:
        raise InputError(f"holds photos of pattern set {second.patterns.set_id}, {capture_dir} of set "
                         f"{first.patterns.set_id}", source=str(other),
                         hint="photograph the same patterns from both camera positions")
    check_same_virtual_panel(capture_dir, other, str(other), "photograph the same panel from both camera positions")


def check_fit_outputs(output: str | os.PathLike | None, report_dir: str | os.PathLike | None, *,
                      inputs: Inputs) -> tuple[Path | None, Path | None]:
    """(profile path, report folder) once both can be written (:mod:`lenticalib.core.files.outputs`: no
    missing folder is created, a folder is not a profile path, a folder holding anything but a
    report is not replaced, neither is nor holds one of the ``inputs``); the report defaults to
    ``NAME-report/`` beside the profile."""
    from .report import REPORT_FILES

    output = None if output is None else check_output_file(output, "profile", example="profile.json", inputs=inputs)
    if report_dir is not None:
        report = check_output_folder(report_dir, "report", contents=REPORT_FILES, inputs=inputs)
    elif output is not None:
        report = output.with_name(output.stem + "-report")
        if report.exists() and not report.is_dir():
            raise InputError("is a file, not a folder for the report", source=str(report),
                             hint="remove it, or choose another report_dir")
        check_output_folder(report, "report", contents=REPORT_FILES, inputs=inputs)
    else:
        report = None
    if report is not None and output is not None and os.path.abspath(report) == os.path.abspath(output):
        raise InputError("is also the profile path", source=str(report), hint="give the report another folder")
    return output, report


def fit_steps(capture_dirs) -> int:
    """How many times the fits of ``capture_dirs`` call ``progress`` (:func:`~.fit.progress_steps`)."""
    return sum(fit_module.progress_steps(open_capture_set(d).patterns) for d in capture_dirs)


def fit_capture_sets(capture_dir: str | os.PathLike, *, output: str | os.PathLike | None = None,
                     report_dir: str | os.PathLike | None = None, moved_right: str | os.PathLike | None = None,
                     views: int | None = None, physical: PhysicalOptions | None = None, force: bool = False,
                     progress: ProgressFn | None = None,
                     progress_total: Callable[[int], None] | None = None) -> FitRun:
    """Fit the profile of the capture set in ``capture_dir``, with the optional second sets.

    ARGUMENTS: ``output``: the profile JSON to write (None: none); ``report_dir``: the report
    folder (default ``NAME-report/`` beside ``output``; None without ``output``: no report);
    ``moved_right``: a capture set for the view direction; ``views``: the number of views,
    2..254 (default: the pattern set's); ``physical``: :class:`PhysicalOptions`; ``force``:
    write the profile even when the fit fails a quality gate; ``progress``: called once per
    step with its name; ``progress_total``: called once, before the first step, with the number
    of steps.

    RETURNED VALUE: a :class:`FitRun`.  Raises InputError/CaptureError (naming the argument or
    file) before the first photo is read, CalibrationError when no plane fits.
    """
    from .report import REPORT_FILES, fit_summary, write_report

    if views is not None and not 2 <= views <= MAX_VIEWS:
        raise InputError(f"{views} views is out of range", source="views",
                         hint=f"use 2..{MAX_VIEWS}, or leave it out to use the pattern set's")
    given = physical or PhysicalOptions()
    sets = [Path(d) for d in (capture_dir, moved_right, given.second_distance) if d is not None]
    inputs = (*(d / MANIFEST_NAME for d in sets), *(d / CAPTURE_FOLDER for d in sets),  # the photos: all of captures/
              None if isinstance(given.camera_model, CameraModel) else given.camera_model)
    output, report = check_fit_outputs(output, report_dir, inputs=inputs)
    if moved_right is not None:
        check_second_set(capture_dir, moved_right, "moved_right", MOVED_RIGHT_HOW)
    physical = (physical or PhysicalOptions()).checked(capture_dir)
    camera = physical.camera_model
    second_distance = physical.second_distance if camera is not None else None
    if progress_total is not None:
        progress_total(fit_steps([d for d in (capture_dir, moved_right, second_distance) if d is not None]))
    options = dict(views=views, camera_model=camera, pixel_pitch_mm=physical.pixel_pitch_mm, progress=progress)
    result = fit_module.fit_capture_set(capture_dir, **options)
    if moved_right is not None:
        from .direction import add_moved_right

        add_moved_right(result, fit_module.fit_capture_set(moved_right, **options), moved_right)
    if camera is not None:
        from .physical_fit import add_physical

        other = fit_module.fit_capture_set(second_distance, **options) if second_distance is not None else None
        add_physical(result, physical.pixel_pitch_mm, second=other, gap=physical.gap_mm,
                     second_directory=second_distance)
    write_profile = output is not None and (result.trusted or force)
    summary = fit_summary(result, capture_dir, report=report, output=output if write_profile else None)
    if report is not None:
        with staged_folder(report, "report", contents=REPORT_FILES, inputs=inputs) as stage:
            write_report(result, stage, capture_dir, summary)
            if write_profile:
                save_profile(result.profile, output)
    elif write_profile:
        save_profile(result.profile, output)
    return FitRun(result, summary, output, write_profile, report)
