"""Guided capture: show -> photograph -> check -> file, with the virtual panel as the camera.

End to end on a virtual display (Xvfb) through the real window presenter, then the fit; resume
after an interruption; retakes of a bad photo; and one-line refusals of bad input.
"""

import json
import shutil

import numpy as np
import pytest

from lenticalib.calib.capture import acquire
from lenticalib.calib.capture.cameras import open_camera
from lenticalib.calib.patterns.capture_sets import load_photo
from lenticalib.calib.routing.compare import compare_profiles
from lenticalib.calib.patterns.calibration_patterns import design_patterns
from lenticalib.core.errors import CaptureError
from lenticalib.core.pattern_sets import write_patterns
from lenticalib.core.profile import load_profile
from lenticalib.render.present.displays import open_presenter

from .cli_support import run_main, run_process
from .display_support import SCREEN

W, H = SCREEN  # the panel is the xvfb fixture's screen
VIEWS = 8
CAMERA = "1200x900"
RAYS = 1  # rays per pixel side of the virtual camera: the fit reads fringe phases over the whole panel


@pytest.fixture(scope="module")
def pattern_dir(tmp_path_factory):
    folder = tmp_path_factory.mktemp("patterns") / "cal"
    write_patterns(folder, design_patterns(W, H, VIEWS))
    return folder


@pytest.fixture(scope="module")
def captured(xvfb, pattern_dir, tmp_path_factory):
    """``lenticalib capture DIR --camera sim:3 --display 0`` on the virtual display, then the fit."""
    folder = tmp_path_factory.mktemp("capture") / "cal"
    shutil.copytree(pattern_dir, folder)
    result = run_process("capture", folder, "--camera", "sim:3", "--display", "0", "--resolution", CAMERA,
                         "--subsamples", str(RAYS), env=xvfb.variables())
    assert result.returncode == 0, result.stderr
    fit = run_main("fit", folder, "-o", folder.parent / "profile.json")  # the fit needs no process of its own
    return folder, result, fit


@pytest.mark.slow
def test_capture_with_the_virtual_camera_then_fit(captured):
    folder, result, fit = captured
    assert "captured 23 photo(s), kept 0 from before, 0 retaken" in result.stdout
    assert sorted(p.name for p in (folder / "captures").iterdir()) == sorted(
        f"{n}.jpg" for n in design_patterns(W, H, VIEWS).names)
    record = json.loads((folder / "simulation.json").read_text())
    assert record["status"] == "complete"
    code, _, err = fit
    assert code == 0, err
    difference = compare_profiles(load_profile(folder.parent / "profile.json"), load_profile(folder / "truth.json"))
    assert difference.order_match
    assert difference.rms <= 0.05 and difference.worst <= 0.15 and abs(difference.centring) <= 0.25, difference


@pytest.mark.slow
def test_the_virtual_camera_photographs_what_the_screen_showed(captured):
    """The scene the capture recorded (the one ``simulate --seed 3`` draws for this panel and
    camera), photographed straight from the pattern PNGs, gives the same photos: the window
    presenter put the patterns on screen unchanged.  (``simulate`` itself: tests/test_sim.py.)"""
    from lenticalib.core.files.imageio import read_image
    from lenticalib.sim.capture import photograph_pattern
    from lenticalib.sim.scene import Scene, random_scene

    folder, _, _ = captured
    scene = Scene.from_dict(json.loads((folder / "simulation.json").read_text()))
    width, height = (int(v) for v in CAMERA.split("x"))
    assert scene.to_dict() == random_scene(3, width=W, height=H, resolution=(width, height),
                                           subsamples=RAYS).to_dict()  # as --subsamples said
    for name in ("x1-0", "f16-2", "order-b"):
        raster = read_image(folder / f"{name}.png")
        assert photograph_pattern(scene, name, raster) == (folder / "captures" / f"{name}.jpg").read_bytes(), name


@pytest.mark.slow
def test_an_interrupted_capture_resumes_where_it_stopped(captured, tmp_path, cli_process):
    folder, _, _ = captured
    again = tmp_path / "cal"
    shutil.copytree(folder, again)
    for name in ("y1-2", "f22-0", "order-r"):
        (again / "captures" / f"{name}.jpg").unlink()
    before = {p.name: p.read_bytes() for p in (again / "captures").iterdir()}
    result = cli_process("capture", again, "--camera", "sim:3", "--display", "none", "--resolution", CAMERA,
                         "--subsamples", str(RAYS))
    assert result.returncode == 0, result.stderr
    assert "captured 3 photo(s), kept 20 from before" in result.stdout
    for name, data in before.items():
        assert (again / "captures" / name).read_bytes() == data  # kept, not retaken
    assert (again / "captures" / "f22-0.jpg").read_bytes() == (folder / "captures" / "f22-0.jpg").read_bytes()
    assert json.loads((again / "simulation.json").read_text())["status"] == "complete"


class _FirstPhotoBlack:
    """A camera that delivers a black photo first for chosen patterns, then what the virtual camera takes."""

    def __init__(self, inner, black):
        self.inner, self.black, self.kind = inner, set(black), "sim"

    def settings(self):
        return self.inner.settings()

    def capture(self, name, shown, destination):
        if name in self.black:
            self.black.discard(name)
            from lenticalib.core.files.imageio import write_image

            return write_image(destination.with_suffix(".png"), np.zeros((900, 1200, 3), np.uint8))
        return self.inner.capture(name, shown, destination)


@pytest.mark.slow
def test_a_bad_photo_is_retaken_at_once_and_kept_aside(pattern_dir, tmp_path):
    folder = tmp_path / "cal"
    shutil.copytree(pattern_dir, folder)
    notes = []
    with open_camera("sim:5", resolution=(1200, 900)) as sim, open_presenter("none", (W, H)) as presenter:
        camera = _FirstPhotoBlack(sim, {"x0-1", "f16-0"})
        report = acquire.capture_set(folder, presenter, camera, settle=0.0, notify=notes.append)
    assert report.retakes == {"x0-1": 1, "f16-0": 1}
    assert len(report.taken) == 23
    assert sorted(p.name for p in (folder / "rejected").iterdir()) == ["f16-0-1.png", "x0-1-1.png"]
    assert any("x0-1.png is black or far too dark: retaking it" in n for n in notes)
    assert not list((folder / "captures").glob("*.png"))


def test_a_photo_that_stays_bad_stops_the_capture_naming_it(pattern_dir, tmp_path):
    class AlwaysBlack(_FirstPhotoBlack):
        def capture(self, name, shown, destination):
            self.black.add(name)
            return super().capture(name, shown, destination)

    folder = tmp_path / "cal"
    shutil.copytree(pattern_dir, folder)
    with open_camera("sim:5", resolution=(1200, 900)) as sim, open_presenter("none", (W, H)) as presenter:
        with pytest.raises(CaptureError, match=r"x0-0\.jpg: is black or far too dark; rejected 2 times"):
            acquire.capture_set(folder, presenter, AlwaysBlack(sim, ()), settle=0.0, retakes=1)
    assert len(list((folder / "rejected").iterdir())) == 2


def test_every_bad_input_ends_in_one_line(xvfb, pattern_dir, tmp_path, cli_process):
    folder = tmp_path / "cal"
    shutil.copytree(pattern_dir, folder)
    foreign = tmp_path / "foreign"
    shutil.copytree(pattern_dir, foreign)
    (foreign / "captures").mkdir()
    (foreign / "captures" / "holiday.jpg").write_bytes(b"x")
    no_gphoto2 = {"PATH": "/nonexistent"}
    big = tmp_path / "big"
    write_patterns(big, design_patterns(800, 600, VIEWS))
    cases = [
        (["capture", folder, "--camera", "polaroid"], None, "--camera: unknown camera kind 'polaroid'"),
        (["capture", folder, "--camera", "opencv:97", "--display", "none"], None, "97"),
        (["capture", folder, "--camera", "gphoto2", "--display", "none"], no_gphoto2, "gphoto2 is not installed"),
        (["capture", tmp_path / "nowhere", "--camera", "sim"], None, "patterns.json"),
        (["capture", foreign, "--camera", "sim", "--display", "none"], None, "holds files that are not photos"),
        (["capture", big, "--camera", "sim", "--display", "0"], xvfb.variables(), "is 640x360"),
        (["capture", folder, "--camera", "sim", "--settle", "-1"], None, "--settle"),
        (["capture", folder, "--camera", "sim", "--subsamples", "0"], None, "--camera sim: option 'subsamples' must be 1..16, got 0"),
        (["capture", folder, "--camera", "opencv:0", "--subsamples", "1"], None,
         "--subsamples: applies only to --camera sim"),
        # the library names its argument (camera, display); the command says its flags
        (["capture", folder, "--camera", "polaroid"], None, "(e.g. --camera opencv:0)"),
        (["capture", folder, "--camera", "sim:x"], None, "--camera: bad seed 'x'"),
        (["capture", folder, "--camera", "manual", "--timeout", "0"], None, "--camera manual: option 'timeout'"),
        (["capture", folder, "--camera", "sim", "--display", "@x"], xvfb.variables(),
         "--display: position '@x' is not @X,Y (e.g. --display @3840,0)"),
    ]
    for args, env, message in cases:
        result = cli_process(*args, env=env, timeout=120)
        assert result.returncode == 2, (args, result.stdout, result.stderr)
        lines = result.stderr.strip().splitlines()
        assert len(lines) == 1 and message in lines[0], (args, result.stderr)
    assert not (folder / "captures").exists() or not any((folder / "captures").iterdir())


@pytest.mark.slow
def test_crosstalk_patterns_are_captured_like_calibration_patterns(captured, tmp_path, cli, cli_process):
    """``crosstalk patterns`` from the fitted profile, then ``capture --camera sim`` (the README's route: no
    seed) shows and photographs them on the virtual panel the profile was fitted on (seed 3, which the fit
    recorded: the same truth), naming it, and ``crosstalk measure`` reads the set (``capture`` runs as a
    real process like the calibration capture; the other two in this one)."""
    folder, _, fit = captured
    code, _, err = fit
    assert code == 0, err
    xt = tmp_path / "xt"
    assert cli("crosstalk", "patterns", "--profile", folder.parent / "profile.json", "-o", xt)[0] == 0
    result = cli_process("capture", xt, "--camera", "sim", "--display", "none", "--resolution", CAMERA,
                         "--subsamples", str(RAYS))
    assert result.returncode == 0, result.stderr
    assert "camera: virtual panel: seed 3 (the panel the patterns' profile was fitted on" in result.stdout
    assert (load_profile(xt / "truth.json").routing_key() == load_profile(folder / "truth.json").routing_key())
    names = sorted(p.stem for p in (xt / "captures").iterdir())
    assert names == sorted(["black", "white", "half-0", "half-1"] + [f"band-{k:02d}" for k in range(10)]
                           + ["level-1in8", "level-1in4", "level-1in2"])
    assert (xt / "crosstalk-truth.json").exists()
    code, _, stderr = cli("crosstalk", "measure", xt, "-o", tmp_path / "crosstalk.json")
    assert code == 0, stderr
    truth = np.asarray(json.loads((xt / "crosstalk-truth.json").read_text())["matrix"])
    data = json.loads((tmp_path / "crosstalk.json").read_text())
    assert len(data["matrix"]) == VIEWS
    assert abs(data["matrix"][0][0] - truth[0, 0]) <= 3 * data["matrix_sigma"][0][0] + 0.005


# ---------------------------------------------------------------------------------------------
# the "unchanged photo" rule at the panel's own size: 3840x2160, 32 views, a small virtual camera
# ---------------------------------------------------------------------------------------------

W4K, H4K, VIEWS_4K = 3840, 2160, 32
SENSOR_4K = (1250, 800)  # the fit's 1 megapixel: the fine fringes are barely resolved
RAYS_4K = 1  # rays per pixel side: the capture's checks judge whole photos, which 3x3 rays only anti-alias


@pytest.fixture(scope="module")
def captured_4k(tmp_path_factory):
    """A 4K pattern set captured by the virtual camera through ``capture_set``."""
    folder = tmp_path_factory.mktemp("capture-4k") / "cal"
    write_patterns(folder, design_patterns(W4K, H4K, VIEWS_4K))
    notes = []
    with open_camera("sim:2", resolution=SENSOR_4K, subsamples=RAYS_4K) as camera, open_presenter("none", (W4K, H4K)) as presenter:
        report = acquire.capture_set(folder, presenter, camera, settle=0.0, notify=notes.append)
    return folder, report, notes


def _check_image(path):
    return acquire.check_image(load_photo(path.stem, path, max_width=acquire.CHECK_WIDTH))


def _photograph(pattern_folder, raster_name, name, path):
    """What the virtual camera of ``captured_4k`` takes of pattern ``raster_name`` of
    ``pattern_folder`` as photo ``name`` (that name's noise), written to ``path``."""
    from lenticalib.core.slides import slides_from_path
    from lenticalib.sim.capture import photograph_pattern
    from lenticalib.sim.scene import random_scene

    scene = random_scene(2, width=W4K, height=H4K, resolution=SENSOR_4K, subsamples=RAYS_4K)
    slide = {s.name: s for s in slides_from_path(pattern_folder)[0]}[raster_name]
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes(photograph_pattern(scene, name, slide.load()))
    return path


@pytest.mark.slow
def test_a_4k_set_is_captured_with_no_photo_taken_for_unchanged(captured_4k):
    """Fine fringes (f16, f22) barely resolved by a 1-megapixel camera still pass: their step is
    judged against two photos of one pattern, not against a fixed share of the light."""
    folder, report, notes = captured_4k
    assert len(report.taken) == 23 and report.retakes == {}, notes
    assert not (folder / "rejected").exists()
    assert (folder / "repeat" / "x0-0.jpg").is_file()  # the first photo, taken again: the noise yardstick
    record = json.loads((folder / "simulation.json").read_text())
    assert record["status"] == "complete" and len(record["captures"]) == 23  # the repeat is not a pattern's photo


@pytest.mark.slow
def test_unchanged_photos_are_rejected_and_fine_steps_pass(captured_4k, tmp_path):
    folder, _, _ = captured_4k
    captures = folder / "captures"
    noise = acquire.change_energy(_check_image(captures / "x0-0.jpg"), _check_image(folder / "repeat" / "x0-0.jpg"))
    assert noise > 0
    for previous, step in (("f16-0", "f16-1"), ("f22-1", "f22-2"), ("x0-0", "x0-1")):
        others = [_check_image(captures / f"{previous}.jpg")]
        size = SENSOR_4K
        # the real next step passes
        assert acquire.photo_problem(step, captures / f"{step}.jpg", size, others, noise, "sim") is None, step
        # an exact repeat of the previous photo, filed as the next step, is rejected
        exact = tmp_path / "exact" / f"{step}.jpg"
        exact.parent.mkdir(exist_ok=True)
        shutil.copyfile(captures / f"{previous}.jpg", exact)
        problem = acquire.photo_problem(step, exact, size, others, noise, "sim")
        assert problem is not None and "same image" in problem.message, step
        # the camera fired before the panel changed: the previous pattern, photographed with new noise
        stale = _photograph(folder, previous, step, tmp_path / "stale" / f"{step}.jpg")
        problem = acquire.photo_problem(step, stale, size, others, noise, "sim")
        assert problem is not None and "no more than two photos of one pattern" in problem.message, step
        assert "focus" not in problem.hint and "virtual camera" in problem.hint  # advice for this camera


@pytest.fixture(scope="module")
def captured_4k_crosstalk(captured_4k):
    """Crosstalk patterns of the 4K capture's true profile, with the longest sweep (1.6 panel widths:
    some bands pass the camera's view nowhere), captured by the same virtual camera."""
    from lenticalib.calib.patterns.crosstalk_patterns import MAX_SWEEP_FRACTION, design_crosstalk_patterns

    folder, _, _ = captured_4k
    xt = folder.parent / "xt"
    pattern_set = design_crosstalk_patterns(load_profile(folder / "truth.json"), MAX_SWEEP_FRACTION * W4K)
    write_patterns(xt, pattern_set)
    notes = []
    with open_camera("sim:2", resolution=SENSOR_4K, subsamples=RAYS_4K) as camera, open_presenter("none", (W4K, H4K)) as presenter:
        report = acquire.capture_set(xt, presenter, camera, settle=0.0, notify=notes.append)
    return xt, pattern_set, report, notes


@pytest.mark.slow
def test_every_crosstalk_band_is_captured_and_a_stale_band_is_not(captured_4k_crosstalk, tmp_path):
    """A band moved by a tenth of the view cone moves little light, yet clearly more than noise; two
    bands the camera sees nowhere give the same dark photo, rightly (the patterns say so); a band
    photographed while the panel still showed the previous one is rejected."""
    from lenticalib.calib.patterns.crosstalk_patterns import seen_columns

    xt, pattern_set, report, notes = captured_4k_crosstalk
    assert len(report.taken) == len(pattern_set.patterns) == 17 and report.retakes == {}, notes
    bands = pattern_set.bands
    unseen = [b.name for b in bands if not seen_columns(pattern_set, b).any()]
    assert len(unseen) >= 2  # the case the capture must not mistake for an unchanged panel
    captures = xt / "captures"
    noise = acquire.change_energy(_check_image(captures / "black.jpg"), _check_image(xt / "repeat" / "black.jpg"))
    for previous, step in zip(bands, bands[1:]):
        if seen_columns(pattern_set, previous).any() or seen_columns(pattern_set, step).any():
            others = [_check_image(captures / f"{previous.name}.jpg")]
            assert acquire.photo_problem(step.name, captures / f"{step.name}.jpg", SENSOR_4K, others, noise,
                                         "sim") is None
            stale = _photograph(xt, previous.name, step.name, tmp_path / f"{step.name}.jpg")
            problem = acquire.photo_problem(step.name, stale, SENSOR_4K, others, noise, "sim")
            assert problem is not None and "same image" in problem.message, step.name
            break
    else:
        pytest.fail("no band is seen by the camera")
