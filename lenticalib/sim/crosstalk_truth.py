"""The true crosstalk of a virtual panel: what an eye receives from each view, by ray tracing.

Definitions (``docs/crosstalk.md``): for a profile that routes the panel's subpixels to views,
``M[i][j]`` is the share of the light an eye at the centre of view ``i``'s zone receives from
view ``j`` (rows sum to 1), through the panel's centre region.  The *zone* of view ``i`` is where
that view's subpixels send their light: subpixels the profile gives view ``i`` have true view
coordinates ``w*`` in ``[i - e, i + 1 - e)`` (``e`` the profile's mean error in the region,
``w - w*``), so the zone centre is the eye position with ``w* = i + 0.5 - e``.

The virtual panel's optics do not vary across its width, so ``M`` is circulant; its rows are
measured where the calibration camera stands (so that truth and measurement see the panel at
the same angle): an eye at the centre of the zone next to the camera, ``0.5 - e`` zones to its
right, photographs (with the simulator's own ray kernel, :func:`.render.render_radiance`; no
camera processing) the centre region while the panel shows one view at a time.
"""

from __future__ import annotations

import math

import numpy as np

from ..core.profile import PanelProfile
from ..core.routing import view_coordinate, view_map
from .camera import Camera
from .optics import PanelOptics
from .truth import view_coordinate_truth
from .scene import Scene

CENTRE_FRACTION = 0.4  # the centre region: this fraction of the panel width and height, centred
EYE_PIXELS = (48, 32)  # the eye camera's image, pixels
EYE_SUBSAMPLES = 4


def profile_error(optics: PanelOptics, eye, profile: PanelProfile, fraction: float = CENTRE_FRACTION,
                  samples: int = 64) -> float:
    """Mean circular difference ``w - w*`` (views) over subpixel centres of the centre region (each
    slot's true centre, slot shifts of a subpixel layout included)."""
    n = profile.views
    h, w = optics.height, optics.width
    ys = np.linspace(h * (0.5 - fraction / 2), h * (0.5 + fraction / 2), samples).astype(np.int64)
    xs = np.linspace(3 * w * (0.5 - fraction / 2), 3 * w * (0.5 + fraction / 2), 4 * samples).astype(np.int64)
    yy, xx = np.meshgrid(ys, xs, indexing="ij")
    w_profile = view_coordinate(profile, ys)[:, xs]
    w_true = view_coordinate_truth(optics, eye, xx + optics.slot_shift_at(xx, yy) + 0.5, yy + 0.5, n)
    d = np.mod(w_profile - w_true + n / 2.0, n) - n / 2.0
    return float(np.angle(np.mean(np.exp(2j * math.pi * d / n))) * n / (2 * math.pi))


def eye_camera(optics: PanelOptics, eye, fraction: float = CENTRE_FRACTION) -> Camera:
    """A small distortion-free pinhole at ``eye`` (world mm) whose image is the centre region."""
    width_mm, height_mm = optics.panel_size
    distance = -float(eye[2])
    w_px, h_px = EYE_PIXELS
    fx = w_px * distance / (fraction * width_mm)
    fy = h_px * distance / (fraction * height_mm)
    return Camera(width=w_px, height=h_px, fx=fx, fy=fy, cx=(w_px - 1) / 2, cy=(h_px - 1) / 2,
                  distortion=(0.0, 0.0, 0.0, 0.0, 0.0), position=tuple(float(c) for c in eye),
                  aim=(0.0, 0.0), subsamples=EYE_SUBSAMPLES, jpeg_quality=None)


def _view_raster(views_map: np.ndarray, profile: PanelProfile, view: int) -> np.ndarray:
    h, w = profile.height, profile.width
    raster = np.zeros((h, w, 3), dtype=np.uint8)
    for channel, position in enumerate(profile.rho):
        raster[:, :, channel] = np.where(views_map[:, position::3] == view, 255, 0)
    return raster


def _light(raster: np.ndarray, optics: PanelOptics, eye) -> float:
    from .panel_light import render_radiance

    return float(render_radiance(raster, Scene(optics, eye_camera(optics, eye))).sum(axis=2).mean())


def zone_centre_eye(optics: PanelOptics, camera_eye, profile: PanelProfile, offset: float = 0.0) -> tuple:
    """World position (mm) of an eye ``offset`` zones right of the centre of the zone next to the camera."""
    n = profile.views
    error = profile_error(optics, camera_eye, profile)
    zone = optics.view_zone_width(-float(camera_eye[2]), n)
    ex, ey, ez = (float(c) for c in camera_eye)
    return (ex + (0.5 - error + offset) * zone, ey, ez)


def true_mixing_matrix(optics: PanelOptics, camera_eye, profile: PanelProfile) -> np.ndarray:
    """The true ``M`` (float64 ``(N, N)``, rows sum to 1) for ``profile`` seen from near ``camera_eye``.

    The eye sits at the centre of the zone of view ``c = N/2`` (see the module docstring); the
    light of view ``c + m`` gives ``h[m]`` and ``M[i][j] = h[(j - i) mod N] / sum(h)``.
    """
    n = profile.views
    eye = zone_centre_eye(optics, camera_eye, profile)
    views_map = view_map(profile)
    centre = n // 2
    light = np.array([_light(_view_raster(views_map, profile, (centre + m) % n), optics, eye) for m in range(n)])
    h = light / light.sum()
    index = (np.arange(n)[None, :] - np.arange(n)[:, None]) % n
    return h[index]


def true_view_cone(optics: PanelOptics, camera_eye, profile: PanelProfile, offsets) -> np.ndarray:
    """Share of white's light an eye receives from one view, vs. its offset (views) from that view's zone centre.

    ARGUMENTS
    offsets   float array (k,): eye offsets in views (zone widths) from the zone centre of view N/2

    RETURNED VALUE
    float64 (k,): light of view N/2 over the light of the white panel, at each offset.
    """
    n = profile.views
    views_map = view_map(profile)
    view = _view_raster(views_map, profile, n // 2)
    white = np.full_like(view, 255)
    out = []
    for offset in np.asarray(offsets, np.float64):
        eye = zone_centre_eye(optics, camera_eye, profile, float(offset))
        out.append(_light(view, optics, eye) / _light(white, optics, eye))
    return np.array(out)
