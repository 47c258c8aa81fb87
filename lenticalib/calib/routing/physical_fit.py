"""The panel's physical constants from fitted routing constants and camera poses.

One fit gives, for the camera at ``E = (x, y, D)``: the slant ``C_r = tan(phi)``, the period
``Delta_r = 3 P_h (1 + g / D) / p`` and the phase (``s_ref``, ``i_ref``); the camera pose
(:mod:`.pose`) gives ``x``, ``y`` and ``D + g``, the distance to the pixel plane.  Lens pitch and
gap are not separable from one distance (``P_h (1 + g/D)`` is all the period holds), so the gap
comes from

- two capture sets from two distances ``D1 + g``, ``D2 + g`` (pixel-plane distances ``Q1``,
  ``Q2``): ``Delta_i = 3 P_h Q_i / (p (Q_i - g))``, hence

      g = Q1 Q2 (Delta_2 - Delta_1) / (Delta_2 Q1 - Delta_1 Q2),

  independent of P_h, and insensitive to a common scale error of both distances (a focal length
  error scales g with them, so g / D -- what the routing needs -- is unchanged);
- or the data sheet (``--gap``).

Then ``D = Q - g``, ``m = 1 + g / D``, ``P_h = Delta_r p / (3 m)``, the slant angle, the lens
position ``x0`` (boundaries ``x = x0 + k P_h + y tan(phi)``, panel-centred mm, reduced into
[0, P_h)) from the profile's phase, and the view cone ``2 atan(P_u / 2g)``.

Units: mm, degrees, subpixels; frames as in :mod:`lenticalib.core.physical`.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from ...core.errors import InputError
from ...core.physical import view_cone_deg
from ...core.profile import PanelProfile, describe_input
from ..camera.pose import SYSTEMATIC_FRACTION, PanelPose

MIN_DISTANCE_RATIO = 1.15  # two capture sets closer than this in distance do not determine the gap


def gap_from_two_distances(period1: float, q1: float, period2: float, q2: float) -> float:
    """g (mm) from the periods (subpixels) fitted at pixel-plane distances q1, q2 (mm)."""
    return q1 * q2 * (period2 - period1) / (period2 * q1 - period1 * q2)


def lens_position(profile: PanelProfile, eye: tuple[float, float, float], pixel_pitch: float, gap: float,
                  lens_pitch: float) -> float:
    """x0 (mm, in [0, P_h)): where a lens boundary crosses the panel's centre row on the lens
    surface, from the profile's seen lines mapped back through ``L = F + (P - F) / m``."""
    n, p, t = profile.views, pixel_pitch, profile.slant
    c0 = profile.offset + 0.5 + (profile.reference_view - n / 2.0) * profile.period / n
    k0 = t * p * (profile.height - 1) / 2.0 - profile.width * p / 2.0
    a = (p / 3.0) * c0 + k0  # a seen line x = t y + a (pixel plane, mm)
    m = 1.0 + gap / eye[2]
    bx, by = eye[0] * (1.0 - 1.0 / m), eye[1] * (1.0 - 1.0 / m)
    centre = a / m + bx - t * by  # the lens centre line on the lens surface
    return float(np.mod(centre - lens_pitch / 2.0, lens_pitch))


def physical_block(profile: PanelProfile, pose: PanelPose, pixel_pitch: float, *,
                   second: tuple[PanelProfile, PanelPose] | None = None, gap: float | None = None,
                   gap_sigma: float = 0.0) -> tuple[dict[str, Any], dict[str, Any]]:
    """(the profile's physical block, a report of how it was found) -- see the module docstring.

    ``pose`` and ``second[1]`` are referred to the pixel plane (``gap_mm`` None).  With neither
    ``second`` nor ``gap`` the block holds the pixel pitch and slant angle only (the camera's
    distance to the lens surface, and so ``eye_mm``, needs the gap).
    """
    q1 = pose.pixel_plane_distance_mm
    report: dict[str, Any] = {"pixel_plane_distance_mm": q1, "pixel_plane_distance_sigma_mm": float(pose.sigma_mm[2])}
    phi = math.atan(profile.slant)
    block: dict[str, Any] = {"pixel_pitch_mm": float(pixel_pitch), "slant_angle_deg": math.degrees(phi),
                             "source": "fit"}
    uncertainty: dict[str, Any] = {}
    if "slant" in (profile.uncertainty or {}):
        uncertainty["slant_angle_deg"] = math.degrees(profile.uncertainty["slant"] / (1 + profile.slant ** 2))
    if second is not None:
        gap, gap_sigma, detail = _gap_from_sets(profile, pose, *second)
        report["gap_from"] = "two capture sets"
        report.update(detail)
    elif gap is not None:
        report["gap_from"] = "given (data sheet)"
    if gap is None:
        report["gap_from"] = None
        report["note"] = ("the gap is unknown, so the camera's distance to the lens surface, the lens pitch and the "
                          "eye position are not in the profile: fit a second capture set from another distance "
                          "(--second-distance) or give the data sheet's gap (--gap)")
        block["uncertainty"] = uncertainty
        return block, report
    distance = q1 - gap
    m = q1 / distance
    lens_pitch = profile.period * pixel_pitch / (3.0 * m)
    eye = (float(pose.eye_mm[0]), float(pose.eye_mm[1]), float(distance))
    block.update({"lens_pitch_mm": lens_pitch, "gap_mm": float(gap), "eye_mm": list(eye),
                  "lens_position_mm": lens_position(profile, eye, pixel_pitch, gap, lens_pitch),
                  "view_cone_deg": view_cone_deg(lens_pitch, math.degrees(phi), gap)})
    sigma_period = (profile.uncertainty or {}).get("period", 0.0)
    # P_h = Delta p (Q - g) / (3 Q): first-order terms in Delta, g and Q
    dq = pixel_pitch * profile.period * gap / (3.0 * q1 ** 2)
    uncertainty["lens_pitch_mm"] = math.sqrt((lens_pitch / profile.period * sigma_period) ** 2
                                             + (pixel_pitch * profile.period / (3 * q1) * gap_sigma) ** 2
                                             + (dq * pose.sigma_mm[2]) ** 2)
    uncertainty["gap_mm"] = float(gap_sigma)
    uncertainty["eye_mm"] = [float(pose.sigma_mm[0]), float(pose.sigma_mm[1]),
                             float(math.hypot(pose.sigma_mm[2], gap_sigma))]
    block["uncertainty"] = uncertainty
    report.update({"gap_mm": float(gap), "gap_sigma_mm": float(gap_sigma), "distance_mm": distance,
                   "magnification": m})
    return block, report


def _gap_from_sets(profile1: PanelProfile, pose1: PanelPose, profile2: PanelProfile,
                   pose2: PanelPose) -> tuple[float, float, dict[str, Any]]:
    q1, q2 = pose1.pixel_plane_distance_mm, pose2.pixel_plane_distance_mm
    ratio = max(q1, q2) / min(q1, q2)
    if ratio < MIN_DISTANCE_RATIO:
        raise InputError(f"the two capture sets are {q1:.0f} and {q2:.0f} mm from the panel: too close in distance "
                         "to tell the gap", source="second_distance",
                         hint=f"take the second set at least {100 * (MIN_DISTANCE_RATIO - 1):.0f} % nearer or farther "
                              "(e.g. 450 and 800 mm)")
    d1, d2 = profile1.period, profile2.period
    gap = gap_from_two_distances(d1, q1, d2, q2)
    if not gap > 0:
        raise InputError(f"the periods fitted at {q1:.0f} and {q2:.0f} mm ({d1:.6f}, {d2:.6f} subpixels) give a gap "
                         f"of {gap:.3g} mm", source="second_distance",
                         hint="the period must shrink as the camera moves away; check that both sets show one panel "
                              "and the camera model is the camera's")
    s1 = (profile1.uncertainty or {}).get("period", 0.0)
    s2 = (profile2.uncertainty or {}).get("period", 0.0)
    h1, h2 = 1e-4 * d1, 1e-2
    terms = [(gap_from_two_distances(d1 + h1, q1, d2, q2) - gap) / h1 * s1,
             (gap_from_two_distances(d1, q1, d2 + h1, q2) - gap) / h1 * s2]
    # the distances: the block jackknife part is independent per set; the intrinsics part is
    # common to both (same camera model, same draws) and enters through the drawn pairs
    jack1, jack2 = pose1.jackknife_sigma_mm[2], pose2.jackknife_sigma_mm[2]
    terms += [(gap_from_two_distances(d1, q1 + h2, d2, q2) - gap) / h2 * jack1,
              (gap_from_two_distances(d1, q1, d2, q2 + h2) - gap) / h2 * jack2]
    # the distance floor (pose.SYSTEMATIC_FRACTION) is a scale error of the seen-point maps, alike in
    # both sets: a common relative error of both distances scales g with them
    terms.append(gap * SYSTEMATIC_FRACTION)
    variance = float(np.sum(np.square(terms)))
    if pose1.drawn_distances is not None and pose2.drawn_distances is not None:
        drawn = gap_from_two_distances(d1, pose1.drawn_distances, d2, pose2.drawn_distances)
        variance += float(np.var(drawn, ddof=1))
    detail = {"second_pixel_plane_distance_mm": q2, "second_period": d2, "first_period": d1}
    return gap, math.sqrt(variance), detail


def add_physical(result, pixel_pitch: float, *, second=None, gap: float | None = None,
                 second_directory=None) -> None:
    """Give ``result`` (a fit with a pose) its profile's physical block and the report's
    ``quality["physical"]``; ``second`` is the fit of ``--second-distance``."""
    other = None
    if second is not None:
        if second.pose is None:
            raise InputError("the second capture set has no camera pose", source=str(second_directory))
        other = (second.profile, second.pose)
    block, report = physical_block(result.profile, result.pose, pixel_pitch, second=other, gap=gap)
    if second is not None:
        pose2 = second.pose.with_gap(block["gap_mm"]) if block.get("gap_mm") else second.pose
        report.update({"second_set": str(second_directory), "second_trusted": bool(second.trusted),
                       "second_pose": pose2.to_dict()})
    if block.get("gap_mm"):
        result.pose = result.pose.with_gap(block["gap_mm"])
        result.quality["camera"]["pose"] = result.pose.to_dict()
    result.quality["physical"] = report
    provenance = dict(result.profile.provenance or {})
    provenance["camera_model"] = describe_input(result.quality["camera"].get("source"))
    if second is not None:
        provenance["second_distance_inputs"] = (second.profile.provenance or {}).get("inputs", [])
    result.profile = result.profile.replace(physical=block, provenance=provenance)
