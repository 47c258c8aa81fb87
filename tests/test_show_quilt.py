"""``lenticalib show --profile``: quilt images and quilt videos played on the panel (render/pipeline/quilt_player.py).

The GL path runs on Mesa's llvmpipe through EGL (no window): the offscreen presenter keeps what it
presented (``keep=True``), and every presented frame is held against ``lenticalib encode --quilt``
of the video frame it came from.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from lenticalib.core.files.imageio import read_image, write_image
from lenticalib.core.profile import PanelProfile
from lenticalib.render.encoders import encode
from lenticalib.render.present.offscreen import MemoryPresenter, OffscreenPresenter
from lenticalib.render.pipeline.quilt_player import play_quilts
from lenticalib.render.pipeline.quilt_sources import quilt_items, tile_for_views
from lenticalib.render.compose.views import QuiltGrid, make_quilt, split_quilt

from .cli_support import one_error_line

PROFILE = {"views": 8, "slant": 0.19, "period": 7.4, "offset": 1.5, "reference_view": 4,
           "width": 96, "height": 54, "subpixel_order": "BGR"}
VIEW = (27, 48)  # (H_v, W_v): a 16:9 view of the 96x54 panel


def _profile() -> PanelProfile:
    return PanelProfile(**PROFILE)


def _write_video(path, frames, fps):
    """A lossless video (FFV1 in .avi) of ``frames`` (RGB (H, W, 3) uint8 each)."""
    import cv2

    height, width = frames[0].shape[:2]
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"FFV1"), fps, (width, height))
    assert writer.isOpened(), "this OpenCV build writes no FFV1"
    for frame in frames:
        writer.write(np.ascontiguousarray(frame[..., ::-1]))
    writer.release()


def _quilt_frames(count, tiles=8, grid=QuiltGrid(4, 2), seed=0):
    rng = np.random.default_rng(seed)
    return [make_quilt(rng.integers(0, 256, (tiles, *VIEW, 3), dtype=np.uint8), grid) for _ in range(count)]


@pytest.fixture
def panel(tmp_path):
    path = tmp_path / "panel.json"
    path.write_text(json.dumps(PROFILE))
    return path


def test_every_presented_frame_is_encode_quilt_of_its_video_frame_and_drops_are_counted(tmp_path, panel, cli):
    frames = _quilt_frames(5)
    video = tmp_path / "clip_qs4x2a1.7778.avi"
    _write_video(video, frames, fps=10)
    expected = []
    for i, frame in enumerate(frames):  # what `encode --quilt` makes of each frame
        write_image(tmp_path / f"f{i}_qs4x2a1.7778.png", frame)
        code, _, err = cli("encode", "--quilt", tmp_path / f"f{i}_qs4x2a1.7778.png", "--profile", panel,
                           "--encoder", "reference", "-o", tmp_path / f"r{i}.png")
        assert code == 0, err
        expected.append(read_image(tmp_path / f"r{i}.png").astype(np.int32))
    profile = _profile()
    # unpaced (every frame), paced at the video's 10 fps, and paced while presenting takes 0.35 s
    # (late frames dropped, and counted)
    for fps, slow in ((None, 0.0), ("video", 0.0), ("video", 0.35)):
        shown = []

        def on_present(item, frame):
            shown.append(frame)
            if slow:
                import time

                time.sleep(slow)

        with OffscreenPresenter((96, 54), keep=True) as presenter:
            report = play_quilts(presenter, quilt_items(video), profile, encoder="gl", fps=fps, on_present=on_present)
            presented = presenter.presented
        assert report.encoder == "gl" and report.decoded == 5
        assert len(presented) == len(shown) == report.presented
        assert report.presented + report.dropped == 5, (shown, report.dropped)
        assert shown == sorted(shown) and shown[-1] == 4
        for frame, raster in zip(shown, presented):
            assert np.abs(raster.astype(np.int32) - expected[frame]).max() <= 1, frame
        if slow:
            assert report.dropped >= 1 and len(shown) < 5
        elif fps is None:
            assert report.dropped == 0 and shown == [0, 1, 2, 3, 4]
    for encoder in ("gl", "auto"):  # auto: gl, or fast where OpenGL renders in software (and says so)
        code, out, err = cli("show", video, "--profile", panel, "--display", "offscreen", "--json", "--encoder", encoder)
        summary = json.loads(out)
        assert code == 0 and summary["presented"] + summary["dropped"] == 5, err
        software = any("software" in note for note in summary["notes"])
        assert summary["encoder"] == ("fast" if encoder == "auto" and software else "gl")


def test_a_quilt_of_another_view_count_is_sampled_at_each_views_fraction_of_the_cone(tmp_path):
    assert tile_for_views(16, 8).tolist() == [1, 3, 5, 7, 9, 11, 13, 15]
    assert tile_for_views(4, 8).tolist() == [0, 0, 1, 1, 2, 2, 3, 3]
    assert tile_for_views(8, 8).tolist() == list(range(8))
    quilt = _quilt_frames(1, tiles=16, grid=QuiltGrid(4, 4))[0]
    quilt = quilt[: 4 * VIEW[0] // 2 * 2]  # 4x4 tiles of 48x27 -> aspect 16:9 (the name says so)
    write_image(tmp_path / "many_qs4x4a1.7778.png", quilt)
    views = split_quilt(quilt, QuiltGrid(4, 4))[1::2]
    for presenter in (OffscreenPresenter((96, 54), keep=True), MemoryPresenter((96, 54))):
        with presenter:
            report = play_quilts(presenter, quilt_items(tmp_path / "many_qs4x4a1.7778.png"), _profile(), interval=0.01)
            shown = presenter.presented[-1] if presenter.kind == "offscreen" else presenter.read_back()
        reference = encode(views, _profile(), "reference").astype(np.int32)
        assert np.abs(shown.astype(np.int32) - reference).max() <= 1
        assert report.encoder == ("gl" if presenter.kind == "offscreen" else "fast")


class _Scripted(MemoryPresenter):
    """No graphics (the CPU fallback); keys pressed after the n-th frame shown."""

    def __init__(self, size, script):
        super().__init__(size)
        self.script, self.frames = dict(script), 0

    def show(self, raster, source=None):
        self.frames += 1
        return super().show(raster, source)

    def keys(self, timeout=0.0):  # one key a call
        waiting = self.script.get(self.frames, [])
        return [waiting.pop(0)] if waiting else []


def test_keys_seek_pause_step_and_quit(tmp_path):
    folder = tmp_path / "show"
    folder.mkdir()
    _write_video(folder / "a_qs4x2a1.7778.avi", _quilt_frames(12, seed=1), fps=1)  # 5 s = 5 frames
    write_image(folder / "b_qs4x2a1.7778.png", _quilt_frames(1, seed=2)[0])
    shown = []
    script = {1: ["right"], 3: ["left"], 5: ["space", "space"], 15: ["right"], 16: ["up"], 17: ["q"]}
    with _Scripted((96, 54), script) as presenter:
        report = play_quilts(presenter, quilt_items(folder), _profile(), fps=None, loop=True,
                             on_present=lambda item, frame: shown.append((item, frame)))
    # seek +5 s from frame 0, -5 s from frame 6; paused (and resumed) after 5 frames; at the end
    # the image; right: the next item (the video again, looped), up: back to the image; q
    assert shown == [(0, 0), (0, 5), (0, 6), (0, 1), (0, 2), (0, 3)] + [(0, f) for f in range(4, 12)] \
        + [(1, 0), (0, 0), (1, 0)], shown
    assert report.encoder == "fast" and report.dropped == 0 and report.items == 4
    assert any("CPU" in note for note in report.notes)


def test_bad_quilts_and_options_end_in_one_line_before_anything_opens(tmp_path, panel, cli):
    write_image(tmp_path / "tall_qs4x2a0.75.png", _quilt_frames(1)[0])
    write_image(tmp_path / "plain.png", _quilt_frames(1)[0])
    _write_video(tmp_path / "odd_qs250x2a1.7778.avi", _quilt_frames(1), fps=5)  # 192 pixels wide
    cases = [
        (["show", tmp_path / "tall_qs4x2a0.75.png", "--profile", panel], "aspect 0.75"),
        (["show", tmp_path / "plain.png", "--profile", panel], "quilt grid unknown"),
        (["show", tmp_path / "plain.png", "--profile", panel, "--quilt-cols", "4"], "--quilt-rows"),
        (["show", tmp_path / "odd_qs250x2a1.7778.avi", "--profile", panel, "--display", "offscreen"],
     "no pixel per tile"),
        (["show", tmp_path / "tall_qs4x2a0.75.png", "--profile", panel, "--display", "offscreen", "--loop"],
         "never ends"),
        (["show", tmp_path / "plain.png", "--quilt-cols", "4"], "--profile"),
    ]
    for argv, words in cases:
        code, _, err = cli(*argv)
        assert code == 2 and words in one_error_line(err), (argv, err)
    assert "--quilt-cols C --quilt-rows R" in cli("show", tmp_path / "plain.png", "--profile", panel)[2]
    code, out, _ = cli("show", tmp_path / "plain.png", "--profile", panel, "--quilt-cols", "4", "--quilt-rows", "2",
                       "--display", "offscreen", "--interval", "0.01", "--json")
    assert code == 0 and json.loads(out)["presented"] == 1
    code, out, _ = cli("show", tmp_path / "tall_qs4x2a0.75.png", "--profile", panel, "--stretch",
                       "--display", "none", "--interval", "0.01")
    assert code == 0 and "1 frame(s) presented, 0 dropped" in out


def test_a_quilt_video_and_image_play_in_a_window_with_real_keys(xvfb, tmp_path):
    import subprocess
    import sys
    import time

    from .display_support import SCREEN

    width, height = SCREEN  # the monitor's mode: the panel's size
    (tmp_path / "panel.json").write_text(json.dumps({**PROFILE, "width": width, "height": height}))
    rng = np.random.default_rng(9)
    views = rng.integers(0, 256, (8, height // 4, width // 4, 3), dtype=np.uint8)
    folder = tmp_path / "show"
    folder.mkdir()
    _write_video(folder / "a_qs4x2a1.7778.avi", [make_quilt(views, QuiltGrid(4, 2))] * 3, fps=30)
    write_image(folder / "b_qs4x2a1.7778.png", make_quilt(views[::-1].copy(), QuiltGrid(4, 2)))
    profile = PanelProfile(**{**PROFILE, "width": width, "height": height})
    image_raster = encode(views[::-1].copy(), profile, "reference").astype(np.int32)
    process = subprocess.Popen([sys.executable, "-m", "lenticalib", "show", str(folder), "--profile",
                                str(tmp_path / "panel.json"), "--json", "--encoder", "gl"], env=xvfb.env(),
                               stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        deadline, seen = time.monotonic() + 30, False
        while time.monotonic() < deadline and not seen:  # the video plays, then the image stays
            seen = np.abs(xvfb.screenshot().astype(np.int32) - image_raster).max() <= 1
            time.sleep(0.1)
        assert seen, "the quilt image never reached the screen"
        xvfb.key("q")
        out, err = process.communicate(timeout=20)
    finally:
        process.kill()
    assert process.returncode == 0, err
    summary = json.loads(out)
    assert summary["encoder"] == "gl" and summary["items"] == 2
    assert summary["presented"] + summary["dropped"] == 4 and summary["decoded"] == 3


def test_a_video_faster_than_the_displays_refresh_is_said_to_drop_frames(tmp_path):
    from lenticalib.render.gpu.monitors import Monitor

    _write_video(tmp_path / "fast_qs4x2a1.7778.avi", _quilt_frames(2), fps=120)
    with MemoryPresenter((96, 54)) as presenter:
        presenter.monitor, presenter.vsync = Monitor(0, "LKG", 0, 0, 96, 54, 60), True  # a 60 Hz window's
        report = play_quilts(presenter, quilt_items(tmp_path / "fast_qs4x2a1.7778.avi"), _profile())
    assert any("120 fps, the display refreshes at 60 Hz: some 50 %" in note for note in report.notes), report.notes
    assert report.presented + report.dropped == 2


def test_the_next_image_of_a_show_is_read_while_one_is_shown(tmp_path, monkeypatch):
    import threading

    from lenticalib.render.pipeline import quilt_player

    frames = _quilt_frames(3, seed=5)
    for k, quilt in enumerate(frames):
        write_image(tmp_path / f"s{k}_qs4x2a1.7778.png", quilt)
    readers, original = [], quilt_player.read_quilt_image

    def recording(item, mapping):
        readers.append((item.path.name[:2], threading.current_thread().name.split("_")[0]))
        return original(item, mapping)

    monkeypatch.setattr(quilt_player, "read_quilt_image", recording)
    with OffscreenPresenter((96, 54), keep=True) as presenter:
        report = play_quilts(presenter, quilt_items(tmp_path), _profile(), encoder="gl", interval=0.05)
    assert readers == [("s0", "MainThread"), ("s1", "quilt-image"), ("s2", "quilt-image")]
    assert report.presented == 3
    for quilt, shown in zip(frames, presenter.presented):
        reference = encode(split_quilt(quilt, QuiltGrid(4, 2)), _profile(), "reference").astype(np.int32)
        assert np.abs(shown.astype(np.int32) - reference).max() <= 1


def test_a_quilt_whose_sides_the_grid_does_not_divide_is_read_from_the_bottom_left(tmp_path):
    # Looking Glass's 4096x4096 8x6 quilts: tiles of 512x682, four rows left over at the top
    quilt = _quilt_frames(1, seed=7)[0]
    padded = np.full((quilt.shape[0] + 1, quilt.shape[1] + 3, 3), 255, np.uint8)  # 195x55: 4x2 tiles of 48x27
    padded[1:, :-3] = quilt  # a left-over row at the top, columns at the right
    write_image(tmp_path / "odd_qs4x2a1.7778.png", padded)
    with OffscreenPresenter((96, 54), keep=True) as presenter:
        play_quilts(presenter, quilt_items(tmp_path / "odd_qs4x2a1.7778.png"), _profile(), encoder="gl", interval=0.01)
    reference = encode(split_quilt(quilt, QuiltGrid(4, 2)), _profile(), "reference").astype(np.int32)
    assert np.abs(presenter.presented[0].astype(np.int32) - reference).max() <= 1
