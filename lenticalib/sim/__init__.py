"""The virtual panel: a physically based slanted-lenticular panel photographed by a camera.

It turns any raster the panel would show into the photo a camera would take of it, and knows
the ground-truth profile for the camera position (``docs/optics.md``; overview in ``docs/simulator.md``).

    optics    PanelOptics (lens sheet, pixel plane, emission), seen point, w*, truth profile
    camera    Camera (OpenCV intrinsics + distortion, pose, photometric settings)
    scene     Scene = optics + camera + seed; random_scene(); JSON form
    render    numba ray kernel and the camera's photometric chain: photograph()
    capture   simulate_capture_set(): photograph a pattern folder into DIR/captures
    capture_camera  SimCamera: the capture camera ``--camera sim`` (registered in lenticalib.calib.cameras)

Heavy modules (numba, OpenCV) load on first use of :func:`photograph`.
"""

from __future__ import annotations

from .camera import Camera
from .optics import PanelOptics, truth_constants, truth_profile, truth_view_direction, view_coordinate_truth
from .scene import RANGES, Scene, random_scene

__all__ = ["Camera", "PanelOptics", "RANGES", "Scene", "photograph", "photograph_jpeg", "random_scene",
           "render_radiance", "simulate_capture_set", "truth_constants", "truth_profile",
           "truth_view_direction", "view_coordinate_truth"]


def __getattr__(name):
    if name in ("photograph", "photograph_jpeg", "render_radiance"):
        from . import render

        return getattr(render, name)
    if name == "simulate_capture_set":
        from .capture import simulate_capture_set

        return simulate_capture_set
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
