"""The virtual panel: a physically based slanted-lenticular panel photographed by a camera.

It turns any raster the panel would show into the photo a camera would take of it, and knows
the ground truth for the camera position: the profile, the crosstalk, the camera itself
(``docs/optics.md``; overview in ``docs/simulator.md``).  sim may import core, calib and render,
never device or cli.

    optics           PanelOptics (lens sheet, pixel plane, emission), seen point
    truth            the ground truth for an eye: w* by ray tracing, the ideal profile, routing error
    camera           Camera (OpenCV intrinsics + distortion, pose, photometric settings)
    scene            Scene = optics + camera + seed; random_scene(); JSON form
    layouts          subpixel layouts of the virtual panel: RGB, BGR, named cell layouts, JSON files
    panel_light      the numba ray kernel: render_radiance(), the light reaching each camera pixel
    gaussian_cover   a blurred point's light inside an aperture: Gaussian CDF tables for the kernel
    photo            the camera's photometric chain (develop) and photo files: photograph()
    capture          simulate_capture_set(): a pattern folder photographed into DIR/captures
    simulate_folder  simulate_folder(): what ``lenticalib simulate`` runs (pattern or board folder)
    capture_backend  SimCamera: the capture camera ``--camera sim`` (registered in
                     lenticalib.calib.capture.cameras)
    crosstalk_truth  the true mixing matrix and view cone, by ray tracing from an eye
    camera_truth     the true mixing matrix from the camera's own position, the views shifted
    boards           chessboards and ChArUco boards (on the panel or printed) photographed by a
                     known camera
    board_poses      where the simulated boards stand: spread over the image, some cut by the frame
    board_set        simulate_board_set(): a synthetic ``lenticalib camera`` set, truth cameramodel
    driver_video     make_driver_video(): the demo avatar filmed under a known motion, with its true
                     controls (the student driver's demo)

Heavy modules (numba, OpenCV) load on first use of :func:`photograph`; importing the package
loads numpy and ``optics``, ``camera`` and ``scene``.
"""

from __future__ import annotations

from .camera import Camera
from .optics import PanelOptics
from .truth import truth_constants, truth_profile, truth_view_direction, view_coordinate_truth
from .scene import RANGES, Scene, random_scene

__all__ = ["Camera", "PanelOptics", "RANGES", "Scene", "photograph", "photograph_jpeg", "random_scene",
           "render_radiance", "simulate_capture_set", "truth_constants", "truth_profile",
           "truth_view_direction", "view_coordinate_truth"]


def __getattr__(name):
    if name == "render_radiance":
        from .panel_light import render_radiance

        return render_radiance
    if name in ("photograph", "photograph_jpeg"):
        from . import photo

        return getattr(photo, name)
    if name == "simulate_capture_set":
        from .capture import simulate_capture_set

        return simulate_capture_set
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
