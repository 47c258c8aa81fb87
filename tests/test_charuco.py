"""ChArUco boards end to end: drawing, detection of whole and partial boards, the simulator's cut
boards, the mrcal solve with the corners a photo identified, and one-line errors.

The ground-truth test photographs a printed ChArUco board with a known simulated camera, about a
third of the boards running off the frame, and checks that those photos are used (their corners
go into the solve) and that the solved camera agrees with the truth within mrcal's own predicted
uncertainty (Mahalanobis distance < 3 over a grid of the image, as in test_camera_calibration).
"""

import json
import os

import numpy as np
import pytest

from lenticalib.calib.intrinsics import board as boards
from lenticalib.calib.intrinsics.charuco_corners import MIN_CHARUCO_CORNERS, charuco_shortfall, find_charuco_corners
from lenticalib.calib.intrinsics.draw import panel_raster
from lenticalib.calib.intrinsics.pipeline import calibrate_camera
from lenticalib.calib.intrinsics.quality import compare_to_truth
from lenticalib.sim.board_set import read_truth_poses, simulate_board_set

from .cli_support import one_error_line, run_main

RESOLUTION = (1024, 768)


def _drawn_corners(board):
    """Panel pixel coordinates (rows, cols, 2) of the inner corners of a panel board as drawn
    (pixel centres at whole numbers, as OpenCV's convention)."""
    ii, jj = np.meshgrid(np.arange(board.rows), np.arange(board.cols), indexing="ij")
    return np.stack([board.origin_px[0] + jj * board.square_px - 0.5,
                     board.origin_px[1] + ii * board.square_px - 0.5], axis=-1)


def test_panel_board_is_read_by_opencv_with_every_corner_where_it_was_drawn():
    board = boards.panel_board(1280, 720, 0.3, pattern="charuco")
    assert board.charuco and board.square_px % 2 == 0 and board.dictionary == "DICT_4X4_100"
    cell = board.marker_px // 6  # 4x4 bits and a black border
    assert cell * 6 == board.marker_px and (board.square_px - board.marker_px) % 2 == 0  # whole cells, centred
    assert board.edge_px == 5 and board.marker_edge_px == 3  # squares: a twelfth of a square; markers: half a cell
    grey = panel_raster(board)[..., 0]
    found = find_charuco_corners(grey, board)
    assert np.isfinite(found).all()
    assert np.abs(found - _drawn_corners(board)).max() < 0.05
    # the manifest round trip keeps what detection needs
    again = boards.Board.from_dict(json.loads(json.dumps(board.to_dict())))
    assert again == board
    doc = board.to_dict()
    assert (doc["pattern"], doc["dictionary"], doc["squares"]) == ("charuco", "DICT_4X4_100", [16, 9])
    assert doc["marker_mm"] == pytest.approx(board.marker_px * 0.3) and doc["square_mm"] == pytest.approx(
        board.square_px * 0.3)


def test_a_partial_board_keeps_its_labels():
    """Half the board cut away (and the rest turned upside down): the corners left carry their own
    row and column, the ones cut away are NaN."""
    board = boards.panel_board(1280, 720, 0.3, pattern="charuco")
    grey = panel_raster(board)[..., 0]
    expected = _drawn_corners(board)
    cut = 700
    part = np.ascontiguousarray(grey[:, :cut])
    found = find_charuco_corners(part, board)
    inside = expected[..., 0] < cut - board.square_px  # corners with both neighbouring markers in the crop
    assert np.isfinite(found[inside]).all()
    assert not np.isfinite(found[expected[..., 0] > cut]).any()
    seen = np.isfinite(found[..., 0])
    assert np.abs(found[seen] - expected[seen]).max() < 0.05
    turned = np.ascontiguousarray(part[::-1, ::-1])
    found = find_charuco_corners(turned, board)
    seen = np.isfinite(found[..., 0])
    assert seen.sum() >= inside.sum()
    h, w = turned.shape
    flipped = np.stack([w - 1 - expected[..., 0], h - 1 - expected[..., 1]], axis=-1)
    assert np.abs(found[seen] - flipped[seen]).max() < 0.05
    # too few corners: the reason, one line
    few = np.full_like(found, np.nan)
    few[0, :MIN_CHARUCO_CORNERS - 1] = expected[0, :MIN_CHARUCO_CORNERS - 1]
    assert "only 9 of 120 ChArUco corners identified" in charuco_shortfall(few)
    line = np.full_like(found, np.nan)
    line[2, :] = expected[2, :]
    assert "one line" in charuco_shortfall(line)


def test_camera_patterns_writes_charuco_boards_for_the_panel_and_for_print(tmp_path, cli):
    out = tmp_path / "boards"
    code, stdout, err = cli("camera", "patterns", "-o", out, "--panel", "1920x1080", "--pixel-pitch", "0.3",
                            "--board", "charuco")
    assert code == 0, err
    assert "DICT_4X4_100 markers" in stdout and "it may run off them" in stdout
    panel = boards.read_board(out / "board.json")
    sheet = boards.read_board(out / "print" / "board.json")
    assert panel.charuco and sheet.charuco and sheet.marker_mm == pytest.approx(0.6 * sheet.square_mm)
    from PIL import Image

    with Image.open(out / "print" / "board-print.png") as img:  # A4 at 300 dpi, squares at their true size
        grey = np.asarray(img.convert("L"))
    found = find_charuco_corners(grey, sheet)
    assert np.isfinite(found).all()
    ii, jj = np.meshgrid(np.arange(sheet.rows), np.arange(sheet.cols), indexing="ij")
    px_per_mm = 300 / 25.4
    expected = np.stack([(sheet.origin_mm[0] + jj * sheet.square_mm) * px_per_mm - 0.5,
                         (sheet.origin_mm[1] + ii * sheet.square_mm) * px_per_mm - 0.5], axis=-1)
    assert np.abs(found - expected).max() < 1.0  # true size on the sheet (Agg snaps edges to whole pixels)
    assert (out / "print" / "board-print.pdf").stat().st_size > 0
    # the chessboard stays the default
    code, _, err = cli("camera", "patterns", "-o", tmp_path / "plain", "--panel", "1920x1080", "--pixel-pitch", "0.3")
    assert code == 0, err
    assert not boards.read_board(tmp_path / "plain" / "board.json").charuco


@pytest.fixture(scope="module")
def cut_set(tmp_path_factory):
    folder = tmp_path_factory.mktemp("charuco") / "set"
    folder.mkdir()
    doc = simulate_board_set(folder, kind="print", seed=2, photos=18, resolution=RESOLUTION, subsamples=1,
                             pattern="charuco")
    model = folder / "camera.cameramodel"
    run = calibrate_camera([folder / "captures"], model, report_dir=folder / "report")
    return folder, doc, model, json.loads(json.dumps(run.summary)), run


@pytest.mark.slow
def test_a_charuco_set_with_boards_cut_by_the_frame_calibrates_with_their_corners(cut_set):
    import mrcal

    from lenticalib.calib.intrinsics.board import read_board
    from lenticalib.sim.board_poses import BoardPose, inside_share
    from lenticalib.sim.camera import Camera

    folder, doc, model_path, summary, run = cut_set
    board = read_board(folder / "board.json")
    camera = Camera.from_dict(doc["camera"])
    truth_poses = read_truth_poses(folder)
    import cv2

    def share(name):
        rt = truth_poses[name]
        return inside_share(camera, board, BoardPose(cv2.Rodrigues(rt[:3])[0], rt[3:]), margin=0.0)

    frames = [os.path.basename(p) for p in summary["photos"]["frames"]]
    cut = [k for k, name in enumerate(frames) if share(name) < 0.85]
    assert len(cut) >= 4, [share(n) for n in frames]  # photos of boards partly outside the frame were used...
    obs = run.calibration.solve.optimization_inputs["observations_board"]
    for k in cut:  # ...with their corners in the solve, the missing ones ignored by mrcal
        weight = obs[k, ..., 2]
        assert (weight > 0).sum() >= MIN_CHARUCO_CORNERS and (weight < 0).sum() > 0
    # the cut boards reach where whole boards do not: the image's outer band
    w, h = RESOLUTION
    q = obs[cut][obs[cut][..., 2] > 0][:, :2]
    edge = np.minimum.reduce([q[:, 0], q[:, 1], w - 1 - q[:, 0], h - 1 - q[:, 1]])
    assert (edge < 0.06 * w).sum() >= 10
    assert summary["coverage"] >= 0.9 and summary["residuals"]["corners"] == int((obs[..., 0] >= 0).sum())
    # the model, read back, agrees with the truth within its own uncertainty
    model = mrcal.cameramodel(str(model_path))
    truth = mrcal.cameramodel(str(folder / "truth.cameramodel"))
    rt = np.array([truth_poses[name] for name in frames])
    for distance in (summary["working_distance_mm"], None):
        c = compare_to_truth(model, truth, rt, distance)
        assert np.mean(c["normalised"] < 3.0) >= 0.95, np.percentile(c["normalised"], [50, 95, 100])
        assert np.median(c["stdev"]) < 0.5  # the uncertainty is a real constraint
    near = compare_to_truth(model, truth, rt, summary["working_distance_mm"])
    assert np.median(np.linalg.norm(near["error"], axis=-1)) < 0.1
    assert (folder / "report" / "summary.json").is_file()


def _expect_error(argv, *fragments):
    code, out, err = run_main(*argv)
    assert code == 2, (code, out, err)
    line = one_error_line(err)
    for fragment in fragments:
        assert fragment in line, (fragment, line)


@pytest.mark.slow
def test_charuco_errors_are_one_line(tmp_path, cut_set):
    folder = cut_set[0]
    captures = folder / "captures"
    out = tmp_path / "c.cameramodel"
    calibrate = ["camera", "calibrate", captures, "-o", out, "--jobs", "1"]
    _expect_error(calibrate + ["--charuco", "12x7", "--square", "20", "--dictionary", "DICT_4X4_50"],
                  "--marker", "marker size")
    _expect_error(calibrate + ["--charuco", "12x7", "--square", "20", "--marker", "12"], "--dictionary",
                  "DICT_4X4_50")
    _expect_error(calibrate + ["--charuco", "12x7", "--square", "20", "--marker", "25", "--dictionary",
                               "DICT_4X4_50"], "--marker", "between 0 and the square size")
    _expect_error(calibrate + ["--charuco", "12x7", "--square", "20", "--marker", "12", "--dictionary",
                               "DICT_4X4_9"], "--dictionary", "unknown ArUco dictionary")
    _expect_error(calibrate + ["--charuco", "30x20", "--square", "20", "--marker", "12", "--dictionary",
                               "DICT_4X4_50"], "--dictionary", "holds 50 markers, the board needs 300")
    _expect_error(calibrate + ["--marker", "12"], "--marker", "ChArUco board only")
    _expect_error(calibrate + ["--board", "11x6", "--charuco", "12x7", "--square", "20"], "not both")
    _expect_error(calibrate + ["--charuco", "12by7"], "--charuco", "COLSxROWS")
    assert not out.exists()
    # a board.json with a broken ChArUco field is named
    bad = tmp_path / "set"
    (bad / "captures").mkdir(parents=True)
    for k in range(10):
        (bad / "captures" / f"b{k}.jpg").write_bytes((captures / f"board-{k + 1:02d}.jpg").read_bytes())
    doc = json.loads((folder / "board.json").read_text())
    doc["dictionary"] = "DICT_ARUCO_SOMETHING"
    (bad / "board.json").write_text(json.dumps(doc))
    _expect_error(["camera", "calibrate", bad / "captures", "-o", out], "board.json", "unknown ArUco dictionary")
    # the right board given by options (not board.json) calibrates the same photos; a wrong dictionary
    # finds no board, in one line after the search, before the solve
    _expect_error(["camera", "calibrate", bad / "captures", "-o", out, "--charuco", "12x7", "--square", "20",
                   "--marker", "12", "--dictionary", "DICT_5X5_50"], "found in 0 of 10 photos", "dictionary")
    patterns = ["camera", "patterns", "-o", tmp_path / "b", "--panel", "1920x1080", "--pixel-pitch", "0.3"]
    _expect_error(patterns + ["--dictionary", "DICT_4X4_250"], "--dictionary", "--board charuco")
    _expect_error(patterns + ["--board", "charuco", "--squares", "60x40"], "--squares")
    assert not (tmp_path / "b").exists()


def test_a_charuco_board_given_by_options_calibrates(tmp_path, cli):
    """--charuco/--square/--marker/--dictionary instead of board.json: the photos are of the board the
    options describe (a fast small set; its accuracy is the ground-truth test's business)."""
    folder = tmp_path / "set"
    folder.mkdir()
    simulate_board_set(folder, kind="print", seed=5, photos=12, resolution=(800, 600), subsamples=1,
                       pattern="charuco")
    os.remove(folder / "board.json")
    code, out, err = cli("camera", "calibrate", folder / "captures", "-o", tmp_path / "c.cameramodel", "--json",
                         "--charuco", "12x7", "--square", "20", "--marker", "12", "--dictionary", "DICT_4X4_50")
    assert code == 0, err
    summary = json.loads(out)
    assert summary["board"]["pattern"] == "charuco" and summary["photos"]["used"] >= 10
    for rejected in summary["photos"]["rejected"]:
        assert "ChArUco corners" in rejected["reason"] or "outliers" in rejected["reason"]


@pytest.mark.slow
def test_simulate_photographs_a_charuco_patterns_folder_and_camera_simulate_makes_charuco_sets(tmp_path, cli):
    """The panel board of 'camera patterns --board charuco' through the virtual lens sheet, with some
    boards cut by the frame, calibrates; 'camera simulate --board charuco' writes a ChArUco set."""
    from lenticalib.calib.camera.model_file import load_camera_model

    folder = tmp_path / "board"
    code, _, err = cli("camera", "patterns", "-o", folder, "--panel", "1920x1080", "--pixel-pitch", "0.36",
                       "--lens-pitch", "1.9", "--board", "charuco")
    assert code == 0, err
    code, _, err = cli("simulate", folder, "--seed", 4, "--photos", 12, "--resolution", "1280x960")
    assert code == 0, err
    doc = json.loads((folder / "simulation.json").read_text())
    assert doc["board"]["pattern"] == "charuco" and doc["cut"] > 0
    code, out, err = cli("camera", "calibrate", folder / "captures", "-o", tmp_path / "c.cameramodel", "--json")
    assert code == 0, err
    summary = json.loads(out)
    assert summary["photos"]["used"] >= 10 and summary["board"]["pattern"] == "charuco"
    assert summary["residuals"]["corners"] < 12 * 15 * 8  # partial boards: not every corner of every photo
    fitted, truth = load_camera_model(tmp_path / "c.cameramodel"), load_camera_model(folder / "truth.cameramodel")
    assert np.allclose(fitted.intrinsics[:2], truth.intrinsics[:2], rtol=0.01)
    code, out, err = cli("camera", "simulate", tmp_path / "sim", "--seed", 3, "--photos", 10, "--kind", "print",
                         "--resolution", "800x600", "--subsamples", 1, "--board", "charuco")
    assert code == 0, err
    assert "ChArUco board (some partly outside the frame)" in out
    assert boards.read_board(tmp_path / "sim" / "board.json").charuco


def test_a_photo_with_too_few_corners_is_named_with_its_reason_in_the_summary():
    from lenticalib.calib.intrinsics.report import summary_lines

    summary = {"output": "c.cameramodel", "lensmodel": "LENSMODEL_OPENCV8", "lensmodel_choice": "forced",
               "photos": {"used": 11, "given": 12, "rejected": [
                   {"photo": "/x/board-04.jpg", "reason": "only 5 of 66 ChArUco corners identified, at least 10 "
                                                         "are needed (show more of the board, sharper)"}]},
               "residuals": {"rms_px": 0.1, "worst_px": 0.3, "outliers": 0, "corners": 600, "noise_px": 0.1},
               "coverage": 0.9, "intrinsics": {"fx": 1.0, "fy": 1.0, "cx": 0.0, "cy": 0.0},
               "field_of_view_deg": [60.0, 45.0], "working_distance_mm": 500.0,
               "uncertainty": {k: {"centre": 0.1, "worst": 0.2, "top_left": 0.1, "top_right": 0.1, "bottom_left": 0.1,
                                   "bottom_right": 0.1} for k in ("at_working_distance", "at_infinity")},
               "cross_validation": {"scale": 1.0, "skipped": "not run"}, "report": None}
    lines = summary_lines(summary)
    assert [line for line in lines if "board-04.jpg: only 5 of 66 ChArUco corners identified" in line]


def test_board_json_problems_and_a_wrong_lens_pitch_say_what_to_do(tmp_path):
    """A board.json lacking a field (or with one of the wrong type, or a panel board whose square in
    mm is not its pixels times the pitch) says how to get a good one; a lens pitch whose soft edges would not fit the squares (50 mm typed for 0.5) is refused, where
    it once gave ramps cut to a third of a square; photos linked into a folder of their own still
    find the board.json beside the originals."""
    from lenticalib.core.errors import InputError

    folder = tmp_path / "set"
    folder.mkdir()
    board = boards.panel_board(1920, 1080, 0.3)
    boards.write_manifest(board, folder)
    doc = json.loads((folder / "board.json").read_text())
    for change in ({"cols": None}, {"square_mm": "twenty"}):
        broken = {k: v for k, v in doc.items() if k not in change}
        if change.get("square_mm"):
            broken["square_mm"] = change["square_mm"]
        (folder / "board.json").write_text(json.dumps(broken))
        with pytest.raises(InputError) as info:
            boards.read_board(folder / "board.json")
        assert info.value.source == str(folder / "board.json") and "camera patterns" in info.value.hint
    # a panel board's square in mm edited away from its pixels times the pitch
    edited = dict(doc, square_mm=doc["square_mm"] * 1.1)
    (folder / "board.json").write_text(json.dumps(edited))
    with pytest.raises(InputError) as info:
        boards.read_board(folder / "board.json")
    assert "is not square_px x pixel_pitch_mm" in info.value.message and "camera patterns" in info.value.hint
    with pytest.raises(InputError) as info:
        boards.panel_board(1920, 1080, 0.3, lens_pitch_px=50 / 0.3)
    assert info.value.source == "lens_pitch_mm" and "lens pitch" in info.value.hint
    assert boards.panel_board(1920, 1080, 0.3, lens_pitch_px=0.5 / 0.3).edge_px >= 2 * 0.5 / 0.3
    # links in another folder: board.json found where the photos lie
    boards.write_manifest(board, folder)
    (folder / "captures").mkdir()
    (folder / "captures" / "a.jpg").write_bytes(b"x")
    linked = tmp_path / "elsewhere" / "deep" / "down"
    linked.mkdir(parents=True)
    os.symlink(folder / "captures" / "a.jpg", linked / "a.jpg")
    assert boards.find_board_manifest([linked / "a.jpg"]) == (folder / "board.json").resolve()
    # and a board.json beside the links wins over the one they point to
    boards.write_manifest(board, linked)
    assert boards.find_board_manifest([linked / "a.jpg"]) == linked / "board.json"
