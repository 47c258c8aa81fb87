"""The capture cameras (lenticalib.calib.capture.cameras): registry, gphoto2, OpenCV, manual, virtual.

No real camera, display or GPU is needed:

* gphoto2 runs against ``STANDIN_GPHOTO2``, a small Python program installed on PATH as
  ``gphoto2`` for the test.  It is a stand-in, not gphoto2: it answers the four command lines the
  backend uses (``--auto-detect``, ``--set-config``, ``--get-config``,
  ``--capture-image-and-download --filename F``) the way gphoto2 2.5 does, from a JSON script the
  test writes, and logs every argument list it got.  What is tested is the backend's real
  subprocess integration: argument lists, working folder, exit codes, stderr, file hand-over.
* The OpenCV backend is exercised on a missing device and on a video file read through the real
  cv2.VideoCapture (a stream source the backend supports), since no webcam is attached.
* The virtual camera is the real simulator at a small panel and camera size.
"""

from __future__ import annotations

import json
import os
import stat
import sys
import threading
import time
from pathlib import Path

import cv2
import numpy as np
import pytest

from lenticalib.calib.capture.cameras import CAMERA_KINDS, make_camera, open_camera
from lenticalib.calib.capture.cameras.base import CaptureCamera
from lenticalib.core.errors import CameraError, InputError
from lenticalib.sim.scene import DEFAULT_RESOLUTION


def _jpeg(seed: int, size=(48, 64)) -> bytes:
    """A small real JPEG file (bytes) made with OpenCV."""
    image = np.random.default_rng(seed).integers(0, 256, (*size, 3), dtype=np.uint8)
    ok, data = cv2.imencode(".jpg", image, [cv2.IMWRITE_JPEG_QUALITY, 90])
    assert ok
    return data.tobytes()


# -- registry ------------------------------------------------------------------------------------

def test_registry_lists_every_kind_and_each_constructs(tmp_path):
    assert set(CAMERA_KINDS) == {"gphoto2", "opencv", "manual", "sim"}
    specs = {"gphoto2": "gphoto2:usb:001,005", "opencv": "opencv:0", "manual": f"manual:{tmp_path}",
             "sim": "sim:7"}
    for kind, spec in specs.items():
        camera = make_camera(spec)
        assert isinstance(camera, CAMERA_KINDS[kind]) and isinstance(camera, CaptureCamera)
        assert camera.kind == kind and camera.spec == spec and not camera.is_open
        assert camera.settings() == []
    assert make_camera("sim:7").seed == 7 and make_camera("sim").seed == 1
    assert make_camera("opencv").device == 0 and make_camera("opencv:/dev/video2").device == "/dev/video2"
    assert make_camera("manual").folder is None and make_camera("gphoto2").port is None


@pytest.mark.parametrize("spec", ["", "   ", "nikon", "webcam:0", "gphoto2:", "opencv:", "opencv:abc", "opencv:-1",
                                  "sim:seven", "sim:-3", "gphoto2:001,005", ":0"])
def test_bad_specs_are_input_errors_naming_the_flag(spec):
    with pytest.raises(InputError) as info:
        make_camera(spec)
    assert info.value.source.split()[0] == "camera" and "\n" not in str(info.value)


def test_unknown_kind_lists_the_kinds():
    with pytest.raises(InputError) as info:
        make_camera("canon")
    message = str(info.value)
    assert all(kind in message for kind in CAMERA_KINDS)


@pytest.mark.parametrize("spec, options", [("sim", {"exposure": 0.01}), ("opencv:0", {"seed": 1}),
                                           ("sim", {"resolution": "big"}), ("sim", {"conditions": "rainy"}),
                                           ("manual", {"timeout": -1}), ("opencv:0", {"discard": -1}),
                                           ("sim:3", {"seed": 4}), ("gphoto2", {"timeout": "soon"})])
def test_bad_options_are_input_errors(spec, options):
    with pytest.raises(InputError) as info:
        make_camera(spec, **options)
    assert info.value.source.split()[0] == "camera"


def test_every_kind_takes_timeout_and_none_means_default(tmp_path):
    # one set of options for whichever kind the user picked (what 'lenticalib capture' passes)
    for spec in ("gphoto2", "opencv:0", f"manual:{tmp_path}", "sim"):
        camera = make_camera(spec, timeout=600.0)
        if camera.kind != "sim":  # the virtual camera never waits
            assert camera.timeout == 600.0
    assert make_camera("manual", timeout=None).timeout == 600.0
    assert make_camera("sim", resolution=None, conditions=None).resolution == DEFAULT_RESOLUTION == (4000, 3000)


def test_capture_needs_an_open_camera(tmp_path):
    camera = make_camera(f"manual:{tmp_path}")
    with pytest.raises(CameraError, match="not open"):
        camera.capture("x0-0", None, tmp_path / "set" / "captures" / "x0-0")


# -- gphoto2 ---------------------------------------------------------------------------------------

STANDIN_GPHOTO2 = r'''#!{python}
"""STAND-IN for the gphoto2 program in lenticalib's tests (it is not gphoto2, and drives no camera).

It answers the command lines lenticalib's gphoto2 backend runs, as gphoto2 2.5 would, scripted by
standin.json next to it, and appends every argument list (and its working folder) to calls.jsonl.
"""
import json, os, shutil, sys
from pathlib import Path

here = Path(__file__).resolve().parent
script = json.loads((here / "standin.json").read_text())
state_path = here / "standin-state.json"
state = json.loads(state_path.read_text()) if state_path.exists() else {{}}
args = sys.argv[1:]
with open(here / "calls.jsonl", "a") as log:
    log.write(json.dumps({{"args": args, "cwd": os.getcwd()}}) + "\n")
if args[:1] == ["--port"]:
    args = args[2:]
if args == ["--auto-detect"]:
    print("Model                          Port")
    print("----------------------------------------------------------")
    for model, port in script["cameras"]:
        print(f"{{model:<31}}{{port}}")
    sys.exit(0)
if args[:1] == ["--set-config"]:
    name, _, value = args[1].partition("=")
    if name not in script["config"]:
        sys.stderr.write(f"\n*** Error ***\n{{name}} not found in configuration tree.\n"
                         "*** Error (-1: 'Unspecified error') ***\n")
        sys.exit(1)
    if value not in script["config"][name]["accepts"]:
        sys.stderr.write(f"*** Error: {{value}} is not a valid choice for {{name}} ***\n")
        sys.exit(1)
    if not script["config"][name].get("readonly"):
        state[name] = value
        state_path.write_text(json.dumps(state))
    sys.exit(0)
if args[:1] == ["--get-config"]:
    name = args[1]
    current = state.get(name, script["config"][name]["current"])
    print(f"Label: {{name}}\nReadonly: 0\nType: RADIO\nCurrent: {{current}}\nEND")
    sys.exit(0)
if args[:2] == ["--capture-image-and-download", "--filename"] and args[3:] == ["--force-overwrite"]:
    if script["capture"] != "ok":
        sys.stderr.write("\n*** Error ***\nOut of Focus\n" + script["capture"] + "\n")
        sys.exit(1)
    print("New file is in location /store_00020001/DCIM/100CANON/IMG_0001.JPG on the camera")
    target = args[2].replace("%C", "jpg")
    shutil.copyfile(script["photo"], target)
    for extra in script.get("extra", []):
        shutil.copyfile(script["photo"], args[2].replace("%C", extra))
    print(f"Saving file as {{target}}")
    sys.exit(0)
sys.stderr.write("stand-in gphoto2: unexpected arguments " + " ".join(sys.argv[1:]) + "\n")
sys.exit(2)
'''

CONFIG = {  # what the scripted camera accepts; focus: the camera says yes but keeps AI Focus (lens switch)
    "/main/capturesettings/autoexposuremode": {"accepts": ["Manual"], "current": "P"},
    "/main/capturesettings/focusmode": {"accepts": ["Manual", "AI Focus"], "current": "AI Focus", "readonly": True},
    "/main/imgsettings/whitebalance": {"accepts": ["Daylight", "Auto"], "current": "Auto"},
    "/main/capturesettings/imagequality": {"accepts": ["JPEG Fine", "RAW"], "current": "RAW"},
}


@pytest.fixture
def standin(tmp_path, monkeypatch):
    """Install the stand-in ``gphoto2`` on PATH; returns a function to script it and read its log."""
    bin_dir = tmp_path / "bin"
    bin_dir.mkdir()
    program = bin_dir / "gphoto2"
    program.write_text(STANDIN_GPHOTO2.format(python=sys.executable))
    program.chmod(program.stat().st_mode | stat.S_IXUSR | stat.S_IXGRP | stat.S_IXOTH)
    photo = tmp_path / "camera-photo.jpg"
    photo.write_bytes(_jpeg(3))
    monkeypatch.setenv("PATH", f"{bin_dir}{os.pathsep}{os.environ.get('PATH', '')}")

    class Standin:
        photo_bytes = photo.read_bytes()

        def script(self, cameras=(("Canon EOS 600D", "usb:001,005"),), capture="ok", extra=()):
            (bin_dir / "standin.json").write_text(json.dumps(
                {"cameras": [list(c) for c in cameras], "config": CONFIG, "capture": capture,
                 "photo": str(photo), "extra": list(extra)}))

        def calls(self):
            log = bin_dir / "calls.jsonl"
            return [json.loads(line) for line in log.read_text().splitlines()] if log.exists() else []

    return Standin()


def test_gphoto2_missing_program_says_install(tmp_path, monkeypatch):
    monkeypatch.setenv("PATH", str(tmp_path))  # a PATH without gphoto2
    camera = make_camera("gphoto2")
    with pytest.raises(CameraError) as info:
        camera.open()
    assert "not installed" in str(info.value) and "apt install gphoto2" in str(info.value)
    assert not camera.is_open


def test_gphoto2_locks_what_the_camera_allows_and_captures_atomically(tmp_path, standin):
    standin.script()
    captures = tmp_path / "set" / "captures"
    with open_camera("gphoto2", timeout=20) as camera:
        lines = camera.settings()
        assert lines[0].startswith("camera: Canon EOS 600D on usb:001,005")
        by_label = {line.split(":")[0]: line for line in lines[1:]}
        assert by_label["exposure"] == "exposure: locked (autoexposuremode=Manual)"
        assert by_label["focus"].startswith("focus: could not lock on this camera")
        assert "kept 'AI Focus'" in by_label["focus"] and "focusmode2: *** Error" in by_label["focus"]
        assert "MF" in by_label["focus"]  # what to do by hand
        assert by_label["white balance"] == "white balance: locked (whitebalance=Daylight)"
        assert by_label["image format"] == "image format: locked (imagequality=JPEG Fine)"  # second candidate

        (captures).mkdir(parents=True)
        (captures / "x0-0.png").write_bytes(b"an older photo of the same pattern")
        path = camera.capture("x0-0", None, captures / "x0-0")
    assert path == captures / "x0-0.jpg"
    assert path.read_bytes() == standin.photo_bytes
    assert sorted(p.name for p in captures.iterdir()) == ["x0-0.jpg"]  # no temp files, no second photo
    capture_call = standin.calls()[-1]
    # argument list, port of the detected camera, gphoto2 working in a hidden folder in captures/
    assert capture_call["args"] == ["--port", "usb:001,005", "--capture-image-and-download", "--filename",
                                    "photo.%C", "--force-overwrite"]
    work = Path(capture_call["cwd"])
    assert work.parent == captures and work.name.startswith(".")
    assert standin.calls()[0]["args"] == ["--auto-detect"]


def test_gphoto2_keeps_jpeg_of_a_raw_plus_jpeg_camera(tmp_path, standin):
    standin.script(extra=["cr2"])
    with open_camera("gphoto2:usb:001,005") as camera:
        path = camera.capture("f16-0", None, tmp_path / "captures" / "f16-0")
    assert path.name == "f16-0.jpg" and sorted(p.name for p in path.parent.iterdir()) == ["f16-0.jpg"]


def test_gphoto2_failed_trigger_quotes_the_camera(tmp_path, standin):
    standin.script(capture="ERROR: Could not capture image.")
    with open_camera("gphoto2") as camera:
        with pytest.raises(CameraError) as info:
            camera.capture("x0-0", None, tmp_path / "captures" / "x0-0")
    message = str(info.value)
    assert "ERROR: Could not capture image." in message and "x0-0" in message and "\n" not in message
    assert list((tmp_path / "captures").iterdir()) == []  # nothing left behind


def test_gphoto2_no_camera_detected(tmp_path, standin):
    standin.script(cameras=())
    with pytest.raises(CameraError) as info:
        open_camera("gphoto2")
    assert "no camera detected" in str(info.value) and "USB" in str(info.value)
    standin.script()  # a camera, but not on the port asked for
    with pytest.raises(CameraError, match="on port usb:002,009"):
        open_camera("gphoto2:usb:002,009")
    standin.script(cameras=(("Canon EOS 600D", "usb:001,005"), ("Nikon DSC D7000", "usb:001,007")))
    with pytest.raises(CameraError, match="2 cameras detected.*gphoto2:usb:001,005"):
        open_camera("gphoto2")


# -- opencv ----------------------------------------------------------------------------------------

def test_opencv_missing_device_is_named():
    camera = make_camera("opencv:97")
    with pytest.raises(CameraError) as info:
        camera.open()
    assert "97" in str(info.value) and "\n" not in str(info.value)
    assert not camera.is_open


def test_opencv_reads_a_stream_after_discarding_stale_frames(tmp_path):
    # a video file stands in for a webcam stream: same VideoCapture read path, no hardware
    video = tmp_path / "stream.avi"
    writer = cv2.VideoWriter(str(video), cv2.VideoWriter_fourcc(*"MJPG"), 10, (160, 120))
    assert writer.isOpened(), "opencv-contrib-python-headless writes MJPG AVI with its bundled codecs"
    for level in range(0, 200, 20):  # frame k is a flat grey of level 20 k
        writer.write(np.full((120, 160, 3), level, np.uint8))
    writer.release()
    with open_camera(f"opencv:{video}", discard=3) as camera:
        settings = camera.settings()
        assert any(line.startswith("resolution:") for line in settings)
        assert any(line.startswith("exposure: could not lock") for line in settings)  # a file has no exposure
        first = camera.capture("x0-0", None, tmp_path / "captures" / "x0-0")
        second = camera.capture("x0-1", None, tmp_path / "captures" / "x0-1")
    assert first.name == "x0-0.jpg" and second.name == "x0-1.jpg"
    assert abs(float(cv2.imread(str(first)).mean()) - 60) < 4  # frames 0-2 dropped, frame 3 kept
    assert abs(float(cv2.imread(str(second)).mean()) - 140) < 4  # frames 4-6 dropped, frame 7 kept
    assert not camera.is_open


# -- manual ----------------------------------------------------------------------------------------

def test_manual_watched_folder_copies_the_next_new_photo(tmp_path):
    watched = tmp_path / "card"
    watched.mkdir()
    (watched / "IMG_0001.JPG").write_bytes(_jpeg(1))  # there before: ignored
    (watched / "IMG_0001.CR2").write_bytes(b"raw")
    photo = _jpeg(2)

    def shoot():
        time.sleep(0.5)
        (watched / "notes.txt").write_text("not a photo")
        # the photo arrives in parts over 0.3 s, as over a slow sync; taking the file when first seen
        # would copy part of it (the camera polls every 0.15 s and waits for a size stable in two polls)
        parts = np.array_split(np.frombuffer(photo, np.uint8), 10)
        with open(watched / "IMG_0002.JPG", "wb") as fh:
            for part in parts:
                fh.write(part.tobytes())
                fh.flush()
                time.sleep(0.03)

    camera = open_camera(f"manual:{watched}", poll=0.15, timeout=20)
    assert any("watched folder" in line for line in camera.settings())
    assert any("yourself" in line for line in camera.settings())
    shooter = threading.Thread(target=shoot)
    shooter.start()
    try:
        path = camera.capture("x0-0", None, tmp_path / "set" / "captures" / "x0-0")
    finally:
        shooter.join()
        camera.close()
    assert path == tmp_path / "set" / "captures" / "x0-0.jpg"
    assert path.read_bytes() == photo
    assert (watched / "IMG_0002.JPG").read_bytes() == photo  # copied, not moved
    assert sorted(p.name for p in path.parent.iterdir()) == ["x0-0.jpg"]


def test_manual_watched_folder_times_out(tmp_path):
    watched = tmp_path / "card"
    watched.mkdir()
    (watched / "IMG_0001.JPG").write_bytes(_jpeg(1))
    with open_camera(f"manual:{watched}", timeout=0.5, poll=0.1) as camera:
        start = time.monotonic()
        with pytest.raises(CameraError) as info:
            camera.capture("x0-0", None, tmp_path / "captures" / "x0-0")
    assert time.monotonic() - start < 5
    assert "no new photo" in str(info.value) and str(watched) in str(info.value)


def test_manual_watched_folder_must_exist(tmp_path):
    with pytest.raises(CameraError, match="does not exist"):
        open_camera(f"manual:{tmp_path / 'nowhere'}")


def test_manual_key_mode_takes_the_file_the_user_put_in_place(tmp_path):
    captures = tmp_path / "captures"
    asked = []

    def user_copies_it(name):
        asked.append(name)
        if name == "x0-0":
            captures.mkdir(exist_ok=True)
            (captures / "x0-0.JPEG").write_bytes(b"jpeg bytes")

    with pytest.raises(InputError, match="wait_for_user"):
        open_camera("manual")
    with open_camera("manual", wait_for_user=user_copies_it) as camera:
        assert camera.capture("x0-0", None, captures / "x0-0") == captures / "x0-0.JPEG"
        with pytest.raises(CameraError) as info:
            camera.capture("x0-1", None, captures / "x0-1")
    assert asked == ["x0-0", "x0-1"]
    assert "x0-1" in str(info.value) and "x0-1.jpg" in str(info.value)


# -- sim -------------------------------------------------------------------------------------------

def test_sim_photographs_the_shown_patterns_and_records_the_truth(tmp_path):
    from lenticalib.calib.patterns.calibration_patterns import design_patterns, render_pattern
    from lenticalib.core.pattern_sets import write_patterns
    from lenticalib.core.profile import load_profile
    from lenticalib.sim.capture import photograph_pattern
    from lenticalib.sim.scene import Scene, random_scene

    pattern_set = design_patterns(192, 108, 8)
    write_patterns(tmp_path, pattern_set)
    captures = tmp_path / "captures"
    rasters = {p.name: render_pattern(p, 192, 108) for p in pattern_set.patterns}
    camera = open_camera("sim:5", resolution=(480, 320), subsamples=1)
    assert any("below the 1 megapixel" in line for line in camera.settings())
    with camera:
        with pytest.raises(CameraError, match="shown raster"):
            camera.capture("x0-0", None, captures / "x0-0")
        with pytest.raises(InputError, match="192x108"):
            camera.capture("x0-0", np.zeros((100, 200, 3), np.uint8), captures / "x0-0")
        first = camera.capture("x0-0", rasters["x0-0"], captures / "x0-0")
        second = camera.capture("f16-1", rasters["f16-1"], captures / "f16-1")
        record = json.loads((tmp_path / "simulation.json").read_text())
        assert record["status"] == "in progress" and [c["pattern"] for c in record["captures"]] == ["x0-0", "f16-1"]
    assert (first, second) == (captures / "x0-0.jpg", captures / "f16-1.jpg")
    photos = [cv2.imread(str(p)) for p in (first, second)]
    assert all(p is not None and p.shape == (320, 480, 3) for p in photos)
    assert np.abs(photos[0].astype(int) - photos[1].astype(int)).mean() > 2

    scene = random_scene(5, width=192, height=108, resolution=(480, 320), subsamples=1)
    assert Scene.from_dict(record) == scene
    assert record["pattern_set"]["set_id"] == pattern_set.set_id and record["truth"]["file"] == "truth.json"
    assert record["captures"][1]["file"] == "captures/f16-1.jpg"
    assert photograph_pattern(scene, "f16-1", rasters["f16-1"]) == second.read_bytes()  # reproducible
    truth = load_profile(tmp_path / "truth.json")
    assert truth.routing_key() == scene.truth_profile(8).routing_key()
    assert truth.provenance["method"] == "simulation"


def test_sim_record_is_complete_once_every_pattern_is_photographed(tmp_path):
    from lenticalib.calib.patterns.calibration_patterns import design_patterns, render_pattern
    from lenticalib.core.pattern_sets import write_patterns

    pattern_set = design_patterns(96, 64, 8)
    write_patterns(tmp_path, pattern_set)

    def photograph(camera, patterns):
        with camera:
            for pattern in patterns:
                camera.capture(pattern.name, render_pattern(pattern, 96, 64), tmp_path / "captures" / pattern.name)
        return json.loads((tmp_path / "simulation.json").read_text())

    # interrupted after 5 photos, resumed with the same scene: the earlier photos stay listed
    record = photograph(make_camera("sim", seed=2, resolution="320x240", subsamples=1), pattern_set.patterns[:5])
    assert record["status"] == "in progress" and len(record["captures"]) == 5
    record = photograph(make_camera("sim:2", resolution=(320, 240), subsamples=1, timeout=600, conditions=None),
                        pattern_set.patterns[5:])
    assert record["status"] == "complete" and record["seed"] == 2
    assert [c["pattern"] for c in record["captures"]] == pattern_set.names
    assert sorted(p.name for p in (tmp_path / "captures").iterdir()) == sorted(f"{n}.jpg" for n in pattern_set.names)
    # another scene over the same folder lists only its own photos: never "complete" with mixed scenes
    record = photograph(make_camera("sim:3", resolution=(320, 240), subsamples=1), pattern_set.patterns[:1])
    assert record["status"] == "in progress" and record["seed"] == 3
    assert [c["pattern"] for c in record["captures"]] == [pattern_set.names[0]]


def test_sim_needs_the_pattern_manifest(tmp_path):
    with open_camera("sim", resolution=(320, 240), subsamples=1) as camera:
        with pytest.raises(InputError, match="patterns.json"):
            camera.capture("x0-0", np.zeros((64, 96, 3), np.uint8), tmp_path / "captures" / "x0-0")
