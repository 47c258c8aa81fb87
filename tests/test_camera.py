"""Camera models for ``fit --camera`` and the camera estimate from panel correspondences."""

from __future__ import annotations

import json
import math

import cv2
import numpy as np
import pytest

from lenticalib.calib.camera.from_panel import estimate_camera, load_camera_model
from lenticalib.core.errors import InputError

MATRIX = np.array([[3100.0, 0, 2010.0], [0, 3100.0, 1490.0], [0, 0, 1]])
DIST = np.array([-0.08, 0.02, 0.0005, -0.0003, 0.0])


def _synthetic_view(seed: int = 3):
    """Panel points (panel pixels, centred) seen by a camera 3300 px in front, off-centre, rolled 2 deg."""
    rng = np.random.default_rng(seed)
    panel = np.column_stack([rng.uniform(-1900, 1900, 3000), rng.uniform(-1060, 1060, 3000)])
    roll = math.radians(2.0)
    rot = cv2.Rodrigues(np.array([0.03, -0.02, roll]))[0]
    centre = np.array([120.0, -80.0, -3300.0])
    tvec = -rot @ centre
    obj = np.column_stack([panel, np.zeros(len(panel))])
    pixels, _ = cv2.projectPoints(obj, cv2.Rodrigues(rot)[0], tvec, MATRIX, DIST)
    return panel, pixels.reshape(-1, 2) + rng.normal(0, 0.05, (len(panel), 2)), centre


def test_pose_from_a_given_model_recovers_the_camera_centre(tmp_path):
    path = tmp_path / "cam.json"
    path.write_text(json.dumps({"camera_matrix": MATRIX.tolist(), "distortion": DIST.tolist(),
                                "image_size": [4000, 3000]}))
    model = load_camera_model(path)
    panel, pixels, centre = _synthetic_view()
    est = estimate_camera(pixels, panel, (4000, 3000), model)
    assert est["reprojection_rms_px"] < 0.2
    assert np.allclose(est["centre_panel_px"], centre, atol=2.0)
    assert est["source"] == str(path)


def test_estimate_without_model_fits_the_distortion():
    panel, pixels, _ = _synthetic_view()
    est = estimate_camera(pixels, panel, (4000, 3000))
    assert est["reprojection_rms_px"] < 1.0
    assert est["distortion"][0] < 0  # barrel, like the truth
    assert est["note"]  # near-frontal: the focal length is flagged as poorly determined


def _mrcal_calibrated_model(path, seed=1):
    """A real .cameramodel written by mrcal from its own synthetic board calibration (30 frames,
    0.3 px noise): LENSMODEL_OPENCV4 with optimization_inputs."""
    import mrcal
    import numpysane as nps

    truth = mrcal.cameramodel(intrinsics=("LENSMODEL_OPENCV4", np.array([1500., 1502., 800., 600., -0.1, 0.03, 1e-3,
                                                                          -5e-4])), imagersize=(1600, 1200))
    q, _ = mrcal.synthesize_board_observations(
        [truth], object_width_n=12, object_height_n=9, object_spacing=20.0, calobject_warp=None,
        rt_ref_boardcenter=np.array([0, 0, 0, 0, 0, 500.]),
        rt_ref_boardcenter__noiseradius=np.array([0.5, 0.5, 0.3, 150, 120, 150.]), Nframes=30)
    q = q + np.random.default_rng(seed).normal(0, 0.3, q.shape)
    obs = nps.glue(q, np.ones(q.shape[:-1] + (1,)), axis=-1)[:, 0]
    n = len(obs)
    idx = np.column_stack([np.arange(n), np.zeros(n, int), -np.ones(n, int)]).astype(np.int32)
    sizes = np.array([[1600, 1200]], np.int32)
    intr, _, rt_ref_frame = mrcal.seed_stereographic(imagersizes=sizes, focal_estimate=1500.,
                                                     indices_frame_camera=idx[:, :2].copy(), observations=obs,
                                                     object_spacing=20.0)
    common = dict(observations_board=obs, indices_frame_camintrinsics_camextrinsics=idx, imagersizes=sizes,
                  calibration_object_spacing=20.0, do_optimize_calobject_warp=False, rt_cam_ref=None)
    for core in (False, True):
        mrcal.optimize(intrinsics=intr, rt_ref_frame=rt_ref_frame, lensmodel="LENSMODEL_STEREOGRAPHIC",
                       do_optimize_intrinsics_core=core, do_optimize_intrinsics_distortions=False,
                       do_apply_regularization=False, do_apply_outlier_rejection=False, **common)
    oi = dict(points=None, observations_point=None, indices_point_camintrinsics_camextrinsics=None,
              calobject_warp=None, intrinsics=np.concatenate([intr, np.zeros((1, 4))], axis=1),
              rt_ref_frame=rt_ref_frame, lensmodel="LENSMODEL_OPENCV4", do_optimize_intrinsics_core=True,
              do_optimize_intrinsics_distortions=True, do_optimize_frames=True, do_optimize_extrinsics=False,
              do_apply_regularization=True, do_apply_outlier_rejection=True,
              **{k: v for k, v in common.items() if k != "do_optimize_calobject_warp"}, do_optimize_calobject_warp=False)
    mrcal.optimize(**oi)
    mrcal.cameramodel(optimization_inputs=oi, icam_intrinsics=0).write(str(path))
    return truth


def test_opencv_yaml_model(tmp_path):
    yaml_path = str(tmp_path / "cam.yaml")
    fs = cv2.FileStorage(yaml_path, cv2.FILE_STORAGE_WRITE)
    fs.write("camera_matrix", MATRIX)
    fs.write("distortion_coefficients", DIST.reshape(1, -1))
    fs.release()
    model = load_camera_model(yaml_path)
    assert np.allclose(model.matrix, MATRIX) and np.allclose(model.distortion, DIST)
    assert model.lensmodel == "LENSMODEL_OPENCV5" and model.intrinsics_draws(3) is None


def test_a_real_mrcal_model_with_optimization_inputs_is_read_by_mrcal(tmp_path):
    path = tmp_path / "cam.cameramodel"
    truth = _mrcal_calibrated_model(path)
    text = path.read_text()
    # the base85 optimization_inputs hold '#' characters: a comment-stripping parser would break here
    assert "#" in text.split("optimization_inputs", 1)[1]
    model = load_camera_model(path)
    assert model.lensmodel == "LENSMODEL_OPENCV4" and model.image_size == (1600, 1200)
    assert model.optimization_inputs is not None
    assert np.allclose(model.intrinsics[:4], truth.intrinsics()[1][:4], rtol=3e-3)
    # normalised rays agree with the truth to the calibration's accuracy
    q = np.array([[800.0, 600.0], [100.0, 100.0], [1500.0, 1100.0]])
    import mrcal

    v = mrcal.unproject(q, *truth.intrinsics())
    assert np.abs(model.normalized(q) - v[:, :2] / v[:, 2:]).max() < 3e-3
    # intrinsics draws: the spread of the focal length is the calibration's, and the truth lies inside it
    draws = model.intrinsics_draws(400, seed=2)
    sigma_f = draws[:, 0].std()
    assert 0.1 < sigma_f < 5.0
    assert abs(model.intrinsics[0] - 1500.0) < 4 * sigma_f


@pytest.mark.parametrize("content, name, words", [
    (None, "missing.json", "not found"),
    ("{not json", "bad.json", "cannot read"),
    ("{'lensmodel': 'LENSMODEL_SPLINED_STEREOGRAPHIC_order=3_Nx=16_Ny=12_fov_x_deg=100', "
     "'intrinsics': [1, 1, 1, 1], 'imagersize': [10, 10]}", "splined.cameramodel", "cannot read"),
    ("__import__('os').system('echo hacked')", "evil.cameramodel", "cannot read"),
    ("truncated", "cut.cameramodel", "cannot read"),
])
def test_bad_camera_models_are_refused_with_the_file_named(tmp_path, content, name, words):
    path = tmp_path / name
    if content is not None:
        path.write_text(content)
    with pytest.raises(InputError) as info:
        load_camera_model(path)
    assert str(path) in str(info.value) and words in str(info.value)
    assert "\n" not in str(info.value)


def test_a_cut_real_model_is_one_line(tmp_path, cli):
    path = tmp_path / "cam.cameramodel"
    _mrcal_calibrated_model(path)
    path.write_text(path.read_text()[: len(path.read_text()) // 2])
    code, _, err = cli("fit", tmp_path, "-o", tmp_path / "p.json", "--camera", path, "--pixel-pitch", "0.2")
    assert code == 2 and err.count("\n") == 1 and str(path) in err and "cannot read" in err


def test_without_mrcal_a_cameramodel_is_refused_saying_how_to_install(tmp_path, monkeypatch):
    import sys

    from lenticalib.core.errors import BackendUnavailableError

    path = tmp_path / "cam.cameramodel"
    path.write_text("{'lensmodel': 'LENSMODEL_PINHOLE', 'intrinsics': [1, 1, 1, 1], 'imagersize': [2, 2]}")
    monkeypatch.setitem(sys.modules, "mrcal", None)  # import mrcal raises ImportError
    with pytest.raises(BackendUnavailableError) as info:
        load_camera_model(path)
    assert "--no-deps mrcal==2.5.2.post1" in str(info.value) and str(path) in str(info.value)
