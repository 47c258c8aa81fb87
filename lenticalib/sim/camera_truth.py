"""The true mixing matrix seen from the camera's own position, with the views shifted (issue 51).

:func:`.crosstalk_truth.true_mixing_matrix` puts an eye at the centre of a view's zone, half a
zone (minus the profile's error) beside the camera, and shows one view at a time.  The
measurement instead keeps the camera where it stood and moves the light: the band photos sweep a
one-view band past it.  The two agree if the view cone does not change over half a zone of eye
position (the blur's growth with the angle, the lens' aperture, the angular fall-off all change a
little).  :func:`camera_mixing_matrix` is the other definition, for the bench to compare: the eye
stays at the camera, and view ``j`` lights the subpixels whose profile coordinate ``w`` has
``floor(w - e + 1/2) = j (mod N)`` (``e`` the profile's mean error ``w - w*`` in the centre
region), so that the camera, at ``w* = N/2``, sits at the centre of view ``N/2``'s shifted zone.
"""

from __future__ import annotations

import numpy as np

from ..core.profile import PanelProfile
from ..core.routing import view_coordinate
from .crosstalk_truth import eye_camera, profile_error
from .optics import PanelOptics
from .scene import Scene


def shifted_views(profile: PanelProfile, shift: float) -> np.ndarray:
    """The view each slot shows when every view is moved by ``shift`` views: int64
    ``(H, 3 W)`` indexed ``[y, 3 x + slot]``, ``floor(w - shift) mod N``."""
    w = view_coordinate(profile)
    return np.floor(np.mod(w - shift, profile.views)).astype(np.int64) % profile.views


def camera_mixing_matrix(optics: PanelOptics, camera_eye, profile: PanelProfile) -> np.ndarray:
    """The true ``M`` (float64 ``(N, N)``, circulant, rows sum to 1) seen by an eye at ``camera_eye``
    (world mm) through the centre region, the views shifted so that it sits at a zone centre."""
    from .panel_light import render_radiance  # lazy: numba

    n = profile.views
    views = shifted_views(profile, profile_error(optics, camera_eye, profile) - 0.5)
    scene = Scene(optics, eye_camera(optics, camera_eye))
    centre = n // 2
    light = []
    for m in range(n):
        raster = np.zeros((profile.height, profile.width, 3), dtype=np.uint8)
        for channel, position in enumerate(profile.rho):
            raster[:, :, channel] = np.where(views[:, position::3] == (centre + m) % n, 255, 0)
        light.append(float(render_radiance(raster, scene).sum(axis=2).mean()))
    h = np.asarray(light) / sum(light)
    return h[(np.arange(n)[None, :] - np.arange(n)[:, None]) % n]
