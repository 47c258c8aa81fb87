"""Hostile student files, torch zip bombs and live student sources (issue 45).

A student file is a file like any other: every field is checked (type, shape, range, finite) and
refused in one line naming the file and the field, before OpenCV, torch or numpy allocate what a
field says.  A ``.pt`` (student or backbone weights) or an ``.npz`` whose zip members inflate to
more than the format holds is refused from the central directory, before anything is inflated:
the 1 GiB bomb is loaded under an address-space limit of 500 MB.  The ``student:`` spec bounds the
camera index before OpenCV sees it and keeps a '+' in a path a '+'.  Tiny students are built here
with ``torch.save`` (an untrained network: no distillation).
"""

from __future__ import annotations

import contextlib
import io
import os
import resource
import struct
import zipfile

import numpy as np
import pytest

torch = pytest.importorskip("torch")
pytest.importorskip("torchvision")

from lenticalib.core.files.arrayfile import load_npz  # noqa: E402
from lenticalib.core.errors import InputError  # noqa: E402
from lenticalib.core.files.imageio import write_image  # noqa: E402
from lenticalib.render.controls.sources import open_controls  # noqa: E402
from lenticalib.render.avatar.rig import DEFAULT_LAYOUT  # noqa: E402
from lenticalib.render.student.frames import CameraFrames, MAX_CAMERA_INDEX  # noqa: E402
from lenticalib.render.student.live import parse_student_spec  # noqa: E402
from lenticalib.render.student.model import build_student  # noqa: E402
from lenticalib.render.student.student_file import load_student, save_student  # noqa: E402

from .cli_support import raises_one_line, refused  # noqa: E402

D = DEFAULT_LAYOUT.dim
MiB = 1 << 20
AS_LIMIT = 500 * MiB  # the address space a refusal may add (issue 45: peaks under 500 MB)


@pytest.fixture(scope="module")
def record():
    """A valid student record (an untrained network), as ``driver distill`` saves it."""
    torch.manual_seed(0)
    return {"layout": [[g, s] for g, s in DEFAULT_LAYOUT.groups], "control_names": list(DEFAULT_LAYOUT.default_names()),
            "crop": {"kind": "box", "box": [8, 8, 48, 48]}, "input_size": 64, "mean": torch.zeros(D),
            "std": torch.ones(D), "active": torch.ones(D, dtype=torch.bool), "group_weights": {"jaw": 1.0},
            "state_dict": build_student(D).state_dict(), "validation": {}, "provenance": {"command": "test"}}


@pytest.fixture(scope="module")
def frames(tmp_path_factory):
    folder = tmp_path_factory.mktemp("frames")
    rng = np.random.default_rng(0)
    for k in range(2):
        write_image(folder / f"frame-{k}.png", rng.integers(0, 255, (64, 64, 3), dtype=np.uint8))
    return folder


def _save(path, record, **changes):
    save_student(path, {**record, **changes})
    return path


@contextlib.contextmanager
def _address_space(extra: int):
    """The process may map at most ``extra`` bytes more than it has mapped now (RLIMIT_AS)."""
    with open("/proc/self/status") as fh:
        vm = next(int(line.split()[1]) * 1024 for line in fh if line.startswith("VmSize:"))
    soft, hard = resource.getrlimit(resource.RLIMIT_AS)
    resource.setrlimit(resource.RLIMIT_AS, (vm + extra, hard))
    try:
        yield
    finally:
        resource.setrlimit(resource.RLIMIT_AS, (soft, hard))


def test_a_valid_student_loads(record, tmp_path):
    s = load_student(_save(tmp_path / "s.pt", record))
    assert s.input_size == 64 and s.layout == DEFAULT_LAYOUT and s.crop == {"kind": "box", "box": [8, 8, 48, 48]}
    assert s.mean.shape == (D,) and s.active.all()


def _nested(depth: int) -> dict:
    node: dict = {}
    for _ in range(depth):
        node = {"a": node}
    return node


def _nan_weight(state):
    state = dict(state)
    state["head.3.bias"] = torch.full_like(state["head.3.bias"], float("nan"))
    return state


# (field changes, the field the line names, words of the line): the cases first
FIELD_CASES = [
    (dict(input_size=200000), "input_size", "is 200000, expected a whole number 32..512"),
    (dict(input_size=-5), "input_size", "is -5"),
    (dict(input_size="64"), "input_size", "is '64'"),
    (dict(layout=[["expression", 2_000_000_000]]), "layout[0]", "size 1..4096"),
    (dict(layout=[["expression", "50"]]), "layout[0]", "['expression', '50']"),
    (dict(layout=[["g", 4000], ["h", 4000]]), "layout", "adds up to 8000 controls"),
    (dict(mean=[0.0] * D), "mean", "expected a float tensor of shape (70,)"),
    (dict(mean=torch.zeros(1000)), "mean", "has shape (1000,), expected (70,)"),
    (dict(crop={"kind": "python", "box": [0, 0, 16, 16]}), "crop", "kind 'python'"),
    (dict(crop={"kind": "box", "box": [float("nan"), 8, 48, 48]}), "crop", "is not four finite numbers"),
    (dict(crop={"kind": "box", "box": [8, 8, 1e9, 48]}), "crop", "out of range"),
    (dict(crop={"kind": "auto", "detector": "haar-frontalface", "scale": float("inf"), "smoothing": 0.7}),
     "crop", "scale inf"),
    (dict(std=torch.full((D,), float("nan"))), "std[0]", "not a finite float32"),
    (dict(std=torch.zeros(D)), "std[0]", "expected a standard deviation > 0"),
    (dict(mean=torch.full((D,), 1e300, dtype=torch.float64)), "mean[0]", "not a finite float32"),
    (dict(active=torch.ones(D)), "active", "expected a bool tensor"),
    (dict(control_names=["x"] * 3), "control_names", "expected 70 names"),
    (dict(state_dict={"head.0.weight": torch.zeros(3)}), "state_dict", "does not fit"),
    (dict(state_dict={"x": [1.0]}), "state_dict", "not a dict of names to tensors"),
    (dict(provenance=_nested(200)), "provenance", "nested more than 64 levels"),
    (dict(validation=[1, 2]), "validation", "expected an object"),
]


@pytest.mark.parametrize("changes, field, words", FIELD_CASES, ids=[c[1] + f"-{k}" for k, c in enumerate(FIELD_CASES)])
def test_every_field_is_checked_in_one_line_naming_file_and_field(record, tmp_path, changes, field, words):
    path = _save(tmp_path / "bad.pt", record, **changes)
    text = raises_one_line(lambda: load_student(path))
    assert text.startswith(f"{path}: field '{field}' ") and words in text, text


def test_non_finite_weights_are_refused(record, tmp_path):
    path = _save(tmp_path / "bad.pt", record, state_dict=_nan_weight(record["state_dict"]))
    assert "field 'state_dict.head.3.bias' holds values that are not finite" in raises_one_line(
        lambda: load_student(path))


@pytest.mark.parametrize("changes, field", [(dict(input_size=200000), "input_size"),
                                            (dict(layout=[["expression", 2_000_000_000]]), "layout[0]"),
                                            (dict(crop={"kind": "box", "box": [float("nan"), 8, 48, 48]}), "crop"),
                                            (dict(mean=torch.zeros(1000)), "mean")])
def test_driver_predict_refuses_a_hostile_student_before_writing(record, frames, tmp_path, changes, field):
    path = _save(tmp_path / "bad.pt", record, **changes)
    before = path.read_bytes()
    line = refused("driver", "predict", path, "--frames", frames, "-o", tmp_path / "p.csv", source=path)
    assert f"field '{field}'" in line
    assert not (tmp_path / "p.csv").exists() and path.read_bytes() == before


def test_a_student_of_another_kind_is_one_line(record, tmp_path):
    torch.save([1, 2, 3], tmp_path / "list.pt")
    assert "is not a student driver" in raises_one_line(lambda: load_student(tmp_path / "list.pt"))
    (tmp_path / "text.pt").write_text("hello")
    assert "not a readable student file (not a zip archive)" in raises_one_line(
        lambda: load_student(tmp_path / "text.pt"))
    os.mkfifo(tmp_path / "fifo.pt")
    assert "is not a regular file" in raises_one_line(lambda: load_student(tmp_path / "fifo.pt"))


# ------------------------------------------------------------------ zip bombs

def _pt_bomb(path, record, inflated: int):
    """``record`` saved by torch, then its 'mean' storage replaced by ``inflated`` bytes of zeros,
    deflated (a few MB): a valid zip that makes torch inflate (and allocate) all of it."""
    buf = io.BytesIO()
    torch.save({"format": "lenticalib.student-driver", "format_version": 1, **record, "mean": torch.zeros(7)}, buf)
    buf.seek(0)
    with zipfile.ZipFile(buf) as src, zipfile.ZipFile(path, "w", compresslevel=1) as out:
        for info in src.infolist():
            data = src.read(info)
            if data == bytes(28) and "/data/" in info.filename:  # mean: 7 float32 zeros
                bomb = zipfile.ZipInfo(info.filename)
                bomb.compress_type = zipfile.ZIP_DEFLATED
                with out.open(bomb, "w", force_zip64=True) as member:
                    chunk = bytes(16 * MiB)
                    for _ in range(inflated // len(chunk)):
                        member.write(chunk)
            else:
                out.writestr(info, data)
    return path


@pytest.fixture(scope="module")
def pt_bomb(record, tmp_path_factory):
    return _pt_bomb(tmp_path_factory.mktemp("bomb") / "bomb.pt", record, 1 << 30)


def test_a_student_pt_inflating_to_1_gib_is_refused_from_its_directory(pt_bomb):
    assert pt_bomb.stat().st_size < 12 * MiB
    before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    with _address_space(AS_LIMIT):
        text = raises_one_line(lambda: load_student(pt_bomb))
    grown = (resource.getrusage(resource.RUSAGE_SELF).ru_maxrss - before) * 1024
    assert text.startswith(f"{pt_bomb}: its zip members inflate to 1.0 GiB in all"), text
    assert "more than a student file can sensibly hold (at most 32.0 MiB)" in text
    assert grown < 64 * MiB


def test_backbone_weights_inflating_to_1_gib_are_refused_from_the_directory(pt_bomb, frames, tmp_path):
    from lenticalib.render.student.distill import DistillOptions, distill_student

    with _address_space(AS_LIMIT):
        text = raises_one_line(lambda: build_student(D, backbone_weights=pt_bomb))
    assert text.startswith(f"{pt_bomb}: its zip members inflate to 1.0 GiB in all") and "backbone weights" in text
    many = tmp_path / "many"
    many.mkdir()
    for k in range(64):
        (many / f"f-{k:02d}.png").write_bytes((frames / "frame-0.png").read_bytes())
    (tmp_path / "c.csv").write_text("t,jaw.0\n" + "".join(f"{k / 30},0\n" for k in range(64)))
    with _address_space(AS_LIMIT):
        with pytest.raises(InputError, match="inflate to 1.0 GiB"):
            distill_student(many, tmp_path / "c.csv", tmp_path / "s.pt", crop="0,0,64,64", backbone_weights=pt_bomb,
                            options=DistillOptions(epochs=1, input_size=32))
    assert not (tmp_path / "s.pt").exists()


def test_a_pickle_over_its_cap_and_too_many_members_are_refused(record, tmp_path):
    path = _save(tmp_path / "big-pickle.pt", record, provenance={"notes": "x" * (2 * MiB)})
    assert "'archive/data.pkl' inflates to 2.0 MiB, more than a student file's pickle holds (at most 1.0 MiB)" \
        in raises_one_line(lambda: load_student(path))
    with zipfile.ZipFile(tmp_path / "many.pt", "w") as z:
        for k in range(1100):
            z.writestr(f"archive/data/{k}", b"")
    assert "lists 1100 members" in raises_one_line(lambda: load_student(tmp_path / "many.pt"))


def _claim(data: bytes, name: bytes, size: int) -> bytes:
    """The zip ``data`` with the central directory's uncompressed size of member ``name`` set to
    ``size`` (< 4 GiB; nothing else changed: the claim alone must be refused)."""
    at = data.index(b"PK\x01\x02")
    while True:
        length = struct.unpack_from("<H", data, at + 28)[0]
        if data[at + 46:at + 46 + length] == name:
            return data[:at + 24] + struct.pack("<L", size) + data[at + 28:]
        at = data.index(b"PK\x01\x02", at + 46)


def test_an_npz_whose_directory_claims_gibs_is_refused_before_inflating(tmp_path):
    from lenticalib.render.controls.files import load_controls

    buf = io.BytesIO()
    np.savez_compressed(buf, t=np.arange(3.0), controls=np.zeros((3, D), np.float32))
    path = tmp_path / "c.npz"
    path.write_bytes(_claim(buf.getvalue(), b"controls.npy", 3 << 30))
    with _address_space(AS_LIMIT):
        text = raises_one_line(lambda: load_controls(path))
    assert text.startswith(f"{path}: its zip members inflate to 3.0 GiB in all (the largest, 'controls.npy'"), text
    assert "more than a .npz file can sensibly hold (at most 256.0 MiB)" in text
    assert "inflate to 3.0 GiB" in raises_one_line(lambda: load_npz(path, max_bytes=2 << 30))


# ------------------------------------------------------------------ live student sources

def test_the_camera_index_is_bounded_before_opencv(record, tmp_path):
    path = _save(tmp_path / "s.pt", record)
    for bad in ("-1", "99999999999999999999", "100", "200", "+1", " 1", "1.0", "\u0663", ""):
        with pytest.raises(InputError, match="camera|no value") as err:
            parse_student_spec(f"student:{path}?camera={bad}")
        assert err.value.source == "controls" and "\n" not in str(err.value)
    assert parse_student_spec(f"student:{path}?camera={MAX_CAMERA_INDEX}")[1]["camera"] == MAX_CAMERA_INDEX
    for bad in (-1, 100, 10 ** 20, True):
        with pytest.raises(InputError, match=f"0..{MAX_CAMERA_INDEX}"):
            CameraFrames(bad)
    for spec in (f"student:{path}?camera=0&camera=1", f"student:{path}?camera=0&speed=2",
                 f"student:{path}?video=a&camera=0"):
        with pytest.raises(InputError):
            parse_student_spec(spec)


def test_camera_minus_one_is_one_line_not_a_crash(record, tmp_path, cli_process):
    """Through ``play`` in a real process: OpenCV's V4L2 backend crashes on -1 (exit 139)."""
    from lenticalib.render.avatar.demo_avatar import make_demo_avatar
    from lenticalib.render.avatar.rig_file import save_rig

    from .cli_support import REPO

    path = _save(tmp_path / "s.pt", record)
    save_rig(tmp_path / "demo.npz", make_demo_avatar(seed=2, count=2000))
    done = cli_process("play", tmp_path / "demo.npz", "--profile", REPO / "fixtures" / "panel-4k-32.json",
                       "--headless", "--frames", "1", "--view-size", "96x54", "--controls",
                       f"student:{path}?camera=-1", timeout=300)
    assert done.returncode == 2, (done.returncode, done.stderr[-2000:])
    assert done.stderr.strip() == ("lenticalib: error: --controls: camera '-1' is not a camera index 0..99 (use "
                                   "student:student.pt?camera=0 or student:student.pt?video=FILE)")


def test_a_plus_in_a_video_path_stays_a_plus(record, tmp_path):
    import cv2

    path = _save(tmp_path / "s.pt", record)
    assert parse_student_spec(f"student:{path}?video=clip+1.avi")[1]["video"] == "clip+1.avi"
    assert parse_student_spec(f"student:{path}?video=a%20b.avi")[1]["video"] == "a%20b.avi"
    writer = cv2.VideoWriter(str(tmp_path / "clip+1.avi"), cv2.VideoWriter_fourcc(*"MJPG"), 30.0, (64, 64))
    for k in range(3):
        writer.write(np.full((64, 64, 3), 40 * k, np.uint8))
    writer.release()
    source = open_controls(f"student:{path}?video={tmp_path / 'clip+1.avi'}", DEFAULT_LAYOUT)
    try:
        assert source.frames.spec == str(tmp_path / "clip+1.avi")
        assert source.latest(0.0)[1].shape == (D,)
    finally:
        source.close()
    os.mkfifo(tmp_path / "fifo.avi")
    with pytest.raises(InputError, match="is not a regular file"):
        open_controls(f"student:{path}?video={tmp_path / 'fifo.avi'}", DEFAULT_LAYOUT)


def test_predict_refuses_a_fifo_for_frames(record, tmp_path):
    path = _save(tmp_path / "s.pt", record)
    os.mkfifo(tmp_path / "frames.avi")
    line = refused("driver", "predict", path, "--frames", tmp_path / "frames.avi", "-o", tmp_path / "p.csv",
                   source=tmp_path / "frames.avi")
    assert "is not a regular file (a FIFO, device or socket)" in line


def test_a_device_other_than_cpu_or_cuda_is_refused_before_the_first_frame(record, tmp_path):
    path = _save(tmp_path / "s.pt", record)
    for device in ("meta", "mps", "cpu:1", "cuda:99999999999999999999"):
        with pytest.raises(InputError, match="cpu, cuda") as err:
            open_controls(f"student:{path}?video=x.avi&device={device}", DEFAULT_LAYOUT)
        assert err.value.source == "controls" and "device" in str(err.value)
