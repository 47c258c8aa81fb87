"""Routing constants for another eye position: a profile carried from one viewer to another.

A fitted profile is right for the eye it was measured from (the calibration camera at ``E1``).
Seen from an eye ``E = (x_E, y_E, -D)`` each lens shows the pixel-plane point on the chief ray
through its centre line, ``P = F + m (L - F)``: the lens-plane point ``L`` scaled by
``m = 1 + g / D`` about the eye's foot point ``F = (x_E, y_E)`` (docs/physical.md).  The lines
the eye sees (where the view coordinate is ``N / 2``) are therefore the same lens centre lines
for every eye, scaled about a different point by a different factor.  Going from ``E1`` to
``E2`` maps every seen line, in pixel-plane millimetres, by

    P2 = k P1 + b,   k = m2 / m1,   b = F2 (1 - m2) + F1 (m2 - k)

which keeps the slant, multiplies the period by ``k`` and shifts the phase.  Only the gap ``g``,
the pixel pitch ``p`` and where ``E1`` was are needed, not the lens pitch: the profile's own
period already holds ``P_h m1``.

A subpixel layout, reversed views and image flips are carried over unchanged: a layout's slot
shift ``e = 1 + 3 dx - 3 C_r dy - c`` (subpixels, :mod:`lenticalib.core.layout`) places each slot
at the panel position ``x_s + e``, which no eye moves, and depends only on the slant, which
retargeting keeps; the new period and offset route every slot from that same position.

Frames and units: world millimetres with the origin at the panel centre on the lens surface,
x right along the rows, y down the columns, the viewer at z = -D; raster coordinates as in
``docs/optics.md`` (subpixel ``x_s`` covers ``[x_s, x_s + 1)``, the profile's ``w`` at the left
edge equals the true ``w*`` at the centre).
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any, Sequence

import numpy as np

from .errors import InputError, ProfileError
from .profile import PanelProfile, make_provenance

DISTANCE_RANGE = (50.0, 20000.0)  # mm; nearer or farther is no viewer of a desktop panel


@dataclasses.dataclass(frozen=True)
class Eye:
    """An eye (or camera centre): ``x``, ``y`` lateral mm from the panel centre (x right, y
    down), ``distance`` mm in front of the lens surface (> 0)."""

    x: float
    y: float
    distance: float

    @classmethod
    def parse(cls, value: Any, source: str = "eye") -> "Eye":
        """From an :class:`Eye`, ``(x, y, D)`` or ``{"x", "y", "distance"}``; InputError naming ``source``."""
        if isinstance(value, Eye):
            return value
        try:
            if isinstance(value, dict):
                x, y, d = value.get("x", 0.0), value.get("y", 0.0), value["distance"]
            else:
                x, y, d = value
            x, y, d = float(x), float(y), float(d)
        except (TypeError, ValueError, KeyError):
            raise InputError(f"{value!r} is not an eye position", source=source,
                             hint="give (x, y, distance) in mm from the panel centre") from None
        if not all(math.isfinite(v) for v in (x, y, d)):
            raise InputError(f"eye position {value!r} is not finite", source=source)
        low, high = DISTANCE_RANGE
        if not low <= d <= high:
            raise InputError(f"viewing distance {d:g} mm is out of range", source=source,
                             hint=f"give the distance from the panel surface in mm, {low:g}..{high:g}")
        return cls(x, y, d)

    def as_list(self) -> list[float]:
        return [self.x, self.y, self.distance]


def calibration_eye(profile: PanelProfile, source: str = "profile") -> Eye:
    """The eye ``profile``'s constants are for: ``physical.eye_mm``, else a centred viewer at
    ``physical.design_distance_mm``; ProfileError naming what is missing otherwise."""
    physical = profile.physical or {}
    if physical.get("eye_mm"):
        x, y, d = physical["eye_mm"]
        return Eye(float(x), float(y), float(d))
    if physical.get("design_distance_mm"):
        return Eye(0.0, 0.0, float(physical["design_distance_mm"]))
    raise ProfileError("the profile does not say which eye position its constants are for", source=source,
                       hint="fit it with a camera model ('lenticalib fit DIR --camera camera.cameramodel') or set "
                            "the viewing distance its constants are for (a centred viewer; physical.eye_mm holds "
                            "any eye): `design_distance_mm`")


def _needs(profile: PanelProfile, source: str) -> tuple[float, float]:
    physical = profile.physical or {}
    if not physical.get("gap_mm"):
        raise ProfileError("the profile has no physical.gap_mm, so it cannot be moved to another distance",
                           source=source, hint="fit two capture sets from two distances ('lenticalib fit DIR "
                                               "--camera M --second-distance DIR2') or add the data sheet's gap: 'lenticalib profile set-physical P --pixel-pitch MM --gap MM'")
    return float(physical["pixel_pitch_mm"]), float(physical["gap_mm"])


def retarget_constants(slant: float, period: float, offset: float, reference_view: float, *, views: int,
                       width: int, height: int, pixel_pitch: float, gap: float, source: Eye,
                       target: Eye) -> tuple[float, float]:
    """(period, offset) for ``target`` of the routing that is right for ``source``.

    ARGUMENTS
    slant, period, offset, reference_view   the profile's C_r, Delta_r, s_ref, i_ref (raster units)
    views, width, height                     N and the raster in pixels
    pixel_pitch, gap                         p and g in mm
    source, target                           the eyes (mm, panel-centred, module docstring)

    RETURNED VALUE
    (Delta_r', s_ref') in subpixels; s_ref' is not reduced (the caller reduces it); slant and
    reference view are unchanged.
    """
    m1 = 1.0 + gap / source.distance
    m2 = 1.0 + gap / target.distance
    k = m2 / m1
    bx = target.x * (1.0 - m2) + source.x * (m2 - k)
    by = target.y * (1.0 - m2) + source.y * (m2 - k)
    # seen lines (w* = N/2 at subpixel centres) x = C_r y + a_j in mm, with
    #   a_j = (p/3)(c0 - j Delta_r) + K0,  c0 = s_ref + 1/2 + (i_ref - N/2) Delta_r / N,
    #   K0 = C_r p (H - 1)/2 - W p/2 (raster -> mm at subpixel centres);  P2 = k P1 + b maps a_j to
    #   k a_j + b_x - C_r b_y.
    half = (reference_view - views / 2.0) / views
    c0 = offset + 0.5 + half * period
    k0 = slant * pixel_pitch * (height - 1) / 2.0 - width * pixel_pitch / 2.0
    c0_new = k * c0 + (3.0 / pixel_pitch) * ((k - 1.0) * k0 + bx - slant * by)
    period_new = k * period
    return period_new, c0_new - 0.5 - half * period_new


def retarget_profile(profile: PanelProfile, eye: Any, *, source: str = "profile",
                     record: bool = True) -> PanelProfile:
    """``profile`` carried to ``eye`` (an :class:`Eye` or ``(x, y, D)`` mm): new period and offset,
    the physical block's ``eye_mm`` set to the new eye, 1-sigmas of period and offset propagated
    from the profile's and the physical block's (gap, calibration eye), and, with ``record``, a
    provenance record naming the source profile's.  The subpixel layout, ``views_reversed`` and
    the image flips are kept as they are (module docstring).  ProfileError naming ``source`` when
    the profile has no physical block with a gap and a calibration eye.
    """
    target = Eye.parse(eye, "eye")
    pixel_pitch, gap = _needs(profile, source)
    origin = calibration_eye(profile, source)
    base = dict(slant=profile.slant, period=profile.period, offset=profile.offset,
                reference_view=profile.reference_view)
    shape = dict(views=profile.views, width=profile.width, height=profile.height, pixel_pitch=pixel_pitch)
    period, offset = retarget_constants(**base, **shape, gap=gap, source=origin, target=target)
    offset = math.fmod(offset, period)
    offset = offset + period if offset < 0 else offset
    physical = dict(profile.physical)
    physical["eye_mm"] = target.as_list()
    unc_phys = dict(physical.get("uncertainty") or {})
    unc_phys.pop("eye_mm", None)  # the target eye is what the caller asked for, exactly
    if unc_phys:
        physical["uncertainty"] = unc_phys
    else:
        physical.pop("uncertainty", None)
    uncertainty = _propagate(profile, base, shape, gap, origin, target)
    provenance = make_provenance("retarget", [], source_profile=dict(profile.provenance or {}),
                                 from_eye_mm=origin.as_list(), to_eye_mm=target.as_list()) if record \
        else profile.provenance
    return profile.replace(period=period, offset=offset, physical=physical, uncertainty=uncertainty or None,
                           provenance=provenance)


def _propagate(profile: PanelProfile, base: dict, shape: dict, gap: float, origin: Eye, target: Eye) -> dict:
    """1-sigma of the new period and offset: first-order propagation of every known 1-sigma
    (profile constants, gap, calibration eye) through :func:`retarget_constants`."""
    sigmas: list[tuple[str, float]] = [(k, float(v)) for k, v in (profile.uncertainty or {}).items() if k in base]
    phys = (profile.physical or {}).get("uncertainty") or {}
    if "gap_mm" in phys:
        sigmas.append(("gap", float(phys["gap_mm"])))
    for axis, value in zip(("x", "y", "distance"), phys.get("eye_mm") or ()):
        sigmas.append((f"eye.{axis}", float(value)))
    if not sigmas:
        return {}

    def evaluate(name: str, delta: float) -> np.ndarray:
        args, g, eye = dict(base), gap, origin
        if name in args:
            args[name] += delta
        elif name == "gap":
            g += delta
        else:
            eye = dataclasses.replace(origin, **{name.split(".")[1]: getattr(origin, name.split(".")[1]) + delta})
        return np.array(retarget_constants(**args, **shape, gap=g, source=eye, target=target))

    variance = np.zeros(2)
    for name, sigma in sigmas:
        if sigma > 0:
            step = sigma * 1e-3
            variance += ((evaluate(name, step) - evaluate(name, -step)) / (2 * step) * sigma) ** 2
    out = {k: v for k, v in (profile.uncertainty or {}).items() if k not in ("period", "offset")}
    out["period"], out["offset"] = (float(v) for v in np.sqrt(variance))
    return out


class Retargeter:
    """Per-frame retargeting for a tracked viewer: ``profile_for(eye)`` is plain arithmetic
    (microseconds) and returns the same object while the eye moves less than ``tolerance_views``
    of routing change anywhere on the panel, so encoders that cache per profile rebuild only
    when the routing really changes."""

    def __init__(self, profile: PanelProfile, tolerance_views: float = 0.01, source: str = "profile"):
        _needs(profile, source)
        calibration_eye(profile, source)
        self.base = profile
        self.tolerance = float(tolerance_views)
        self.current: PanelProfile | None = None

    def profile_for(self, eye: Sequence[float] | Eye) -> PanelProfile:
        """The routing for ``eye`` (mm, panel-centred); the cached profile when close enough."""
        new = retarget_profile(self.base, eye, record=False)
        if self.current is not None and routing_difference(self.current, new) <= self.tolerance:
            return self.current
        self.current = new
        return new


def routing_difference(a: PanelProfile, b: PanelProfile) -> float:
    """Largest |w_a - w_b| (views, circular) over the panel's four corners and centre: the
    routing of two profiles of one panel differs by an affine function of (x_s, y), so its
    extremes lie at the corners.  Reversed views change only its sign; a subpixel layout moves
    the slots by a few subpixels, which changes the difference by that few subpixels' share of
    it (negligible against any useful tolerance)."""
    n = a.views
    xs = np.array([0.0, 3 * a.width - 1, 0.0, 3 * a.width - 1, 1.5 * a.width])
    ys = np.array([0.0, 0.0, a.height - 1, a.height - 1, a.height / 2])

    def w(p: PanelProfile) -> np.ndarray:
        return p.reference_view + (3 * p.slant * ys + p.offset - xs) * n / p.period

    d = np.mod(w(a) - w(b) + n / 2, n) - n / 2
    return float(np.max(np.abs(d)))
