"""The fit in millimetres: camera pose, gap from two distances, physical constants, retargeting.

One virtual panel photographed by one camera (fixed intrinsics, the simulator's OpenCV model
written as an mrcal .cameramodel) from 600 and 850 mm; both sets fitted through the library
(``fit_capture_sets`` with ``PhysicalOptions``: what ``lenticalib fit --camera --pixel-pitch
--second-distance`` runs).  Checked against the scene's
truth: the camera's distance (and the lens-sheet magnification's share of it), the gap, lens
pitch, lens position, and the retargeted profile at 400-900 mm against the ray-traced routing.
"""

import dataclasses
import json
import types

import numpy as np
import pytest

from lenticalib.calib.routing.fit_pipeline import PhysicalOptions, fit_capture_sets
from lenticalib.calib.intrinsics.pipeline import calibrate_camera
from lenticalib.core.profile import load_profile
from lenticalib.core.retarget import retarget_profile
from lenticalib.sim.truth import routing_error
from lenticalib.sim.scene import random_scene


# every test reads the two 1920x1080 capture sets and their fit (minutes on two cores)
pytestmark = pytest.mark.slow

DISTANCES = (600.0, 850.0)


def _true_model(camera, path):
    import mrcal

    intrinsics = np.array([camera.fx, camera.fy, camera.cx, camera.cy, *camera.distortion])
    mrcal.cameramodel(intrinsics=("LENSMODEL_OPENCV5", intrinsics), imagersize=(camera.width, camera.height)).write(
        str(path))
    return path


def simulate_two_distances(capture_set, seed=7, distances=DISTANCES):
    """Two capture sets of one 1920x1080, 32-view panel, one camera (same intrinsics) at two distances.

    One ray per sensor pixel (``subsamples=1``; the renderer still integrates each ray's lens blur
    and its neighbouring subpixels analytically): the pose and the gap come from the fringe phase
    over the whole panel, which the 3x3 rays only anti-alias; half the time of the sets and
    of the board photos (``calibrated``), the same checks and tolerances."""
    scene = random_scene(seed, width=1920, height=1080, resolution=(1500, 1000), distance=distances[0],
                         jpeg_quality=90, subsamples=1)
    sets = []
    for distance in distances:
        cam = scene.camera
        moved = dataclasses.replace(scene, camera=cam.replace(position=(cam.position[0], cam.position[1], -distance)))
        sets.append((capture_set(moved, views=32), moved))
    return scene, sets


@pytest.fixture(scope="module")
def two_distances(tmp_path_factory, capture_set):
    root = tmp_path_factory.mktemp("two-distances")
    scene, sets = simulate_two_distances(capture_set)
    model = _true_model(scene.camera, root / "camera.cameramodel")
    out = root / "out"
    out.mkdir()
    run = fit_capture_sets(sets[0][0], output=out / "profile.json",
                           physical=PhysicalOptions(camera_model=model, pixel_pitch_mm=scene.optics.pixel_pitch,
                                                    second_distance=sets[1][0]))
    assert run.trusted and run.profile_written, run.result.problems
    summary = json.loads((out / "profile-report" / "summary.json").read_text())
    return types.SimpleNamespace(scene=scene, sets=sets, profile=load_profile(out / "profile.json"),
                                 summary=summary, root=root, model=model)


def test_the_camera_distance_is_right_and_refers_to_the_lens_surface(two_distances):
    t = two_distances
    optics, camera = t.scene.optics, t.sets[0][1].camera
    true_eye = np.array([camera.position[0], camera.position[1], -camera.position[2]])
    block = t.profile.physical
    eye, sigma = np.array(block["eye_mm"]), np.array(block["uncertainty"]["eye_mm"])
    assert abs(eye[2] - true_eye[2]) / true_eye[2] < 0.01  # the acceptance: within 1 %
    assert np.all(np.abs(eye - true_eye) < 3 * sigma)  # and within its own 3 sigma
    assert np.all(sigma < [1.0, 1.0, 1.0])  # an exactly known camera: sub-millimetre
    # the lens-sheet magnification: read as distance it would put the camera g too far, which
    # is many sigma here (g / D = 0.4 %) -- this check fails without the correction
    pixel_plane = t.summary["quality"]["physical"]["pixel_plane_distance_mm"]
    assert abs(pixel_plane - true_eye[2]) > 5 * sigma[2]
    assert pixel_plane == pytest.approx(true_eye[2] + optics.gap, abs=3 * sigma[2])


def test_the_gap_and_the_lens_sheet_come_out_of_two_distances(two_distances):
    t = two_distances
    optics = t.scene.optics
    block = t.profile.physical
    unc = block["uncertainty"]
    assert abs(block["gap_mm"] / optics.gap - 1) < 0.02  # the acceptance: within 2 %
    assert abs(block["gap_mm"] - optics.gap) < 3 * unc["gap_mm"]
    assert abs(block["lens_pitch_mm"] - optics.lens_pitch) < max(3 * unc["lens_pitch_mm"], 1e-5 * optics.lens_pitch)
    assert block["slant_angle_deg"] == pytest.approx(np.degrees(optics.slant_angle), abs=3 * unc["slant_angle_deg"])
    lens_error = (block["lens_position_mm"] - optics.x0 + optics.lens_pitch / 2) % optics.lens_pitch \
        - optics.lens_pitch / 2
    assert abs(lens_error) < 0.002 * optics.lens_pitch


@pytest.mark.parametrize("distance, lateral", [(400.0, 0.0), (500.0, 40.0), (750.0, -60.0), (900.0, 0.0)])
def test_the_retargeted_profile_meets_the_target(two_distances, distance, lateral):
    t = two_distances
    optics = t.scene.optics
    moved = retarget_profile(t.profile, (lateral, 0.0, distance))
    error = routing_error(optics, (lateral, 0.0, -distance), moved, rows=50, cols=240)
    assert np.sqrt(np.mean(error ** 2)) < 0.05 and np.abs(error).max() < 0.15
    # the profile as fitted would be wrong there by views
    unmoved = routing_error(optics, (lateral, 0.0, -distance), t.profile, rows=50, cols=240)
    assert np.abs(unmoved).max() > 1.0


def test_without_the_gap_the_profile_says_why(two_distances, tmp_path, cli):
    t = two_distances
    code, out, _ = cli("fit", t.sets[1][0], "-o", tmp_path / "p.json", "--camera", t.model,
                       "--pixel-pitch", t.scene.optics.pixel_pitch)
    assert code == 0 and "gap unknown" in out
    block = load_profile(tmp_path / "p.json").physical
    assert "gap_mm" not in block and "eye_mm" not in block and block["pixel_pitch_mm"] > 0
    code, _, err = cli("profile", "retarget", tmp_path / "p.json", "--distance", "700", "-o", tmp_path / "q.json")
    assert code == 2 and "gap" in err and err.count("\n") == 1


@pytest.mark.parametrize("argv, words", [
    (["--pixel-pitch", "0.2"], "needs a camera model"),
    (["--camera", "{model}"], "--pixel-pitch"),
    (["--camera", "{model}", "--pixel-pitch", "9"], "out of range"),
    (["--camera", "{model}", "--pixel-pitch", "0.3", "--second-distance", "{set0}"], "same capture set"),
    (["--camera", "{model}", "--pixel-pitch", "0.3", "--gap", "1", "--second-distance", "{set1}"], "one way"),
])
def test_physical_options_are_checked_before_the_fit(two_distances, tmp_path, cli, argv, words):
    t = two_distances
    names = {"model": str(t.model), "set0": str(t.sets[0][0]), "set1": str(t.sets[1][0])}
    code, _, err = cli("fit", t.sets[0][0], "-o", tmp_path / "p.json", *[a.format(**names) for a in argv])
    assert code == 2 and words in err and err.count("\n") == 1
    assert not (tmp_path / "p.json").exists()


@pytest.fixture(scope="module")
def calibrated(two_distances):
    """The user's path: the same camera calibrated (``calibrate_camera``: what 'lenticalib camera
    calibrate' runs) from 20 simulated photos of a board shown on the same panel, then both sets
    fitted with that model."""
    from lenticalib.sim.board_set import simulate_board_set

    t = two_distances
    boards = t.root / "boards"
    boards.mkdir()
    simulate_board_set(boards, kind="panel", seed=7, photos=20, scene=t.scene)
    model = t.root / "calibrated.cameramodel"
    calibrate_camera([boards / "captures"], model, report_dir=t.root / "camera-report")
    out = t.root / "out-calibrated"
    out.mkdir()
    run = fit_capture_sets(t.sets[0][0], output=out / "profile.json",
                           physical=PhysicalOptions(camera_model=model, pixel_pitch_mm=t.scene.optics.pixel_pitch,
                                                    second_distance=t.sets[1][0]))
    assert run.trusted and run.profile_written, run.result.problems
    return types.SimpleNamespace(profile=load_profile(out / "profile.json"), model=model)


def test_with_a_calibrated_camera_distance_gap_and_retargeting_meet_the_targets(two_distances, calibrated):
    t = two_distances
    optics, camera = t.scene.optics, t.sets[0][1].camera
    block = calibrated.profile.physical
    unc = block["uncertainty"]
    true_eye = np.array([camera.position[0], camera.position[1], -camera.position[2]])
    eye, sigma = np.array(block["eye_mm"]), np.array(unc["eye_mm"])
    assert abs(eye[2] / true_eye[2] - 1) < 0.01
    assert np.all(np.abs(eye - true_eye) < 3 * sigma)
    # the camera's intrinsics uncertainty is part of the pose's (the calibrated model has its inputs)
    assert sigma[2] > np.array(t.profile.physical["uncertainty"]["eye_mm"])[2]
    assert abs(block["gap_mm"] / optics.gap - 1) < 0.02
    for lateral, distance in ((0.0, 400.0), (-60.0, 750.0), (0.0, 900.0)):
        moved = retarget_profile(calibrated.profile, (lateral, 0.0, distance))
        error = routing_error(optics, (lateral, 0.0, -distance), moved, rows=50, cols=240)
        assert np.sqrt(np.mean(error ** 2)) < 0.05 and np.abs(error).max() < 0.15



def test_the_camera_model_records_its_cross_validated_uncertainty(two_distances, calibrated):
    """'camera calibrate' writes the cross-validation scale into the model's note; the loader reads
    it and the intrinsics draws (and so every pose sigma) carry it."""
    from lenticalib.calib.camera.model_file import load_camera_model
    from lenticalib.calib.camera.model_file import NOTE_KEY

    text = calibrated.model.read_text()
    assert NOTE_KEY in text.split("{", 1)[0]
    model = load_camera_model(calibrated.model)
    assert model.uncertainty_scale >= 1.0
    unscaled = dataclasses.replace(model, uncertainty_scale=1.0)
    ratio = model.intrinsics_draws(300, seed=3)[:, 0].std() / unscaled.intrinsics_draws(300, seed=3)[:, 0].std()
    assert ratio == pytest.approx(model.uncertainty_scale, rel=1e-9)
