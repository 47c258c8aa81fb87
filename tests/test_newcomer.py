"""What a new user trips on (issue 48, items 2-5, 8 and 9): each hint is followed and must work,
numbers that a command prints agree with each other, and wording says what the file really is.

Most tests run the command line in this process (:func:`tests.cli_support.run_main`) on small
inputs; a hint is *followed*: the path or command it suggests is run and must be accepted.
"""

from __future__ import annotations

import json
import re
import shutil
import types

import numpy as np
import pytest

from lenticalib.core.profile import PanelProfile, load_profile, save_profile

from .cli_support import REPO, refused, run_main

FIXTURE = REPO / "fixtures" / "panel-4k-32.json"
SMALL = PanelProfile(views=8, slant=0.19, period=7.4, offset=1.5, reference_view=4.0, width=320, height=180,
                     subpixel_order="RGB", view_direction=1)


def _suggested_path(line: str) -> str:
    """The path an error line's hint suggests ("..., e.g. PATH)")."""
    found = re.search(r"e\.g\. (\S+?)\)$", line)
    assert found, f"no suggested path in {line!r}"
    return found.group(1)


def _follow(argv: list, line: str) -> list:
    """``argv`` with its ``-o`` value replaced by the path ``line``'s hint suggests."""
    out = list(argv)
    out[out.index("-o") + 1] = _suggested_path(line)
    return out


# ------------------------------------------------------------------ item 2: retarget after set-physical

def test_retarget_after_the_data_sheet_route_names_the_flag_that_fixes_it_and_that_flag_works(tmp_path,
                                                                                                monkeypatch):
    monkeypatch.chdir(tmp_path)
    shutil.copy(FIXTURE, "p.json")
    assert run_main("profile", "set-physical", "p.json", "--pixel-pitch", "0.1796", "--gap", "2.0")[0] == 0
    line = refused("profile", "retarget", "p.json", "--distance", "900", "-o", "p900.json", source="p.json")
    assert "physical.design_distance_mm" not in line and "`" not in line, line  # no JSON field, no library name
    command = re.search(r"'lenticalib (profile set-physical [^']*--design-distance MM)'", line)
    assert command, line
    code, out, err = run_main(*command.group(1).replace("MM", "750").split())
    assert code == 0, err
    code, out, err = run_main("profile", "retarget", "p.json", "--distance", "900", "-o", "p900.json")
    assert code == 0 and err == "", err
    assert load_profile("p900.json").physical["eye_mm"] == [0.0, 0.0, 900.0]


# ------------------------------------------------------------------ item 3: hints suggest names that work

def test_an_output_folder_given_by_mistake_suggests_a_file_name_the_command_takes(tmp_path, monkeypatch):
    from lenticalib.core.files.imageio import write_image
    from lenticalib.core.looking_glass.convert import export_visual_json
    from lenticalib.render.compose.views import QuiltGrid, make_quilt

    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("LENTICALIB_EMULATOR_DIR", str(tmp_path / "emu"))
    (tmp_path / "myfolder").mkdir()
    save_profile(SMALL, "small.json")
    views = np.random.default_rng(1).integers(0, 256, (8, 45, 80, 3), dtype=np.uint8)
    write_image("q_qs4x2a1.7778.png", make_quilt(views, QuiltGrid(4, 2)))
    export_visual_json(load_profile(FIXTURE), "visual.json", dpi=280.0)
    assert run_main("device", "flash", "emu://newcomer", FIXTURE)[0] == 0
    commands = {
        "encode": ["encode", "--profile", "small.json", "--quilt", "q_qs4x2a1.7778.png", "--encoder", "reference",
                   "-o", "myfolder"],
        "device read": ["device", "read", "emu://newcomer", "-o", "myfolder"],
        "profile import-lkg": ["profile", "import-lkg", "visual.json", "--views", "32", "-o", "myfolder"],
        "profile export-lkg": ["profile", "export-lkg", "small.json", "--dpi", "140", "-o", "myfolder"],
        "profile retarget": ["profile", "retarget", "p.json", "--distance", "900", "-o", "myfolder"],
    }
    shutil.copy(FIXTURE, "p.json")
    assert run_main("profile", "set-physical", "p.json", "--pixel-pitch", "0.1796", "--gap", "2",
                    "--design-distance", "700")[0] == 0
    for name, argv in commands.items():
        line = refused(*argv, source="myfolder")
        assert "is a folder" in line, (name, line)
        code, out, err = run_main(*_follow(argv, line))  # the suggestion, taken as given
        assert code == 0, (name, line, err)
        assert (tmp_path / _suggested_path(line)).is_file(), name


def test_a_hint_never_suggests_a_name_without_a_suffix_where_one_is_needed(tmp_path):
    from lenticalib.core.errors import InputError
    from lenticalib.core.files.outputs import check_output_file

    (tmp_path / "d").mkdir()
    with pytest.raises(InputError) as caught:
        check_output_file(tmp_path / "d", "thing", inputs=())  # no example given: no name suggested
    assert "e.g." not in str(caught.value) and "/out" not in str(caught.value)


# ------------------------------------------------------------------ item 4: camera models are .cameramodel

@pytest.mark.parametrize("name", ["cam.json", "cam", "cam.yaml"])
def test_camera_calibrate_refuses_a_model_name_fit_could_not_read_before_any_work(tmp_path, name):
    photos = tmp_path / "photos"
    photos.mkdir()
    for k in range(2):
        (photos / f"board-{k}.jpg").write_bytes(b"a photo of the board")
    argv = ["camera", "calibrate", photos, "--board", "9x6", "--square", "20", "-o", tmp_path / name]
    line = refused(*argv, source=tmp_path / name)
    assert ".cameramodel" in line and f"name it {tmp_path / 'cam.cameramodel'}" in line, line
    assert not (tmp_path / name).exists()
    argv[-1] = tmp_path / "cam.cameramodel"  # the suggestion passes the output checks: the photos are next
    assert "only 2 photos given" in refused(*argv, source="PHOTOS")


# ------------------------------------------------------------------ item 5: advice agrees with the summary

UNCERTAINTY = {"at_working_distance": {"centre": 0.004, "top_left": 0.075, "top_right": 0.081, "bottom_left": 0.077,
                                       "bottom_right": 0.079, "median": 0.01, "worst": 0.081},
               "at_infinity": {"centre": 0.02, "top_left": 0.18, "top_right": 0.21, "bottom_left": 0.19,
                               "bottom_right": 0.20, "median": 0.05, "worst": 0.21}}


def test_the_calibration_advice_labels_each_number_with_its_distance_as_the_summary_does():
    from lenticalib.calib.intrinsics.quality import weak_corners
    from lenticalib.calib.intrinsics.report import summary_lines

    advice = weak_corners(UNCERTAINTY, distance_mm=983.0)
    assert len(advice) == 4
    summary = {"intrinsics": {"fx": 1000.0, "fy": 1000.0, "cx": 800.0, "cy": 600.0}, "residuals":
               {"rms_px": 0.03, "worst_px": 0.1, "outliers": 0, "corners": 100, "noise_px": 0.03},
               "uncertainty": UNCERTAINTY, "output": "c.cameramodel", "lensmodel": "LENSMODEL_OPENCV5",
               "lensmodel_choice": "x", "photos": {"used": 20, "given": 20, "rejected": []}, "coverage": 0.9,
               "field_of_view_deg": [60.0, 45.0], "working_distance_mm": 983.0, "advice": advice, "report": None}
    lines = summary_lines(summary)
    stated = next(line for line in lines if line.startswith("uncertainty"))
    assert "0.075-0.081 px at the image corners" in stated and "at infinity" in stated
    assert "0.180-0.210 px at the image corners" in stated  # the corners at infinity, as the advice uses them
    for line in (x for x in lines if x.startswith("advice:")):
        numbers = re.findall(r"(\d\.\d\d) px at (983 mm|infinity)", line)
        assert len(numbers) == 2, line  # each number labelled with its distance
        for value, where in numbers:
            limits = UNCERTAINTY["at_working_distance" if where == "983 mm" else "at_infinity"]
            assert any(f"{limits[k]:.2f}" == value for k in ("top_left", "top_right", "bottom_left",
                                                             "bottom_right")), line


def test_the_coverage_figure_outlines_every_image_corner_the_advice_asks_photos_for():
    from matplotlib.figure import Figure

    from lenticalib.calib.intrinsics.quality import weak_corner_keys
    from lenticalib.calib.intrinsics.report import _coverage_figure

    w, h, rows, cols = 1600, 1200, 6, 8
    ys, xs = np.meshgrid(np.linspace(250, 1150, rows), np.linspace(250, 1550, cols), indexing="ij")
    obs = np.zeros((2, rows, cols, 3))
    obs[..., 0], obs[..., 1], obs[..., 2] = xs, ys, 1.0  # every cell but the top-left ones holds corners
    obs[1, ..., 0] = xs - 200.0
    obs[1, ..., 1] = ys + 40.0
    obs[1, ..., 1] = np.clip(obs[1, ..., 1], 0, h - 1)
    solve = types.SimpleNamespace(optimization_inputs={"observations_board": obs, "imagersizes": [[w, h]]},
                                  observed=np.ones((2, rows, cols), bool), inlier=np.ones((2, rows, cols), bool))
    qual = {"coverage": 0.9, "uncertainty": UNCERTAINTY}
    fig = Figure(figsize=(18, 12))
    _coverage_figure(fig, {"cal": types.SimpleNamespace(solve=solve), "qual": qual})
    ax = fig.axes[0]
    outlined = {(round(p.get_x()), round(p.get_y())) for p in ax.patches
                if not p.get_fill() and p.get_edgecolor()[:3] == pytest.approx((1.0, 0.498, 0.055), abs=0.01)}
    corners = {"top_left": (0, 0), "top_right": (1400, 0), "bottom_left": (0, 1000), "bottom_right": (1400, 1000)}
    assert outlined == {corners[k] for k in weak_corner_keys(UNCERTAINTY)} == set(corners.values())
    assert "outlined image corners" in ax.get_title()


# ------------------------------------------------------------------ item 8: wording

def test_a_png_named_ply_is_called_a_png_image(tmp_path):
    avatar = tmp_path / "head.ply"
    shutil.copy(REPO / "fixtures" / "demo_qs8x4a1.7778.png", avatar)
    line = refused("render", avatar, "--profile", FIXTURE, "-o", tmp_path / "f.png", source=avatar)
    assert "is a PNG image, not a PLY file" in line and "codec" not in line, line


def test_a_missing_video_is_said_not_to_exist(tmp_path):
    from lenticalib.core.errors import InputError
    from lenticalib.render.student.frames import CameraFrames

    with pytest.raises(InputError) as caught:
        CameraFrames(str(tmp_path / "test.avi"))
    assert "no such file" in str(caught.value) and "OpenCV" not in str(caught.value)


def test_an_existing_file_as_output_folder_is_never_suggested_for_removal(tmp_path):
    (tmp_path / "small.json").write_text("{}\n")
    (tmp_path / "head.ply").write_bytes(b"ply\n")
    line = refused("render", tmp_path / "head.ply", "--profile", FIXTURE, "-o", tmp_path / "small.json",
                   source=tmp_path / "small.json")
    assert "remove" not in line and "delete" not in line, line
    assert (tmp_path / "small.json").read_text() == "{}\n"


# ------------------------------------------------------------------ item 9: small things a user sees

def test_device_list_labels_a_looking_glass_units_usb_serial_as_info_does(tmp_path, monkeypatch):
    from .looking_glass_support import CELLS, visual_bytes

    monkeypatch.setenv("LENTICALIB_EMULATOR_DIR", str(tmp_path / "emu"))
    (tmp_path / "visual.json").write_bytes(visual_bytes(CELLS))
    assert run_main("emulate", "--looking-glass", tmp_path / "visual.json", "--name", "bench")[0] == 0
    code, listed, _ = run_main("device", "list")
    assert code == 0
    row = next(line for line in listed.splitlines() if line.startswith("lkg-emu://bench"))
    code, info, _ = run_main("device", "info", "lkg-emu://bench")
    usb = re.search(r"USB serial (\S+)", info).group(1)
    assert row.endswith(f"USB serial {usb}"), row  # never a bare "serial" where info's serial differs
    assert "serial LKG-P-01234" in info


def test_a_profile_read_from_a_unit_says_when_it_was_read(tmp_path, monkeypatch):
    from .looking_glass_support import CELLS, visual_bytes

    monkeypatch.setenv("LENTICALIB_EMULATOR_DIR", str(tmp_path / "emu"))
    (tmp_path / "visual.json").write_bytes(visual_bytes(CELLS))
    assert run_main("emulate", "--looking-glass", tmp_path / "visual.json", "--name", "bench")[0] == 0
    code, _, err = run_main("device", "read", "lkg-emu://bench", "-o", tmp_path / "lkg.json", "--views", "45")
    assert code == 0, err
    code, shown, _ = run_main("profile", "show", tmp_path / "lkg.json")
    read = load_profile(tmp_path / "lkg.json").provenance["read"]
    assert "unknown date" not in shown and f"read from Looking Glass on {read}" in shown


def test_the_render_table_shows_present_as_not_run_and_counts_one_frame(tmp_path):
    from lenticalib.render.avatar.gaussians import Gaussians
    from lenticalib.render.avatar.ply import save_ply

    rng = np.random.default_rng(2)
    means = rng.uniform(-0.1, 0.1, (50, 3)).astype(np.float32)
    save_ply(tmp_path / "g.ply", Gaussians(means, np.tile(np.float32([1, 0, 0, 0]), (50, 1)),
                                           np.full((50, 3), 0.01, np.float32), np.full(50, 0.8, np.float32),
                                           np.full((50, 1, 3), 0.5, np.float32)))
    save_profile(SMALL, tmp_path / "small.json")
    code, out, err = run_main("render", tmp_path / "g.ply", "--profile", tmp_path / "small.json", "-o",
                              tmp_path / "f.png", "--view-size", "64x36")
    assert code == 0, err
    present = next(line for line in out.splitlines() if line.startswith("present"))
    assert present.split()[1:] == ["-", "-", "-"], out
    assert "(1 frame," in out and "(1 frames" not in out


def test_diagnose_names_no_worst_view_for_a_metric_equal_in_every_view():
    from lenticalib.render.diagnose.avatars import METRICS
    from lenticalib.render.diagnose.report import diagnose_table

    views = [dict({m: 0.0 for m in METRICS}, yaw_deg=yaw, O_alpha=0.05 + 0.001 * k)
             for k, yaw in enumerate((-25.0, 0.0, 25.0))]
    worst = {m: {"yaw_deg": -25.0, "value": 0.0} for m in METRICS}
    worst["O_alpha"] = {"yaw_deg": 25.0, "value": 0.052}
    result = {"avatar": "demo.npz", "views": views, "renderer": "cpu", "mask_source": "mesh",
              "crop": {"x0": 0, "x1": 10, "y0": 0, "y1": 10}, "worst": worst,
              "side": {"views": [views[0], views[2]], "mean": {m: 0.0 for m in METRICS}}}
    lines = diagnose_table(result)
    at_yaw = next(line for line in lines if line.strip().startswith("at yaw")).split()[2:]
    cells = dict(zip(METRICS, at_yaw))
    assert cells["O_alpha"] == "25.0" and all(cells[m] == "-" for m in METRICS if m != "O_alpha"), lines


def test_the_compensation_figure_has_no_tick_without_a_bar():
    from matplotlib.figure import Figure

    from lenticalib.calib.crosstalk.report import _compensation

    n = 8
    offsets = np.arange(n) - n // 2  # -4..3, as compensation_study gives them
    study = {"rms_without": [0.1] * n, "rms_with": [0.01] * n, "leak_offsets": offsets.tolist(),
             "leak_without": (0.02 / (1 + np.abs(offsets))).tolist(), "leak_with": [0.001] * n,
             "residual_crosstalk_without": 0.1, "residual_crosstalk_with": 0.01, "mean_rms_without": 0.1,
             "mean_rms_with": 0.01, "example_intended": [0.5] * n, "example_seen_without": [0.45] * n,
             "example_seen_with": [0.5] * n, "example_target": [0.5] * n, "black_lift": 0.02}
    fig = Figure(figsize=(18, 8))
    _compensation(fig, study)
    ax = fig.axes[0]
    low, high = ax.get_xlim()
    ticks = [t for t in ax.get_xticks() if low <= t <= high]
    assert set(ticks) <= set(offsets.tolist()), (ticks, offsets)
    assert high < offsets.max() + 1 and low > offsets.min() - 1


def test_the_bundled_profile_says_which_way_its_views_run_so_play_does_not_warn():
    from lenticalib.core.view_direction import direction_warning

    profile = load_profile(FIXTURE)
    assert profile.view_direction == 1 and direction_warning(profile) is None
    assert json.loads(FIXTURE.read_text())["provenance"]["view_direction"]["method"] == "the virtual panel's truth"


def test_the_virtual_panel_runs_its_views_to_the_right_as_the_fixture_says():
    from lenticalib.sim.scene import random_scene

    for seed in (1, 2, 3):  # either slant sign, either subpixel order: always +1 (docs/simulator.md)
        assert random_scene(seed).truth_profile(32).view_direction == 1
