"""The library's pipelines called as a library user calls them, without the CLI: a two-distance fit
(``calib.routing.fit_pipeline``), a camera calibration (``calib.intrinsics.pipeline``), encoding to a file
(``render.pipeline.encode_file``); their errors name the argument, and the CLI's mapping of those names to
its flags (``cli.shared.flags``).  Small sizes: a 640x360 panel, a 1200x900 camera, 12 board photos."""

import dataclasses
import json
import shutil
import types

import numpy as np
import pytest

from lenticalib.calib.routing import fit as fit_module
from lenticalib.calib.routing.fit_pipeline import PhysicalOptions, fit_capture_sets
from lenticalib.core.errors import InputError
from lenticalib.core.profile import load_profile

W, H, VIEWS, CAMERA = 640, 360, 8, (1200, 900)
DISTANCES = (400.0, 580.0)


@pytest.fixture(scope="module")
def two_distances(tmp_path_factory):
    """One 640x360 panel photographed by one camera (its true intrinsics as an mrcal model) from 400
    and 580 mm, fitted through ``fit_capture_sets`` with ``PhysicalOptions(second_distance=...)``."""
    import mrcal

    from lenticalib.calib.patterns.calibration_patterns import design_patterns
    from lenticalib.core.pattern_sets import write_patterns
    from lenticalib.sim.capture import simulate_capture_set
    from lenticalib.sim.scene import random_scene

    root = tmp_path_factory.mktemp("pipeline-two-distances")
    write_patterns(root / "patterns", design_patterns(W, H, VIEWS))
    scene = random_scene(7, width=W, height=H, resolution=CAMERA, distance=DISTANCES[0], subsamples=1)
    sets = []
    for distance in DISTANCES:
        cam = scene.camera
        moved = dataclasses.replace(scene, camera=cam.replace(position=(cam.position[0], cam.position[1], -distance)))
        folder = root / f"set-{distance:.0f}"
        shutil.copytree(root / "patterns", folder)
        simulate_capture_set(folder, moved)
        sets.append(folder)
    cam = scene.camera
    model = root / "camera.cameramodel"
    mrcal.cameramodel(intrinsics=("LENSMODEL_OPENCV5", np.array([cam.fx, cam.fy, cam.cx, cam.cy, *cam.distortion])),
                      imagersize=(cam.width, cam.height)).write(str(model))
    (root / "out").mkdir()
    steps, totals = [], []
    run = fit_capture_sets(sets[0], output=root / "out" / "profile.json",
                           physical=PhysicalOptions(camera_model=model, pixel_pitch_mm=scene.optics.pixel_pitch,
                                                    second_distance=sets[1]),
                           progress=steps.append, progress_total=totals.append)
    return types.SimpleNamespace(root=root, scene=scene, sets=sets, model=model, run=run, steps=steps, totals=totals)


def test_a_two_distance_fit_through_the_library_gives_the_gap_and_the_distance(two_distances):
    t = two_distances
    run, optics = t.run, t.scene.optics
    assert run.trusted and run.profile_written
    block = run.profile.physical
    unc = block["uncertainty"]
    assert abs(block["gap_mm"] / optics.gap - 1) < 0.02 and abs(block["gap_mm"] - optics.gap) < 3 * unc["gap_mm"]
    true_eye = np.array([t.scene.camera.position[0], t.scene.camera.position[1], DISTANCES[0]])
    eye = np.array(block["eye_mm"])
    assert abs(eye[2] / true_eye[2] - 1) < 0.01 and np.all(np.abs(eye - true_eye) < 3 * np.array(unc["eye_mm"]))
    assert run.summary["quality"]["physical"]["second_set"] == str(t.sets[1])
    # both fits reported progress, and the total announced first is the number of steps made
    assert t.totals == [len(t.steps)] == [2 * fit_module.progress_steps(fit_module.open_capture_set(t.sets[0]).patterns)]


def test_the_library_fit_writes_the_profile_and_the_report_it_returns(two_distances):
    run = two_distances.run
    out = two_distances.root / "out"
    assert run.profile_path == out / "profile.json" and run.report_dir == out / "profile-report"
    assert load_profile(run.profile_path).to_dict() == run.profile.to_dict()
    assert json.loads((run.report_dir / "summary.json").read_text()) == run.summary
    assert run.summary["output"] == str(run.profile_path)


def test_without_an_output_the_library_fit_writes_nothing(two_distances, monkeypatch, tmp_path):
    """Fit again (the slow fit replaced by the first result): no output, no report, no file anywhere."""
    monkeypatch.setattr(fit_module, "fit_capture_set", lambda *args, **kwargs: dataclasses.replace(
        two_distances.run.result, warnings=[]))
    folder = tmp_path / "set"
    shutil.copytree(two_distances.sets[0], folder)
    before = sorted(p.relative_to(tmp_path) for p in tmp_path.rglob("*"))
    run = fit_capture_sets(folder)
    assert run.profile_path is None and run.report_dir is None and not run.profile_written
    assert run.summary["output"] is None and run.summary["report"] is None
    assert sorted(p.relative_to(tmp_path) for p in tmp_path.rglob("*")) == before


@pytest.mark.parametrize("kwargs, field, words", [
    (dict(physical=PhysicalOptions(pixel_pitch_mm=0.2)), "pixel_pitch_mm", "needs a camera model"),
    (dict(physical=PhysicalOptions(camera_model="{model}")), "camera_model", "pixel_pitch_mm"),
    (dict(physical=PhysicalOptions(camera_model="{model}", pixel_pitch_mm=9.0)), "pixel_pitch_mm", "out of range"),
    (dict(physical=PhysicalOptions(camera_model="{model}", pixel_pitch_mm=0.3, gap_mm=0.0)), "gap_mm", "out of range"),
    (dict(physical=PhysicalOptions(camera_model="{model}", pixel_pitch_mm=0.3, second_distance="{set0}")),
     "second_distance", "same capture set as capture_dir"),
    (dict(physical=PhysicalOptions(camera_model="{model}", pixel_pitch_mm=0.3, gap_mm=1.0, second_distance="{set1}")),
     "gap_mm", "second_distance or gap_mm"),
    (dict(moved_right="{set0}"), "moved_right", "same capture set"),
    (dict(views=1), "views", "out of range"),
])
def test_library_fit_errors_name_the_argument_before_any_fit(two_distances, monkeypatch, kwargs, field, words):
    t = two_distances
    names = {"{model}": str(t.model), "{set0}": str(t.sets[0]), "{set1}": str(t.sets[1])}

    def resolve(value):
        return names.get(value, value) if isinstance(value, str) else value

    if "physical" in kwargs:
        p = kwargs["physical"]
        kwargs = dict(kwargs, physical=dataclasses.replace(
            p, camera_model=resolve(p.camera_model), second_distance=resolve(p.second_distance)))
    kwargs = {k: resolve(v) for k, v in kwargs.items()}

    def no_fit(*args, **kw):
        raise AssertionError("the fit started before the arguments were checked")

    monkeypatch.setattr(fit_module, "fit_capture_set", no_fit)
    with pytest.raises(InputError) as caught:
        fit_capture_sets(t.sets[0], **kwargs)
    assert caught.value.source == field and words in str(caught.value)
    assert "--" not in str(caught.value)  # the library does not speak of command-line flags


def test_the_cli_maps_argument_names_to_its_flags():
    from lenticalib.cli.shared.flags import flag_names, with_flags
    from lenticalib.cli.fit import FLAGS

    error = with_flags(InputError("a camera model gives the pose only with the pitch", source="camera_model",
                                  hint="pass pixel_pitch_mm (the panel's width in mm / its pixels)"), FLAGS)
    assert str(error) == ("--camera: a camera model gives the pose only with the pitch (pass --pixel-pitch MM (the "
                          "panel's width in mm / its pixels))")
    error = with_flags(InputError("32 views is out of range; `seed` and seeds", source="views", hint="use views"),
                       {"views": "--views", "seed": "--seed N"})
    assert str(error) == "--views: 32 views is out of range; --seed N and seeds (use views)"
    with pytest.raises(InputError, match=r"^--gap: give the gap one way \(either --second-distance DIR2 or --gap MM\)$"):
        with flag_names(FLAGS):
            raise InputError("give the gap one way", source="gap_mm", hint="either second_distance or gap_mm")


@pytest.fixture(scope="module")
def board_photos(tmp_path_factory):
    from lenticalib.sim.board_set import simulate_board_set

    folder = tmp_path_factory.mktemp("pipeline-board") / "set"
    folder.mkdir()
    simulate_board_set(folder, kind="print", seed=2, photos=12, resolution=(1280, 960))
    return folder


def test_a_camera_calibration_through_the_library(board_photos, tmp_path):
    from lenticalib.calib.camera.model_file import load_camera_model
    from lenticalib.calib.intrinsics.pipeline import calibrate_camera

    stages = []

    def stage(name, steps):
        record = [name, steps, 0]
        stages.append(record)

        def step(*message):
            record[2] += 1
        return step

    output, report = tmp_path / "camera.cameramodel", tmp_path / "report"
    run = calibrate_camera([board_photos / "captures"], output, report_dir=report, jobs=1, stage=stage)
    assert run.output == output and run.report_dir == report
    assert run.summary["photos"]["used"] == 12 and run.summary["output"] == str(output)
    assert json.loads((report / "summary.json").read_text()) == json.loads(json.dumps(run.summary))
    fitted, truth = load_camera_model(output), load_camera_model(board_photos / "truth.cameramodel")
    np.testing.assert_allclose(fitted.matrix[[0, 1, 0, 1], [0, 1, 2, 2]], truth.matrix[[0, 1, 0, 1], [0, 1, 2, 2]],
                               rtol=0.01)
    from lenticalib.calib.intrinsics.solve import PROGRESS_STEPS

    assert [(name, steps) for name, steps, _ in stages] == [
        ("finding corners", 12), ("solving", PROGRESS_STEPS), ("refining corners in rectified views", 12),
        ("solving with the refined corners", PROGRESS_STEPS), ("cross-validating", 1)]
    assert stages[0][2] == 12 and stages[2][2] == 12 and stages[4][2] == 1


@pytest.mark.parametrize("kwargs, field", [
    (dict(jobs=0), "jobs"),
    (dict(board_corners=(11, 6)), "board_corners"),
    (dict(board_corners=(11, 6), square_mm=-20.0), "square_mm"),
    (dict(lensmodel="LENSMODEL_FISHEYE"), "lensmodel"),
])
def test_camera_calibration_errors_name_the_argument(board_photos, tmp_path, kwargs, field):
    from lenticalib.calib.intrinsics.pipeline import calibrate_camera

    with pytest.raises(InputError) as caught:
        calibrate_camera([board_photos / "captures"], tmp_path / "c.cameramodel", **kwargs)
    assert caught.value.source == field and "--" not in str(caught.value)
    assert not (tmp_path / "c.cameramodel").exists()


def test_encode_to_file_writes_what_encode_makes(tmp_path):
    from lenticalib.core.files.imageio import read_image, write_image
    from lenticalib.core.profile import PanelProfile
    from lenticalib.render.pipeline.encode_file import CompensationOptions, encode_to_file
    from lenticalib.render.encoders import encode

    profile = PanelProfile(views=8, slant=0.19, period=7.4, offset=1.5, reference_view=4, width=160, height=90,
                           subpixel_order="BGR")
    rng = np.random.default_rng(4)
    views = rng.integers(0, 256, (8, 90, 160, 3), dtype=np.uint8)
    (tmp_path / "v").mkdir()
    for i, view in enumerate(views):
        write_image(tmp_path / "v" / f"view-{i}.png", view)
    done = encode_to_file(profile, tmp_path / "out.png", views_dir=tmp_path / "v", encoder="reference")
    np.testing.assert_array_equal(read_image(tmp_path / "out.png"), encode(views, profile, "reference"))
    assert done.summary()["view_size"] == [160, 90] and done.compensate_seconds is None
    with pytest.raises(InputError) as caught:
        encode_to_file(profile, tmp_path / "x.png", views_dir=tmp_path / "v",
                       compensation=CompensationOptions(black_lift=0.1))
    assert caught.value.source == "black_lift" and "crosstalk_file" in str(caught.value)
    assert not (tmp_path / "x.png").exists()


def test_field_paths_in_messages_are_not_taken_for_argument_names():
    from lenticalib.cli.shared.flags import with_flags

    error = with_flags(InputError("field 'physical.gap_mm': 0 is outside 0.0001..50", source="p.json",
                                  hint="either second_distance or gap_mm"), {"gap_mm": "--gap MM",
                                                                             "second_distance": "--second-distance DIR2"})
    assert str(error) == "p.json: field 'physical.gap_mm': 0 is outside 0.0001..50 (either --second-distance DIR2 or --gap MM)"
