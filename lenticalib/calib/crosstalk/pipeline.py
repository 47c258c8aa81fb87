"""``measure_crosstalk_set``: the whole of ``lenticalib crosstalk measure`` as one library call.

Checks first (the output file and report folder, the profile against the patterns' own record,
the capture set, the eye separation), then the measurement (:func:`.measure.measure_crosstalk`),
the document (:func:`.result.crosstalk_document`, with provenance and, when a ``predict``
function is given, what pre-compensation with the measured matrix would do), the report folder
(staged) and ``crosstalk.json`` (atomically).

Errors name the argument at fault by its parameter name (``source="eye_separation_views"``,
``"report_dir"``, ``"profile"`` ...); a command-line front end maps them to its flags.
"""

from __future__ import annotations

import dataclasses
import math
import os
from pathlib import Path
from typing import Callable

import numpy as np

from ...core.errors import InputError
from ...core.files.outputs import check_output_file, check_output_folder, staged_folder
from ...core.pattern_sets import MANIFEST_NAME
from ...core.profile import PanelProfile, load_profile, make_provenance


@dataclasses.dataclass(frozen=True)
class EyeSeparation:
    """How far apart a viewer's eyes are, for the eye-pair crosstalk: ``views`` (in views), or
    ``mm`` (typically 63-65) at ``distance_mm`` from a panel whose full view cone is
    ``cone_angle_deg`` (data sheet).  All None: no eye-pair figure."""

    views: float | None = None
    mm: float | None = None
    distance_mm: float | None = None
    cone_angle_deg: float | None = None

    def resolve(self, views: int) -> tuple[float | None, str | None]:
        """(eye separation in views, a note of how it was given) for a panel of ``views`` views;
        InputError naming the field (``eye_separation_views``, ``eye_separation_mm``,
        ``distance_mm``, ``cone_angle_deg``) when it is incomplete or out of range."""
        from .result import eye_separation_views

        if self.views is not None and self.mm is not None:
            raise InputError("give the eye separation once", source="eye_separation_mm",
                             hint="use eye_separation_views or eye_separation_mm, not both")
        if self.views is not None:
            if not (math.isfinite(self.views) and 0.5 <= self.views <= views / 2):
                raise InputError(f"{self.views} views is out of range", source="eye_separation_views",
                                 hint=f"use 0.5..{views / 2:g} views")
            return self.views, None
        if self.mm is None:
            if self.distance_mm is not None or self.cone_angle_deg is not None:
                raise InputError("is only used with eye_separation_mm",
                                 source="distance_mm" if self.distance_mm is not None else "cone_angle_deg",
                                 hint="add eye_separation_mm")
            return None, None
        for field, value, lo, hi in (("eye_separation_mm", self.mm, 20.0, 120.0),
                                     ("distance_mm", self.distance_mm, 100.0, 10000.0),
                                     ("cone_angle_deg", self.cone_angle_deg, 1.0, 120.0)):
            if value is None:
                raise InputError("is needed with eye_separation_mm", source=field,
                                 hint="give the viewing distance in mm and the panel's full view-cone angle in degrees")
            if not (math.isfinite(value) and lo <= value <= hi):
                raise InputError(f"{value} is out of range", source=field, hint=f"use {lo:g}..{hi:g}")
        e = eye_separation_views(self.mm, self.distance_mm, self.cone_angle_deg, views)
        if not 0.5 <= e <= views / 2:
            raise InputError(f"{self.mm} mm is {e:.2f} views at {self.distance_mm:g} mm", source="eye_separation_mm",
                             hint=f"the eyes must be 0.5..{views / 2:g} views apart; check distance_mm and "
                                  "cone_angle_deg")
        return e, (f"{self.mm:g} mm at {self.distance_mm:g} mm from a panel with a {self.cone_angle_deg:g} degree "
                   f"view cone")


@dataclasses.dataclass
class CrosstalkRun:
    """What :func:`measure_crosstalk_set` did: ``document`` (what ``crosstalk.json`` holds),
    ``measurement`` (:class:`.measure.Measurement`: matrix, warnings, seconds ...), ``eye_separation``
    (views, or None), ``compensation`` (the ``predict`` study, or None), ``output`` (the file
    written), ``report_dir`` (the report folder written, or None)."""

    document: dict
    measurement: object
    eye_separation: float | None
    compensation: dict | None
    output: Path
    report_dir: Path | None


def measure_crosstalk_set(directory: str | os.PathLike, output: str | os.PathLike, *,
                          profile: str | os.PathLike | PanelProfile | None = None,
                          report_dir: str | os.PathLike | None = None, eye: EyeSeparation | None = None,
                          photos: str = "srgb", predict: Callable[[np.ndarray], dict] | None = None,
                          progress: Callable[[str], None] | None = None,
                          progress_total: Callable[[int], None] | None = None,
                          force: bool = False) -> CrosstalkRun:
    """Measure the crosstalk from ``directory/captures`` and write ``output`` (and the report).

    ARGUMENTS
    directory       folder from ``lenticalib crosstalk patterns`` with ``captures/``
    output          the crosstalk JSON to write
    profile         the profile the patterns were drawn from (a path or a profile), checked
                    against the patterns' own record; None: the record alone
    report_dir      the report folder (figures); None: no report
    eye             :class:`EyeSeparation` for the eye-pair crosstalk
    photos          "srgb" (camera JPEGs) or "linear" (16-bit from RAW)
    predict         ``predict(matrix)`` -> a compensation study
                    (:func:`lenticalib.render.compose.compensation.predict_compensation`): its numbers go
                    into the document as ``compensation_prediction``, its figure into the report
    progress        called once per step; ``progress_total`` once before, with the number of steps
    force           measure photos that do not follow the profile's routing anyway
                    (:func:`.checks.check_routing`); the document's provenance then says so, and why

    RETURNED VALUE
    :class:`CrosstalkRun`.  Every InputError about the arguments and outputs comes before the
    photos are read.
    """
    from .measure import measure_crosstalk, open_crosstalk_set
    from .report import REPORT_FILES, write_crosstalk_report
    from .result import crosstalk_document, write_crosstalk

    profile_file = None if profile is None or isinstance(profile, PanelProfile) else profile
    # the manifest, the photos (all of captures/) and the profile's file: what the outputs may not be
    inputs = (Path(directory) / MANIFEST_NAME, Path(directory) / "captures", profile_file)
    output = check_output_file(output, "crosstalk file", example="crosstalk.json", inputs=inputs)
    if report_dir is not None:
        check_output_folder(report_dir, "crosstalk report", contents=REPORT_FILES, inputs=inputs)
        if os.path.abspath(report_dir) == os.path.abspath(output):
            raise InputError("is also the crosstalk file path", source="report_dir", hint="give the report a folder")
    if profile_file is not None:
        profile = load_profile(profile_file, "`profile`")
    pattern_set, capture = open_crosstalk_set(directory, profile, "profile")
    eye_views, eye_note = (eye or EyeSeparation()).resolve(pattern_set.views)
    if progress_total is not None:
        progress_total(len(pattern_set.patterns) + 3)
    measurement = measure_crosstalk(directory, profile, photos=photos, profile_source="profile", progress=progress,
                                    force=force)
    routing = measurement.diagnostics["routing_check"]  # a refusal overridden by force: the file says so, and why
    forced = ({"forced": "measured with force (--force) although the photos do not follow the routing of the profile "
                         "the patterns were drawn from: " + "; ".join(routing["reasons"])} if routing["forced"] else {})
    provenance = make_provenance("crosstalk measurement", inputs=measurement.inputs,
                                 **({"profile_file": str(profile_file)} if profile_file is not None else {}),
                                 pattern_set=pattern_set.set_id, seconds=round(measurement.seconds, 2), **forced)
    document = crosstalk_document(measurement, eye_views, eye_note, provenance)
    study = predict(measurement.matrix) if predict is not None else None
    if study is not None:
        document["compensation_prediction"] = {k: (round(v, 5) if isinstance(v, float) else v)
                                               for k, v in study.items() if not isinstance(v, list)}
    if report_dir is not None:
        with staged_folder(report_dir, "crosstalk report", contents=REPORT_FILES, inputs=inputs) as stage:
            write_crosstalk_report(measurement, stage, document, compensation=study)
            write_crosstalk(output, document)
    else:
        write_crosstalk(output, document)
    return CrosstalkRun(document, measurement, eye_views, study, output,
                        None if report_dir is None else Path(report_dir))
