"""Which way the view index runs (a profile's ``view_direction``): a pattern to look at, or two fits.

THE PATTERN (:func:`direction_raster`, ``lenticalib patterns --direction``)
Every view with index ``i < N/2`` shows "LEFT" and an arrow pointing left, every view with
``i >= N/2`` "RIGHT" and an arrow pointing right.  If the view index grows as the viewer moves
right (+1), a viewer moving to the right of the panel centre sees RIGHT and one moving left sees
LEFT; if they see LEFT on the right, the direction is -1.

TWO FITS (:func:`direction_from_moved_right`, ``lenticalib fit --moved-right``)

One camera position cannot tell the direction: a fit puts its camera at the view-cone centre
``w* = N/2`` and measures which subpixels that camera sees, and the same set of subpixels is
seen whether the view index grows or falls to the viewer's right.  A second capture set of the
same patterns, taken after moving the camera a few centimetres to the RIGHT at the same
distance, tells it: the view coordinate that the moved camera sees, measured in the *first*
profile, grew (+1) or fell (-1).

THE DERIVATION
Fit ``k`` (k = 1 first position, 2 moved right) gives the routing

    w_k(x_s, y) = i_k + (3 C_k y + s_k - x_s) N / Delta_k

calibrated for its own camera: camera ``k`` sees, under every lens, the subpixels with
``w_k = N/2`` (mod N).  Both fits describe the same lens sheet from the same distance, so
``C_1 = C_2`` and ``Delta_1 = Delta_2`` within their uncertainties, and the two routings differ by
a constant: the rotation of the view cone between the two camera positions.  At the panel
centre ``(x_c, y_c) = (1.5 W, H / 2)`` camera 2 sees the subpixel with ``w_2 = N/2``; in the first
profile's coordinate that subpixel has

    w_1 = N/2 + dw,    dw = w_1(x_c, y_c) - w_2(x_c, y_c)
                          = (s_1 - s_2) N / Delta      (equal i_k = N/2, C_k, Delta_k)

because ``w`` changes with ``s_ref`` by ``N / Delta_r`` views per subpixel.  The offsets are
known only modulo ``Delta`` (so ``dw`` modulo N) and ``dw`` is reduced into ``(-N/2, N/2]``.
``dw > 0``: the camera on the right sees a higher view index of the first profile, so the index
grows as the viewer moves right, ``view_direction = +1``; ``dw < 0`` gives -1.  (On a panel as
docs/optics.md describes it -- raster x to the viewer's right, lenses focused on the pixel
plane -- a move to the right lowers ``s_ref`` and ``dw`` is +1 view per view-zone width moved.)

THE UNCERTAINTY
``sigma = (N / Delta) sqrt(sigma_s1^2 + sigma_s2^2)`` views, from the offsets' 1-sigma in the two
profiles (the offset is the value at the raster origin, extrapolated from the whole panel, so
this is no smaller than the uncertainty at the centre).  The sign is reported only when
``|dw| >= 3 sigma`` (else the camera moved too little) and ``N/2 - |dw| >= 3 sigma`` (else the move
was close to half the view cone, where the reduction modulo N can flip the sign).  A move of
more than half the view cone cannot be recognised at all: it wraps to the opposite sign; move
the camera a few centimetres (about one to three views), not a large part of the cone.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any, Callable

import numpy as np

from ...core.errors import InputError
from ...core.profile import PanelProfile
from ...core.view_direction import with_direction

MIN_SIGMAS = 3.0  # |dw| (and N/2 - |dw|) must exceed this many sigma
VIEW_LONG_SIDE = 960  # pixels of the longer side of a view of the direction pattern
BACKGROUND = 48  # dark grey (sRGB 8-bit) behind the white text
DIRECTION_PATTERN_NAME = "direction.png"


def direction_view_size(profile: PanelProfile) -> tuple[int, int]:
    """(width, height) of the pattern's views: the panel's aspect, the longer side 960 pixels."""
    scale = VIEW_LONG_SIDE / max(profile.width, profile.height)
    return max(1, round(profile.width * scale)), max(1, round(profile.height * scale))


def direction_view(label: str, size: tuple[int, int], index: int | None = None) -> np.ndarray:
    """One view of the pattern: ``label`` ("LEFT" or "RIGHT") in large bold white letters on dark
    grey with a thick arrow pointing that way below it, and ``view i`` small at the bottom.

    RETURNED VALUE
    uint8 ``(height, width, 3)`` RGB.
    """
    import cv2

    width, height = size
    image = np.full((height, width, 3), BACKGROUND, dtype=np.uint8)
    white = (255, 255, 255)
    font = cv2.FONT_HERSHEY_DUPLEX
    # the text takes 70 % of the width or 35 % of the height, whichever is smaller
    (tw, th), _ = cv2.getTextSize(label, font, 1.0, 1)
    scale = min(0.7 * width / tw, 0.35 * height / th)
    thickness = max(1, round(scale * 2.2))
    (tw, th), base = cv2.getTextSize(label, font, scale, thickness)
    cv2.putText(image, label, ((width - tw) // 2, int(0.45 * height)), font, scale, white, thickness, cv2.LINE_AA)
    # the arrow: a bar and a triangular head, from the centre towards the labelled side
    sign = -1 if label == "LEFT" else 1
    cy, half = int(0.68 * height), max(2, round(0.06 * height))
    tail, tip = width // 2 - sign * round(0.3 * width), width // 2 + sign * round(0.3 * width)
    neck = tip - sign * 3 * half
    cv2.rectangle(image, (min(tail, neck), cy - half // 2), (max(tail, neck), cy + half // 2), white, -1)
    head = np.array([[tip, cy], [neck, cy - 2 * half], [neck, cy + 2 * half]], dtype=np.int32)
    cv2.fillPoly(image, [head], white, cv2.LINE_AA)
    if index is not None:
        small = max(0.3, 0.05 * height / 22)
        text = f"view {index}"
        (sw, _), _ = cv2.getTextSize(text, font, small, 1)
        cv2.putText(image, text, ((width - sw) // 2, int(0.93 * height)), font, small, (160, 160, 160),
                    max(1, round(small)), cv2.LINE_AA)
    return image


def direction_views(profile: PanelProfile) -> np.ndarray:
    """The pattern's N views: uint8 ``(N, H_v, W_v, 3)``; view ``i`` says LEFT for ``i < N/2``, else RIGHT."""
    size = direction_view_size(profile)
    n = profile.views
    return np.stack([direction_view("LEFT" if i < n / 2 else "RIGHT", size, i) for i in range(n)])


def direction_raster(profile: PanelProfile, encode: Callable[..., np.ndarray], method: str = "reference") -> np.ndarray:
    """The panel raster of the direction pattern: :func:`direction_views` encoded with ``profile``.

    ARGUMENTS
    profile   the panel
    encode    the encoder entry point, called as ``encode(views, profile, method, allow_stretch=True)``
              -> raster: :func:`lenticalib.render.encoders.encode`.  The caller passes it because the
              calibration layer stands beside the render layer, not on it (it imports only
              ``lenticalib.core``): what the pattern shows is calibration's, turning N views into a
              panel raster is render's, and the command that writes the pattern uses both.
    method    the encoder's name (``reference``: the golden model; the pattern is drawn once)

    RETURNED VALUE
    uint8 ``(height, width, 3)`` RGB, ready for ``lenticalib show``.
    """
    # the views have the panel's aspect up to whole pixels (more than the encoder's 1 % only for a
    # panel with a side of a few pixels): filling the panel with them is what is meant
    return encode(direction_views(profile), profile, method, allow_stretch=True)


@dataclasses.dataclass(frozen=True)
class DirectionEvidence:
    """What the two fits say about the view direction.

    ``direction`` is +1, -1 or None (unknown; ``reason`` says why); ``dw`` and ``sigma`` are in
    views (see the module docstring).
    """

    direction: int | None
    dw: float
    sigma: float | None  # None when a profile has no offset uncertainty
    reason: str | None
    details: dict[str, Any]

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready evidence for the profile's provenance and the fit summary."""
        return {"result": self.direction, "delta_w_views": self.dw, "sigma_views": self.sigma,
                "min_sigmas": MIN_SIGMAS, "reason": self.reason, **self.details}


def _w(profile: PanelProfile, x_s: float, y: float) -> float:
    n = profile.views
    return profile.reference_view + (3.0 * profile.slant * y + profile.offset - x_s) * n / profile.period


def direction_from_moved_right(first: PanelProfile, second: PanelProfile) -> DirectionEvidence:
    """The view direction from a fit at the first camera position and one moved to the right.

    ARGUMENTS
    first    the profile fitted from the first position (its camera at w* = N/2)
    second   the profile fitted from the position moved sideways to the right (same distance)

    RETURNED VALUE
    :class:`DirectionEvidence`; ``direction`` is None (with ``reason``) when ``|dw|`` is below
    ``3 sigma``, within ``3 sigma`` of ``N/2``, or a profile has no offset uncertainty.

    Raises InputError when the two profiles are of different panels, view counts or subpixel
    orders (they cannot be two fits of the same panel).
    """
    if (first.width, first.height, first.views) != (second.width, second.height, second.views):
        raise InputError(f"the two fits describe different panels ({first.width}x{first.height}, {first.views} "
                         f"views vs {second.width}x{second.height}, {second.views} views)", source="moved_right",
                         hint="photograph the same patterns of the same panel from both positions")
    n = first.views
    x_c, y_c = 1.5 * first.width, 0.5 * first.height
    raw = _w(first, x_c, y_c) - _w(second, x_c, y_c)
    dw = raw - n * math.floor(raw / n + 0.5)  # into [-N/2, N/2)
    if dw == -n / 2:
        dw = n / 2
    sig1 = (first.uncertainty or {}).get("offset")
    sig2 = (second.uncertainty or {}).get("offset")
    details: dict[str, Any] = {
        "first": {"offset": first.offset, "offset_sigma": sig1, "period": first.period, "slant": first.slant,
                  "reference_view": first.reference_view, "subpixel_order": first.subpixel_order},
        "moved_right": {"offset": second.offset, "offset_sigma": sig2, "period": second.period,
                        "slant": second.slant, "reference_view": second.reference_view,
                        "subpixel_order": second.subpixel_order},
        "evaluated_at": [x_c, y_c],
    }
    if sig1 is None or sig2 is None:
        return DirectionEvidence(None, float(dw), None, "a fit has no offset uncertainty", details)
    sigma = n / first.period * math.hypot(sig1, sig2)
    reason = None
    if (first.is_stripe, first.subpixel_order) != (second.is_stripe, second.subpixel_order):
        reason = (f"the two fits disagree on the subpixel order ({first.layout_name} vs "
                  f"{second.layout_name}), so one of them is wrong")
    elif abs(dw) < MIN_SIGMAS * sigma:
        reason = (f"the moved camera sees {dw:+.3f} +- {sigma:.3f} views from the first, less than "
                  f"{MIN_SIGMAS:g} sigma: move the camera further to the right")
    elif n / 2 - abs(dw) < MIN_SIGMAS * sigma:
        reason = (f"the moved camera sees {dw:+.3f} +- {sigma:.3f} views from the first, too close to half "
                  f"the view cone ({n / 2:g} views) to tell the sign: move the camera less far")
    direction = None if reason else (1 if dw > 0 else -1)
    return DirectionEvidence(direction, float(dw), float(sigma), reason, details)


def add_moved_right(result, second, second_directory) -> None:
    """Give ``result`` (a :class:`~lenticalib.calib.routing.fit.FitResult`) the direction found with ``second``.

    ``second`` is the fit of the capture set in ``second_directory``, taken after moving the
    camera to the right.  Sets ``result.profile`` to a copy with ``view_direction`` (+1, -1 or
    None) and the evidence in ``provenance["view_direction"]``, ``result.direction`` to the
    evidence (for the fit summary), and appends one warning line to ``result.warnings`` when
    the direction stays unknown.  A second fit that failed a quality gate gives no direction.
    """
    evidence = direction_from_moved_right(result.profile, second.profile)
    if not second.trusted and evidence.direction is not None:
        evidence = dataclasses.replace(evidence, direction=None,
                                       reason="the fit of the moved camera's photos is not trustworthy ("
                                              + "; ".join(second.problems) + ")")
    record = {**evidence.to_dict(), "capture_set": str(second_directory),
              "moved_right_trusted": bool(second.trusted), "moved_right_problems": list(second.problems),
              "moved_right_inputs": (second.profile.provenance or {}).get("inputs", [])}
    result.profile = with_direction(result.profile, evidence.direction,
                                    "moved-right (a second capture set, camera moved to the right)", **record)
    result.direction = {"method": "moved-right", **record}
    if evidence.direction is None:
        result.warnings.append(f"view_direction left unknown: {evidence.reason}")
