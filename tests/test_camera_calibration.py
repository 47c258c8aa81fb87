"""``lenticalib camera``: boards, corner labelling, the mrcal solve against synthetic ground truth, the CLI.

The two ground-truth tests photograph a board 24 times with a known simulated camera (OpenCV
k1 k2 p1 p2 k3 distortion, defocus, Bayer noise, JPEG), calibrate through the library (``calibrate_camera``), read the written
.cameramodel back and compare its projections with the truth's over a 40 x 30 grid of the image,
normalised by mrcal's own predicted 2 x 2 covariance (the "mean-pcam" reference: see
lenticalib.calib.intrinsics.quality.compare_to_truth).  A correct calibration with a correct
uncertainty puts that Mahalanobis distance below 3 at ~99 % of the points.
"""

import json
import shutil
import os

import numpy as np
import pytest

from lenticalib.calib.intrinsics import board as boards
from lenticalib.calib.intrinsics.corners import grey8, orient
from lenticalib.calib.intrinsics.pipeline import calibrate_camera
from lenticalib.calib.intrinsics.quality import compare_to_truth
from lenticalib.calib.camera.model_file import write_cameramodel
from lenticalib.calib.intrinsics.solve import OPENCV5, OPENCV8, Solve, choose
from lenticalib.sim.board_set import read_truth_poses, simulate_board_set

import mrcal  # noqa: E402  (a requirement of 'lenticalib camera')

from .cli_support import one_error_line, run_main

RESOLUTION = (1280, 960)


def _calibrated(tmp_path_factory, kind):
    folder = tmp_path_factory.mktemp(kind) / "set"
    folder.mkdir()
    simulate_board_set(folder, kind=kind, seed=1, photos=24, resolution=RESOLUTION)
    model, report = folder / "camera.cameramodel", folder / "report"
    run = calibrate_camera([folder / "captures"], model, report_dir=report)  # what 'camera calibrate' runs
    return folder, model, report, json.loads(json.dumps(run.summary))  # as --json prints it


@pytest.fixture(scope="module")
def printed(tmp_path_factory):
    return _calibrated(tmp_path_factory, "print")


@pytest.fixture(scope="module")
def shown(tmp_path_factory):
    return _calibrated(tmp_path_factory, "panel")


def _three_sigma_check(folder, model_path, summary):
    """The solved model (read back from disk) against the truth: (near, far) comparison dicts."""
    model = mrcal.cameramodel(str(model_path))
    truth = mrcal.cameramodel(str(folder / "truth.cameramodel"))
    poses = read_truth_poses(folder)
    rt = np.array([poses[os.path.basename(p)] for p in summary["photos"]["frames"]])
    near = compare_to_truth(model, truth, rt, summary["working_distance_mm"])
    far = compare_to_truth(model, truth, rt, None)
    for c in (near, far):
        assert np.mean(c["normalised"] < 3.0) >= 0.95, np.percentile(c["normalised"], [50, 95, 100])
        assert np.median(c["stdev"]) < 0.5  # the uncertainty is a real constraint...
        assert np.median(c["normalised"]) > 0.1  # ...and not inflated so much that every error looks tiny
    return near, far


@pytest.mark.slow
def test_printed_board_intrinsics_are_within_their_uncertainty(printed):
    folder, model_path, _, summary = printed
    assert summary["photos"]["used"] == 24 and summary["photos"]["rejected"] == []
    assert summary["lensmodel"] in (OPENCV5, OPENCV8)  # the truth is OPENCV5: the splined model must not pay for itself
    assert summary["residuals"]["rms_px"] < 0.05
    near, far = _three_sigma_check(folder, model_path, summary)
    assert np.max(np.abs(near["error"])) < 1.0  # pixels, anywhere in the image


@pytest.mark.slow
def test_panel_shown_board_intrinsics_are_unbiased(shown):
    """Seen through the lens sheet the board is a rigid board in the pixel plane (z = +g): modelled
    there, the intrinsics come out within their uncertainty, and the solved board poses are those of
    the pixel plane, not of the lens surface g nearer."""
    folder, model_path, _, summary = shown
    assert summary["photos"]["used"] == 24
    assert summary["board"]["kind"] == "panel"
    _three_sigma_check(folder, model_path, summary)
    model = mrcal.cameramodel(str(model_path))
    sim = json.loads((folder / "simulation.json").read_text())
    gap = sim["optics"]["gap"]
    board = boards.read_board(folder / "board.json")
    centre = np.array([(board.cols - 1) * board.square_mm / 2, (board.rows - 1) * board.square_mm / 2, 0.0])
    poses = read_truth_poses(folder)
    rt_true = np.array([poses[os.path.basename(p)] for p in summary["photos"]["frames"]])
    fit = mrcal.transform_point_rt(model.optimization_inputs()["rt_ref_frame"], centre)
    true = mrcal.transform_point_rt(rt_true, centre)
    offset = np.mean(np.linalg.norm(fit, axis=-1) - np.linalg.norm(true, axis=-1))
    assert abs(offset) < 0.3 * gap, (offset, gap)


@pytest.mark.slow
def test_calibrate_writes_a_real_cameramodel_and_a_report(printed):
    folder, model_path, report, summary = printed
    model = mrcal.cameramodel(str(model_path))
    assert model.intrinsics()[0] == summary["lensmodel"]
    assert tuple(model.imagersize()) == RESOLUTION
    oi = model.optimization_inputs()
    assert oi is not None and oi["observations_board"].shape == (24, 6, 11, 3)
    assert model_path.read_text().startswith("# lenticalib camera calibrate")
    from PIL import Image

    for name, size in (("residuals.png", (1800, 1200)), ("coverage.png", (1800, 1200)),
                       ("uncertainty.png", (1800, 860))):
        with Image.open(report / name) as img:
            assert img.size == size
    from lenticalib.core.figures import read_figure_record

    coverage = read_figure_record(report / "coverage.png")["axes"][0]
    assert f"{100 * summary['coverage']:.0f}% of the 8x6 grid" in coverage["title"]
    assert ("cell with no corner" in coverage["legend"]) == (summary["coverage"] < 1.0)  # the empty cells shown
    on_disk = json.loads((report / "summary.json").read_text())
    assert on_disk["intrinsics"] == summary["intrinsics"]
    inputs = on_disk["provenance"]["inputs"]
    assert len(inputs) == 25 and all(len(i["sha256"]) == 64 for i in inputs)  # 24 photos + board.json
    unc = summary["uncertainty"]["at_working_distance"]
    assert 0 < unc["centre"] < unc["worst"] < 1.0
    assert {c["lensmodel"] for c in summary["candidates"]} >= {OPENCV5, OPENCV8}


@pytest.mark.slow
def test_corner_labels_do_not_depend_on_the_detector_order(printed):
    """Any labelling of the grid (from either end, mirrored) is turned back into the drawn one."""
    folder = printed[0]
    board = boards.read_board(folder / "board.json")
    from lenticalib.core.files.imageio import read_image

    grey = grey8(read_image(folder / "captures" / "board-01.jpg"))
    rt = read_truth_poses(folder)["board-01.jpg"]
    truth = mrcal.cameramodel(str(folder / "truth.cameramodel"))
    q = mrcal.project(mrcal.transform_point_rt(rt, board.object_points()), *truth.intrinsics())
    for variant in (q, q[::-1, ::-1], q[:, ::-1], q[::-1, :]):
        np.testing.assert_array_equal(orient(variant.copy(), grey, symmetric=False), q)
        # a board that looks the same after a half turn: labelled with its first row left to right
        np.testing.assert_array_equal(orient(variant.copy(), grey, symmetric=True), q)


def test_the_splined_model_must_pay_for_its_parameters():
    rng = np.random.default_rng(0)
    shape = (20, 6, 11, 2)
    noise = rng.normal(0, 0.1, shape)
    inlier = np.ones(shape[:3], bool)

    def solve(name, residuals, n):
        return Solve(name, {"intrinsics": np.zeros((1, n)), "do_optimize_intrinsics_core": True,
                            "observations_board": np.ones(shape[:3] + (3,))}, residuals, inlier, 0.0)

    small = solve(OPENCV8, noise, 12)
    big_slightly_better = solve("SPLINED", noise * 0.97, 250)
    big_much_better = solve("SPLINED", noise * 0.5, 250)
    assert choose(small, big_slightly_better)[0] is small
    assert choose(small, big_much_better)[0] is big_much_better


def test_write_cameramodel_leaves_an_earlier_file_when_it_fails(tmp_path):
    path = tmp_path / "camera.cameramodel"
    model = mrcal.cameramodel(intrinsics=("LENSMODEL_OPENCV5", np.array([900.0, 900, 639.5, 479.5, 0, 0, 0, 0, 0])),
                              imagersize=RESOLUTION)
    write_cameramodel(model, path, note="first")
    before = path.read_text()

    class Broken:
        def write(self, f, note=None):  # mrcal's writer, given a file object, fails half way
            f.write("half a mod")
            raise RuntimeError("disk went away")

    with pytest.raises(RuntimeError):
        write_cameramodel(Broken(), path)
    assert path.read_text() == before and sorted(p.name for p in tmp_path.iterdir()) == ["camera.cameramodel"]
    assert mrcal.cameramodel(str(path)).intrinsics()[1][0] == 900.0


def test_camera_patterns_writes_the_panel_and_the_printable_boards(tmp_path, cli):
    out = tmp_path / "boards"
    code, stdout, err = cli("camera", "patterns", "-o", out, "--panel", "1920x1080", "--pixel-pitch", "0.36")
    assert code == 0, err
    manifest = json.loads((out / "board.json").read_text())
    assert manifest["format"] == "lenticalib.camera-board" and manifest["format_version"] == 1
    assert manifest["kind"] == "panel" and (manifest["cols"], manifest["rows"]) == (15, 8)
    assert manifest["panel"] == {"width": 1920, "height": 1080, "pixel_pitch_mm": 0.36}
    assert manifest["square_mm"] == pytest.approx(manifest["square_px"] * 0.36, abs=1e-9)
    from lenticalib.core.files.imageio import read_image

    raster = read_image(out / "board.png")
    assert raster.shape == (1080, 1920, 3) and raster.dtype == np.uint8
    (x0, y0), s = manifest["origin_px"], manifest["square_px"]
    assert 0.75 <= 16 * s / 1920 <= 0.8 and 0.75 <= 9 * s / 1080 <= 0.8
    assert raster[y0 - s // 2, x0 - s // 2, 0] == 0 and raster[y0 - s // 2, x0 + s // 2, 0] == 255  # as drawn
    assert raster[5, 5, 0] == 255  # white margin
    for name in ("board-print.pdf", "board-print.png", "board.json"):
        assert (out / "print" / name).stat().st_size > 0
    sheet = json.loads((out / "print" / "board.json").read_text())
    assert sheet["kind"] == "print" and sheet["square_mm"] == 20.0 and (sheet["cols"] + sheet["rows"]) % 2 == 1
    from PIL import Image

    with Image.open(out / "print" / "board-print.png") as img:  # A4 at 300 dpi
        assert abs(img.size[0] - 297 / 25.4 * 300) <= 1 and abs(img.size[1] - 210 / 25.4 * 300) <= 1
    # the pitch from a profile's physical block
    profile = {"views": 8, "slant": 0.19, "period": 7.4, "offset": 1.5, "reference_view": 4, "width": 1920,
               "height": 1080, "subpixel_order": "BGR", "physical": {"pixel_pitch_mm": 0.36}}
    (tmp_path / "panel.json").write_text(json.dumps(profile))
    code, _, err = cli("camera", "patterns", "-o", tmp_path / "b2", "--profile", tmp_path / "panel.json")
    assert code == 0, err
    assert json.loads((tmp_path / "b2" / "board.json").read_text())["square_mm"] == manifest["square_mm"]


def _expect_error(argv, *fragments, absent=()):
    code, out, err = run_main(*argv)
    assert code == 2, (code, out, err)
    line = one_error_line(err)
    for fragment in fragments:
        assert fragment in line, (fragment, line)
    for path in absent:
        assert not os.path.lexists(path), path


def _blank_photos(folder, n, size=RESOLUTION):
    import cv2

    folder.mkdir(parents=True, exist_ok=True)
    img = np.full((size[1], size[0]), 128, np.uint8)
    for k in range(n):
        cv2.imwrite(str(folder / f"blank-{k:02d}.jpg"), img)


@pytest.mark.slow
def test_camera_errors_are_one_line_before_any_work(tmp_path, printed):
    folder = printed[0]
    captures = folder / "captures"
    out = tmp_path / "cam.cameramodel"
    calibrate = ["camera", "calibrate", "--jobs", "1"]
    _expect_error(calibrate + [tmp_path / "nowhere", "-o", out], "no such file or folder", absent=[out])
    _expect_error(calibrate + [captures, "-o", out, "--board", "11by6", "--square", "20"], "must be COLSxROWS in inner corners")
    _expect_error(calibrate + [captures, "-o", out, "--board", "11x6"], "needs both")
    _expect_error(calibrate + [captures, "-o", out, "--board", "11x6", "--square", "-20"], "out of range",
                  "--square")
    _expect_error(calibrate + [captures, "-o", out, "--lensmodel", "LENSMODEL_FISHEYE"], "unknown lens model")
    _expect_error(calibrate + [captures, "-o", tmp_path / "missing" / "c.cameramodel"], "does not exist")
    _expect_error(calibrate + [captures, "-o", tmp_path], "is a folder")
    loose = tmp_path / "loose"
    _blank_photos(loose, 12)
    _expect_error(calibrate + [loose, "-o", out], "no board geometry", "--board COLSxROWS")
    _expect_error(calibrate + [loose / "blank-00.jpg", loose / "blank-01.jpg", "-o", out, "--board", "11x6",
                               "--square", "20"], "only 2 photos given", "at least 10")
    (loose / "blank-05.jpg").write_bytes(b"not a jpeg at all")
    _expect_error(calibrate + [loose, "-o", out, "--board", "11x6", "--square", "20"], "blank-05.jpg",
                  "not a readable photo", absent=[out])
    patterns = ["camera", "patterns", "-o", tmp_path / "b"]
    _expect_error(patterns + ["--panel", "1920x1080"], "pixel pitch", "--pixel-pitch", absent=[tmp_path / "b"])
    _expect_error(patterns + ["--panel", "1920x1080", "--pixel-pitch", "0.3", "--squares", "15x9"],
                  "--squares: a 15x9 board", "half turn")  # the library's squares, as the flag
    profile = {"views": 8, "slant": 0.19, "period": 7.4, "offset": 1.5, "reference_view": 4, "width": 1920,
               "height": 1080, "subpixel_order": "BGR"}
    (tmp_path / "panel.json").write_text(json.dumps(profile))
    _expect_error(patterns + ["--profile", tmp_path / "panel.json"], "does not give the panel's pixel pitch")
    _expect_error(["camera", "simulate", tmp_path / "s", "--resolution", "12x9"], "out of range",
                  absent=[tmp_path / "s"])


@pytest.mark.slow
def test_too_few_boards_fail_before_the_solve_with_the_counts(tmp_path, printed, monkeypatch):
    """3 photos with the board and 9 without: refused after detection, before any solve."""
    folder = printed[0]
    photos = tmp_path / "captures"
    _blank_photos(photos, 9)
    for k in (1, 2, 3):
        (photos / f"board-{k:02d}.jpg").write_bytes((folder / "captures" / f"board-{k:02d}.jpg").read_bytes())
    import lenticalib.calib.intrinsics.solve as solve

    def no_solve(*args, **kwargs):
        raise AssertionError("the solve must not start")

    monkeypatch.setattr(solve, "calibrate", no_solve)
    out = tmp_path / "cam.cameramodel"
    _expect_error(["camera", "calibrate", photos, "-o", out, "--board", "11x6", "--square", "20",
                   "--jobs", "1"], "found in 3 of 12 photos", "at least 10", "tilt", absent=[out])


def test_lenticalib_simulate_photographs_the_board_of_a_camera_patterns_folder(tmp_path, cli):
    from lenticalib.calib.camera.model_file import load_camera_model

    folder = tmp_path / "board"
    code, out, err = cli("camera", "patterns", "-o", folder, "--panel", "1920x1080", "--pixel-pitch", "0.36",
                         "--lens-pitch", "1.9")
    assert code == 0, err
    code, out, err = cli("simulate", folder, "--seed", 4, "--photos", 12, "--resolution", "1280x960")
    assert code == 0, err
    assert len(list((folder / "captures").glob("board-*.jpg"))) == 12
    doc = json.loads((folder / "simulation.json").read_text())
    assert doc["optics"]["width"] == 1920 and doc["optics"]["pixel_pitch"] == pytest.approx(0.36)
    code, out, err = cli("camera", "calibrate", folder / "captures", "-o", tmp_path / "c.cameramodel")
    assert code == 0, err
    fitted, truth = load_camera_model(tmp_path / "c.cameramodel"), load_camera_model(folder / "truth.cameramodel")
    assert np.allclose(fitted.intrinsics[:2], truth.intrinsics[:2], rtol=0.01)
    for argv, words in ((["simulate", folder / "print"], "printed board"),
                        (["simulate", folder, "--distance", 500], "--distance"),
                        (["simulate", folder, "--photos", 1], "--photos")):
        code, out, err = cli(*argv)
        assert code == 2 and words in err and err.count("\n") == 1


@pytest.mark.slow
def test_the_model_never_replaces_a_photo_or_the_board_and_an_empty_photo_is_named(printed, tmp_path):
    """``-o`` naming one of the inputs (a photo, board.json) is refused before the corner search,
    the file untouched; an empty photo among the others is one clear error naming it, not a
    traceback from the image library's header parser."""
    folder = printed[0]
    for target in (sorted((folder / "captures").glob("*.jpg"))[0], folder / "board.json"):
        before = target.read_bytes()
        code, _, err = run_main("camera", "calibrate", folder / "captures", "-o", target)
        assert code == 2, err
        line = one_error_line(err)
        assert line.startswith(f"lenticalib: error: {target}: is one of this command's inputs"), line
        assert target.read_bytes() == before
    shutil.copytree(folder / "captures", tmp_path / "captures")
    shutil.copy(folder / "board.json", tmp_path / "board.json")
    photos = tmp_path / "captures"
    (photos / "zz-empty.jpg").write_bytes(b"")
    code, _, err = run_main("camera", "calibrate", photos, "-o", tmp_path / "c.cameramodel")
    assert code == 2 and "Traceback" not in err, err
    assert one_error_line(err).startswith(f"lenticalib: error: {photos / 'zz-empty.jpg'}: "), err


def test_the_board_folder_stands_for_its_captures(printed):
    """Given the folder 'camera patterns' (or the simulator) wrote, the photos are those in its
    captures/, not the board drawing beside board.json (which once made 'only 1 photos given')."""
    from lenticalib.calib.intrinsics.pipeline import collect_photos

    folder = printed[0]
    assert collect_photos([folder]) == collect_photos([folder / "captures"])
    assert all(p.parent == folder / "captures" for p in collect_photos([folder]))


def test_board_panel_is_a_library_call_naming_its_arguments(tmp_path):
    """The panel of `camera patterns` (profile, or panel + pixel pitch) is chosen by the library."""
    from lenticalib.calib.intrinsics.pipeline import board_panel
    from lenticalib.core.errors import InputError

    assert board_panel(panel="1920x1080", pixel_pitch_mm=0.3) == (1920, 1080, 0.3, None)
    profile = {"views": 8, "slant": 0.19, "period": 7.5, "offset": 1.5, "reference_view": 4, "width": 1920,
               "height": 1080, "subpixel_order": "BGR", "physical": {"pixel_pitch_mm": 0.2}}
    (tmp_path / "p.json").write_text(json.dumps(profile))
    assert board_panel(tmp_path / "p.json") == (1920, 1080, 0.2, 2.5)
    for kwargs in ({}, {"profile": tmp_path / "p.json", "panel": "1920x1080"}, {"panel": "1920x1080"}):
        with pytest.raises(InputError) as caught:
            board_panel(**kwargs)
        assert "--" not in str(caught.value) and caught.value.source in ("profile", "panel")
