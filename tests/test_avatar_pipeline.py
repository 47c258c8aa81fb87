"""The avatar pipeline end to end on the CPU: ``lenticalib render`` and ``lenticalib play --headless``.

A small demo avatar (fixed seed), the bundled 4K 32-view profile, the cpu renderer and the fast
encoder.  Checks: what is written, that the written views are exactly what was encoded, that a
Gaussian lands where cameras.json projects it, that the view direction is honoured (and a
profile that does not state it is warned about), and one-line refusals.
"""

import json
import subprocess
import sys

import numpy as np
import pytest

from lenticalib.core.files.imageio import read_image
from lenticalib.core.profile import load_profile, save_profile
from lenticalib.render.encoders import encode
from lenticalib.render.avatar.gaussians import SH_C0, Gaussians
from lenticalib.render.avatar.ply import save_ply

PROFILE = "fixtures/panel-4k-32.json"
SMALL_VIEWS = "192x108"


@pytest.fixture(scope="module")
def demo(tmp_path_factory):
    from lenticalib.render.avatar.demo_avatar import make_demo_avatar
    from lenticalib.render.avatar.rig_file import save_rig

    path = tmp_path_factory.mktemp("avatar") / "demo.npz"
    save_rig(path, make_demo_avatar(seed=1, count=6000))
    return path


@pytest.fixture(scope="module")
def directed(tmp_path_factory):
    """The bundled profile with view_direction +1, with -1 and unknown (None)."""
    folder = tmp_path_factory.mktemp("profiles")
    base = load_profile(PROFILE)
    out = {}
    for sign in (1, -1, None):
        out[sign] = folder / ("unknown.json" if sign is None else f"p{sign:+d}.json")
        save_profile(base.replace(view_direction=sign), out[sign])
    return out


def test_render_writes_the_raster_the_views_and_the_cameras(demo, directed, tmp_path, cli_process):
    result = cli_process("render", demo, "--profile", directed[1], "-o", tmp_path / "frame.png",
                         "--view-size", SMALL_VIEWS, "--views-out", tmp_path / "views", "--background", "0.1,0.1,0.1")
    assert result.returncode == 0, result.stderr
    assert "warning" not in result.stderr
    for stage in ("drive", "render", "compose", "total", "fps"):
        assert stage in result.stdout
    raster = read_image(tmp_path / "frame.png")
    assert raster.shape == (2160, 3840, 3) and raster.dtype == np.uint8
    views = np.stack([read_image(tmp_path / "views" / "frame-00000" / f"view-{i:02d}.png") for i in range(32)])
    assert views.shape == (32, 108, 192, 3)
    assert np.array_equal(encode(views, load_profile(PROFILE)), raster)  # the views are exactly what was encoded
    cameras = json.loads((tmp_path / "views" / "cameras.json").read_text())
    assert cameras["format"] == "lenticalib.cameras" and len(cameras["views"]) == 32
    # the head is in the middle of every view, on the background
    for view in views[[0, 16, 31]]:
        centre = view[40:70, 80:112].astype(int)
        assert np.abs(centre - 26).sum(axis=2).mean() > 20  # not background (0.1 * 255 = 26)
        assert np.abs(view[:5, :5].astype(int) - 26).max() <= 1


def test_a_gaussian_lands_where_cameras_json_projects_it(directed, tmp_path, cli_process):
    point = np.array([0.013, -0.021, 0.007])
    rng = np.random.default_rng(3)
    # one bright small Gaussian at a known point, and a few dim ones far away to give the box a size
    means = np.vstack([point, rng.uniform(-0.12, 0.12, (6, 3))]).astype(np.float32)
    scales = np.full((7, 3), 0.002, np.float32)
    opac = np.array([0.99] + [0.05] * 6, np.float32)
    sh = np.zeros((7, 1, 3), np.float32)
    sh[0, 0] = (1.0 - 0.5) / SH_C0
    quats = np.tile([1.0, 0.0, 0.0, 0.0], (7, 1)).astype(np.float32)
    save_ply(tmp_path / "dot.ply", Gaussians(means, quats, scales, opac, sh))
    result = cli_process("render", tmp_path / "dot.ply", "--profile", directed[1], "-o", tmp_path / "f.png",
                         "--view-size", "480x270", "--views-out", tmp_path / "v")
    assert result.returncode == 0, result.stderr
    cameras = json.loads((tmp_path / "v" / "cameras.json").read_text())
    for index in (0, 11, 31):
        entry = cameras["views"][index]
        k, m = np.array(entry["K"]), np.array(entry["world_to_camera"])
        cam = m[:3, :3] @ point + m[:3, 3]
        expected = (k @ cam)[:2] / cam[2]
        view = read_image(tmp_path / "v" / "frame-00000" / f"view-{index:02d}.png").astype(float).sum(axis=2)
        ys, xs = np.mgrid[0:view.shape[0], 0:view.shape[1]]
        near = (np.abs(xs - expected[0]) < 8) & (np.abs(ys - expected[1]) < 8)
        w = view * near
        centroid = np.array([(w * xs).sum(), (w * ys).sum()]) / w.sum()
        assert np.abs(centroid - expected).max() < 0.1, (index, centroid, expected)


@pytest.mark.slow
def test_the_view_direction_reverses_the_cameras_and_unknown_is_warned(demo, directed, tmp_path, cli_process):
    out = {}
    for sign in (1, -1):
        r = cli_process("render", demo, "--profile", directed[sign], "-o", tmp_path / f"r{sign}.png", "--view-size",
                        SMALL_VIEWS, "--views-out", tmp_path / f"v{sign}")
        assert r.returncode == 0, r.stderr
        out[sign] = np.stack([read_image(tmp_path / f"v{sign}" / "frame-00000" / f"view-{i:02d}.png")
                              for i in range(32)])
    assert np.array_equal(out[1], out[-1][::-1])
    assert not np.array_equal(out[1][0], out[1][31])
    r = cli_process("render", demo, "--profile", directed[None], "-o", tmp_path / "u.png", "--view-size", SMALL_VIEWS)
    assert r.returncode == 0, r.stderr
    assert "does not say which way its views run" in r.stderr


def test_an_image_background_shows_where_the_avatar_is_not(demo, directed, tmp_path, cli_process):
    from lenticalib.core.files.imageio import write_image

    backdrop = np.zeros((108, 192, 3), np.uint8)
    backdrop[:, :96] = (200, 30, 40)
    backdrop[:, 96:] = (20, 60, 210)
    write_image(tmp_path / "backdrop.png", backdrop)
    r = cli_process("render", demo, "--profile", directed[1], "-o", tmp_path / "b.png", "--view-size", SMALL_VIEWS,
                    "--background", tmp_path / "backdrop.png", "--views-out", tmp_path / "v")
    assert r.returncode == 0, r.stderr
    view = read_image(tmp_path / "v" / "frame-00000" / "view-16.png").astype(int)
    assert np.abs(view[:6, :6] - (200, 30, 40)).max() <= 1 and np.abs(view[-6:, -6:] - (20, 60, 210)).max() <= 1
    assert np.abs(view[40:70, 80:112] - backdrop[40:70, 80:112]).sum(axis=2).mean() > 30  # the head covers it


@pytest.mark.slow
def test_a_sequence_as_pngs_and_as_a_lossless_video_holds_the_same_rasters(demo, directed, tmp_path, cli_process):
    import cv2

    args = ("--profile", directed[1], "--view-size", SMALL_VIEWS, "--frames", "2", "--fps", "2")
    r = cli_process("render", demo, "-o", tmp_path / "frames", *args)
    assert r.returncode == 0, r.stderr
    r = cli_process("render", demo, "-o", tmp_path / "seq.mkv", *args)
    assert r.returncode == 0, r.stderr
    capture = cv2.VideoCapture(str(tmp_path / "seq.mkv"))
    for k in range(2):
        ok, frame = capture.read()
        assert ok and np.array_equal(frame[:, :, ::-1], read_image(tmp_path / "frames" / f"frame-{k:05d}.png"))
    assert not capture.read()[0]
    assert not list(tmp_path.glob(".*"))  # no temporary file left


def _table(stdout: str) -> dict:
    """The stage table's rows: {stage: [median, mean, p95] (floats, or "-" for a stage not run)}."""
    rows = {}
    for line in stdout.splitlines():
        name, *values = line.split()
        if name in ("drive", "render", "compose", "present", "total") and len(values) == 3:
            rows[name] = [v if v == "-" else float(v) for v in values]
    return rows


def test_play_headless_runs_frames_and_prints_the_stage_table(demo, directed, cli_process):
    result = cli_process("play", demo, "--profile", directed[1], "--headless", "--frames", "1",
                         "--view-size", SMALL_VIEWS)
    assert result.returncode == 0, result.stderr
    assert "(1 frame," in result.stdout
    rows = _table(result.stdout)
    assert rows["present"] == ["-", "-", "-"], result.stdout  # headless presents nothing
    assert rows["total"][0] == pytest.approx(sum(rows[s][0] for s in ("drive", "render", "compose")), abs=0.02)


def test_play_headless_keeps_running_through_hostile_stdin_and_reports_the_bad_lines(demo, directed, tmp_path):
    import signal

    hostile = [b"[" * 50000, b'{"jaw": [' + b"7" * 5000 + b", 0, 0]}", b'{"jaw": [1e39, 0, 0]}',
               b'{"jaw": [1' + b"0" * 400 + b", 0, 0]}", b'{"jaw": [NaN, 0, 0]}', b"\xff\xfe",
               b'{"jaw": [0.1, 0, 0]}' + b" " * 70000, b'{"jaw": "open"}', b'{"controls": [0, 0]}']
    feed = tmp_path / "controls.jsonl"
    feed.write_bytes(b"\n".join(hostile + [b'{"jaw": [0.1, 0, 0]}']) + b"\n")
    with open(feed, "rb") as stdin:
        proc = subprocess.Popen([sys.executable, "-m", "lenticalib", "play", str(demo), "--profile", str(directed[1]),
                                 "--headless", "--stats", "--controls", "-", "--view-size", SMALL_VIEWS],
                                stdin=stdin, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        try:
            for line in proc.stdout:  # the per-second stage line: the loop has run for a second
                if line.startswith("drive"):
                    break
            proc.send_signal(signal.SIGINT)
            rest, stderr = proc.communicate(timeout=300)
        finally:
            proc.kill()
    assert proc.returncode == 0, stderr
    assert f"controls stdin: 1 valid line, {len(hostile)} bad (last: stdin line {len(hostile)}: " in rest, rest
    assert "bad control line (1 so far): stdin line 1: not JSON: nested too deep" in stderr
    assert "Traceback" not in stderr


def test_a_control_file_the_avatar_cannot_use_is_refused_before_play_starts(demo, directed, tmp_path, cli_process):
    (tmp_path / "big.jsonl").write_text('{"t": 0, "jaw": [0, 0, 0]}\n{"t": 1, "jaw": [1e39, 0, 0]}\n')
    result = cli_process("play", demo, "--profile", directed[1], "--headless", "--frames", "1",
                         "--view-size", SMALL_VIEWS, "--controls", tmp_path / "big.jsonl")
    assert result.returncode == 2 and result.stdout == "", result.stdout
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and f"{tmp_path / 'big.jsonl'}:2: jaw[0] is 1e+39, out of range" in lines[0], lines


def test_a_renderer_or_encoder_that_cannot_run_here_is_refused_before_anything_is_loaded(tmp_path, cli_process):
    """Neither the avatar nor the profile exists: refusing the backend first is the only way to name it."""
    import importlib.util

    import torch

    cuda = torch.cuda.is_available()
    gsplat = importlib.util.find_spec("gsplat") is not None
    for options, words in ((["--renderer", "gsplat"], "renderer 'gsplat' cannot run here: it needs a CUDA GPU "
                            "and torch sees none (renderers that can run here: cpu, gl, gl-compute)" if not cuda else
                            "none.json" if gsplat else "renderer 'gsplat' cannot run here: it needs gsplat"),
                           (["--encoder", "torch", "--device", "cuda"], "encoder 'torch' cannot run here: device "
                            "'cuda' requested but torch sees no CUDA device" if not cuda else "none.json")):
        result = cli_process("play", tmp_path / "none.npz", "--profile", tmp_path / "none.json", "--headless", *options)
        lines = result.stderr.strip().splitlines()
        assert result.returncode == 2 and len(lines) == 1 and words in lines[0], result.stderr


def test_a_device_torch_cannot_use_is_refused_before_the_first_frame(demo, directed, cli_process):
    """The drive runs on --device too: the cpu renderer with the fast encoder still needs it to exist."""
    import torch

    cases = [("bogus", "--device: 'bogus' is not a torch device")]
    if not torch.cuda.is_available():
        cases.append(("cuda", "--device: device 'cuda' requested but torch sees no CUDA device (use --device cpu)"))
    for device, words in cases:
        result = cli_process("play", demo, "--profile", directed[1], "--headless", "--frames", "1",
                             "--view-size", SMALL_VIEWS, "--device", device)
        lines = result.stderr.strip().splitlines()
        assert result.returncode == 2 and result.stdout == "" and len(lines) == 1 and words in lines[0], result.stderr


@pytest.mark.slow
def test_bad_inputs_end_in_one_line(demo, directed, tmp_path, cli_process):
    (tmp_path / "bad.npz").write_bytes(b"not a zip")
    (tmp_path / "bad.jsonl").write_text('{"t": 0, "controls": [1, 2, 3]}\n')
    cases = [
        (["render", tmp_path / "missing.npz", "--profile", directed[1], "-o", tmp_path / "a.png"], "no such avatar file"),
        (["render", tmp_path / "bad.npz", "--profile", directed[1], "-o", tmp_path / "a.png"], "bad.npz"),
        (["render", demo, "--profile", directed[1], "-o", tmp_path / "a.png", "--controls", tmp_path / "bad.jsonl"],
         "bad.jsonl"),
        (["render", demo, "--profile", directed[1], "-o", tmp_path / "a.png", "--renderer", "opengl"],
         "--renderer: unknown renderer 'opengl'"),
        (["render", demo, "--profile", directed[1], "-o", tmp_path / "a.png", "--view-size", "500x500"],
         "--view-size: views of 500x500 (aspect"),
        (["render", demo, "--profile", directed[1], "-o", tmp_path / "a.png", "--background", "red"], "--background"),
        (["render", demo, "--profile", directed[1], "-o", tmp_path / "a.png", "--frames", "3"], "one PNG"),
        (["render", demo, "--profile", tmp_path / "none.json", "-o", tmp_path / "a.png"], "none.json"),
    ]
    for args, message in cases:
        result = cli_process(*args)
        assert result.returncode == 2, (args, result.stdout, result.stderr)
        lines = result.stderr.strip().splitlines()
        assert len(lines) == 1 and message in lines[0], (args, result.stderr)
    assert not (tmp_path / "a.png").exists()


@pytest.mark.slow
def test_crosstalk_compensation_in_the_loop_changes_what_is_encoded(demo, directed, tmp_path, cli_process):
    n = 32
    row = np.full(n, 0.002)
    row[0], row[1], row[-1] = 0.5, 0.2, 0.2
    row /= row.sum()
    matrix = row[(np.arange(n)[None, :] - np.arange(n)[:, None]) % n]
    crosstalk = tmp_path / "crosstalk.json"
    crosstalk.write_text(json.dumps({"format": "lenticalib.crosstalk", "format_version": 1, "views": n,
                                     "matrix": matrix.tolist()}))
    result = cli_process("render", demo, "--profile", directed[1], "-o", tmp_path / "frame.png",
                         "--view-size", SMALL_VIEWS, "--views-out", tmp_path / "views", "--compensate", crosstalk,
                         "--black-lift", "0.03")
    assert result.returncode == 0, result.stderr
    raster = read_image(tmp_path / "frame.png")
    views = np.stack([read_image(tmp_path / "views" / "frame-00000" / f"view-{i:02d}.png") for i in range(n)])
    assert np.array_equal(encode(views, load_profile(PROFILE)), raster)  # the compensated views are what was encoded
    plain = cli_process("render", demo, "--profile", directed[1], "-o", tmp_path / "plain.png",
                        "--view-size", SMALL_VIEWS)
    assert plain.returncode == 0, plain.stderr
    assert not np.array_equal(read_image(tmp_path / "plain.png"), raster)
    assert np.abs(views[:, :5, :5].astype(int) - 48).max() <= 1  # the black background is lifted to 0.03 (sRGB 48)


def test_the_first_ctrl_c_asks_the_live_loop_to_stop_and_the_second_interrupts():
    # an interrupt raised inside a numba kernel surfaces as SystemError: the first Ctrl-C only sets a flag
    import os
    import signal

    from lenticalib.render.pipeline.live import stop_on_interrupt

    before = signal.getsignal(signal.SIGINT)
    with stop_on_interrupt() as interrupted:
        assert not interrupted.is_set()
        os.kill(os.getpid(), signal.SIGINT)
        for _ in range(1000):  # the handler runs between bytecodes of the main thread
            if interrupted.is_set():
                break
        assert interrupted.is_set()
        with pytest.raises(KeyboardInterrupt):
            os.kill(os.getpid(), signal.SIGINT)
            for _ in range(1000):
                pass
    assert signal.getsignal(signal.SIGINT) is before
