"""The ground truth of a virtual panel for an eye: w* by ray tracing, the ideal profile (``docs/optics.md``).

The truth a calibration is scored against, computed from :class:`~.optics.PanelOptics` by ray
tracing (``view_coordinate_truth``, ``truth_view_direction``) and in closed form
(``truth_constants``, ``truth_profile``); ``routing_error`` compares a profile with it.  Units as
in :mod:`.optics`: world mm, raster subpixels/rows, view coordinates in views.
"""

from __future__ import annotations

import math
from typing import Any, Mapping

import numpy as np

from ..core.errors import InputError
from ..core.profile import PanelProfile
from ..core.routing import view_coordinate
from .optics import PanelOptics


def view_coordinate_truth(optics: PanelOptics, eye, X, Y, views: int) -> np.ndarray:
    """True view coordinate w* (views, in [0, N)) of raster points (X, Y) for an eye at ``eye``.

    Evaluated by ray tracing, independently of the profile formula: the pixel-plane point P at
    (X, Y) is joined to the eye; the lens that line crosses gives a centre line u_c; the chief
    ray from P through u_c reaches the eye plane z = -D at ``u_eye = u_c + (u_c - u_P) D / g``;
    ``w* = N/2 + N (u_eye - u_E) g / (P_u (D + g))`` modulo N.

    ARGUMENTS
    X, Y     continuous raster coordinates (subpixels, rows), any broadcastable shapes;
             a subpixel's centre is (x_s + 0.5, y + 0.5)
    eye      (ex, ey, ez) world mm, ez = -D < 0
    views    N

    RETURNED VALUE
    float64 array of the broadcast shape, reduced into [0, N).
    """
    ex, ey, ez = (float(c) for c in eye)
    distance, g = -ez, optics.gap
    x_p, y_p = optics.raster_to_world(X, Y)
    # The line eye -> P (at z = g) meets z = 0 at fraction D / (D + g) of the way.
    t = distance / (distance + g)
    u_l, _ = optics.to_uv(ex + (x_p - ex) * t, ey + (y_p - ey) * t)
    u_c = optics.lens_centre(optics.lens_index(u_l))
    u_p, _ = optics.to_uv(x_p, y_p)
    u_e, _ = optics.to_uv(ex, ey)
    u_eye = u_c + (u_c - u_p) * distance / g
    w = views / 2.0 + views * (u_eye - u_e) * g / (optics.lens_pitch_u * (distance + g))
    return np.mod(w, views)


def routing_error(optics: PanelOptics, eye, profile: PanelProfile, rows: int = 40, cols: int = 160) -> np.ndarray:
    """w - w* (views, circular, in [-N/2, N/2)) of ``profile`` for an eye at ``eye`` (world mm,
    z < 0) on a ``rows`` x ``cols`` grid of subpixels spread over the whole panel: the profile's
    ``w`` at each subpixel's index (:func:`lenticalib.core.routing.view_coordinate`, slot shifts
    included) against :func:`view_coordinate_truth` at the subpixel's true centre (across the
    lenses: ``x_s + e + 0.5``, ``e`` of :meth:`PanelOptics.slot_shifts`)."""
    n = profile.views
    ys = np.linspace(0, optics.height - 1, rows).astype(np.int64)
    xs = np.linspace(0, 3 * optics.width - 1, cols).astype(np.int64)
    yy, xx = np.meshgrid(ys, xs, indexing="ij")
    w = view_coordinate(profile, ys)[:, xs]
    true_x = xx + optics.slot_shift_at(xx, yy) + 0.5
    return np.mod(w - view_coordinate_truth(optics, eye, true_x, yy + 0.5, n) + n / 2, n) - n / 2


def truth_constants(optics: PanelOptics, eye, views: int) -> dict[str, float]:
    """The ideal routing constants for an eye at ``eye`` (closed form, see :func:`truth_profile`).

    RETURNED VALUE
    dict with ``slant`` (C_r), ``period`` (Delta_r, subpixels), ``offset`` (s_ref in
    [0, Delta_r)) and ``reference_view`` (i_ref = N/2).
    """
    ex, ey, ez = (float(c) for c in eye)
    distance = -ez
    if not distance > 0:
        raise InputError(f"the eye must be in front of the panel (z < 0), got z = {ez}", source="eye")
    g, p = optics.gap, optics.pixel_pitch
    slant = optics.slant
    period = optics.period_at(distance)
    u_e = ex * math.cos(optics.slant_angle) - ey * math.sin(optics.slant_angle)
    # w*(X, Y) = N/2 + (3 C_r Y + s_X - X) N / Delta_r with
    #   s_X = Delta_r (1/2 + x0/P_h - g u_E / (P_u (D + g))) + 1.5 W - 1.5 C_r H   (mod Delta_r);
    # the profile evaluates w at (x_s, y) what w* is at (x_s + 1/2, y + 1/2):
    #   s_ref = s_X + 1.5 C_r - 1/2.
    s_x = (period * (0.5 + optics.x0 / optics.lens_pitch)
           - 3.0 * g * u_e / (distance * p * math.cos(optics.slant_angle))
           + 1.5 * optics.width - 1.5 * slant * optics.height)
    offset = math.fmod(s_x + 1.5 * slant - 0.5, period)
    if offset < 0:
        offset += period
    if offset >= period:  # -tiny + period rounding up
        offset = 0.0
    return {"slant": slant, "period": period, "offset": offset, "reference_view": views / 2.0}


def truth_view_direction(optics: PanelOptics, eye, constants: Mapping[str, float], views: int) -> int:
    """Which way the view index of a profile runs for a viewer near ``eye``: +1 or -1.

    Found by ray tracing, not from the profile formula's sign conventions: an eye at ``eye`` and
    one moved a quarter of a view zone to the right (world +x, same distance) look through the
    same point of the lens plane, the panel centre; :meth:`PanelOptics.seen_point` gives the
    pixel-plane point each sees, :meth:`PanelOptics.world_to_raster` its raster coordinates
    ``(X, Y)``, and the profile ``constants`` (``slant``, ``period``, ``offset``,
    ``reference_view``) its view coordinate ``w(X - 0.5, Y - 0.5)`` (the half-subpixel convention
    of :func:`truth_profile`).  +1 when the moved eye sees a higher ``w`` (the circular difference,
    a quarter view), else -1.  For this model (raster x along world x, lenses focused on the pixel
    plane: ``u_P = u_c + (u_c - u_E) g / D``) it is always +1: moving the eye right moves the seen
    point left, and ``w`` falls to the right.
    """
    ex, ey, ez = (float(c) for c in eye)
    step = 0.25 * optics.view_zone_width(-ez, views)
    n, period = views, constants["period"]
    w = []
    for dx in (0.0, step):
        x_p, y_p = optics.seen_point((ex + dx, ey, ez), 0.0, 0.0)
        X, Y = optics.world_to_raster(x_p, y_p)
        w.append(constants["reference_view"]
                 + (3.0 * constants["slant"] * (float(Y) - 0.5) + constants["offset"] - (float(X) - 0.5)) * n / period)
    d = (w[1] - w[0] + n / 2) % n - n / 2
    return 1 if d > 0 else -1


def truth_profile(optics: PanelOptics, eye, views: int, *, name: str | None = None,
                  provenance: Mapping[str, Any] | None = None) -> PanelProfile:
    """The ideal profile of ``optics`` for a calibration camera at ``eye`` (world mm, z < 0).

    Its ``w(x_s, y)`` equals :func:`view_coordinate_truth` at every subpixel centre
    ``(x_s + 0.5, y + 0.5)`` modulo N, with the camera at ``w* = N/2``; on a panel with a
    subpixel layout the profile carries it, so that the slot shifts ``e`` put ``w`` at the true
    centre ``(x_s + e + 0.5, y + 0.5)`` of every slot (:meth:`PanelOptics.slot_shifts`):
    ``C_r = tan(phi)``, ``Delta_r = 3 P_h (1 + g/D) / p``, ``i_ref = N/2`` and ``s_ref``
    reduced into ``[0, Delta_r)``; ``view_direction`` from :func:`truth_view_direction`.
    """
    constants = truth_constants(optics, eye, views)
    return PanelProfile(views=int(views), width=optics.width, height=optics.height,
                        subpixel_order=optics.subpixel_order, subpixel_layout=optics.subpixel_layout,
                        name=name,
                        view_direction=truth_view_direction(optics, eye, constants, int(views)),
                        provenance=dict(provenance) if provenance else None, **constants)
