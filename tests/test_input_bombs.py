"""Small files that claim gigabytes, deep nesting and special files, for every reader (issue 45, rule 2).

Each bomb is run through the command a user would run, in a child process that first imports
what that command imports (numpy, and torch, mrcal, OpenCV or plyfile where the command needs
them), then limits its own address space to what it has mapped at that moment plus
:data:`HEADROOM` (500 MB, ``RLIMIT_AS``), then runs ``lenticalib.cli.main``.  A reader that
allocated what a bomb claims would die of a MemoryError (a traceback, not one line).  The
child also reports the growth of its peak resident memory (``VmHWM``, its own high-water mark;
``ru_maxrss`` would count the parent's memory at the fork) past that point, which must stay
under 500 MB too.  Every case ends in exit 2 and one error line naming the file, and
leaves its input byte-identical.  FIFOs and devices are refused at once (a child that waited
on one would run into the timeout).  Fixed seeds; nothing random.
"""

from __future__ import annotations

import hashlib
import json
import os
import subprocess
import sys
import textwrap
import zipfile
import zlib

import numpy as np
import pytest

from .cli_support import REPO, one_error_line

MB = 1_000_000
MiB = 1 << 20
HEADROOM = 500 * MB  # address space (and resident memory) a refusal may add past the imports

_CHILD = textwrap.dedent("""
    import importlib, json, resource, sys
    stats, modules, argv = sys.argv[1], sys.argv[2], sys.argv[3:]
    for name in filter(None, modules.split(",")):
        importlib.import_module(name)
    from lenticalib.cli import main

    def status(key):  # bytes; VmHWM is this process's own peak (ru_maxrss would include the parent's at fork)
        with open("/proc/self/status") as fh:
            return next(int(line.split()[1]) * 1024 for line in fh if line.startswith(key + ":"))

    base = status("VmHWM")
    resource.setrlimit(resource.RLIMIT_AS, (status("VmSize") + {headroom}, resource.getrlimit(resource.RLIMIT_AS)[1]))
    try:
        code = main(argv)
    except SystemExit as exc:
        code = exc.code
    peak = status("VmHWM")
    with open(stats, "w") as fh:
        json.dump({{"code": code, "grown": peak - base, "peak": peak}}, fh)
""").format(headroom=HEADROOM)


def _digest(path) -> str | None:
    p = os.fspath(path)
    if not os.path.isfile(p):
        return None  # a FIFO or a device: never read here
    with open(p, "rb") as fh:
        return hashlib.sha256(fh.read()).hexdigest()


def bounded(tmp_path, *argv, inputs=(), modules: str = "numpy", timeout: float = 120) -> str:
    """Run ``lenticalib ARGV`` in a child under the address-space limit (module docstring); it must
    exit 2 with one error line, grow by less than :data:`HEADROOM` and leave ``inputs`` as they
    were.  Returns the error line."""
    before = {str(p): _digest(p) for p in inputs}
    stats = tmp_path / "stats.json"
    stats.unlink(missing_ok=True)
    env = {**os.environ, "MALLOC_ARENA_MAX": "2", "OMP_NUM_THREADS": "1",
           "LENTICALIB_EMULATOR_DIR": str(tmp_path / "emulators")}  # an emulated unit made by mistake stays here
    run = subprocess.run([sys.executable, "-c", _CHILD, str(stats), modules, *map(str, argv)], cwd=REPO, env=env,
                         capture_output=True, text=True, timeout=timeout)
    assert stats.exists(), f"the child died (exit {run.returncode}): {run.stderr[-2000:]}"
    result = json.loads(stats.read_text())
    assert result["code"] == 2, (result, run.stdout, run.stderr)
    line = one_error_line(run.stderr)
    assert result["grown"] < HEADROOM, f"resident memory grew by {result['grown'] / MB:.0f} MB: {line}"
    assert {str(p): _digest(p) for p in inputs} == before
    print(f"MEMORY peak {result['peak'] / MB:.0f} MB, grown {result['grown'] / MB:.0f} MB: {line[:150]}")
    return line


# ------------------------------------------------------------------ JSON

VISUAL = {"pitch": {"value": 52.563}, "slope": {"value": -7.24467}, "center": {"value": 0.4017},
          "viewCone": {"value": 40.0}, "invView": {"value": 1.0}, "DPI": {"value": 324.0},
          "screenW": {"value": 1536.0}, "screenH": {"value": 2048.0}, "flipSubp": {"value": 0.0},
          "serial": "LKG-TEST"}


def _nested(depth: int) -> dict:
    value: object = 1
    for _ in range(depth):
        value = {"x": value}
    return value


def test_a_10_mb_visual_json_and_a_10_mb_profile_are_refused_from_their_size(tmp_path):
    visual = tmp_path / "visual.json"
    visual.write_text(json.dumps({**VISUAL, "extra": list(range(1_300_000))}))
    assert visual.stat().st_size > 9 * MB
    line = bounded(tmp_path, "profile", "import-lkg", visual, "--views", 48, "-o", tmp_path / "p.json",
                   inputs=[visual])
    assert str(visual) in line and "more than a visual.json can sensibly hold (at most 64.0 KiB)" in line
    assert not (tmp_path / "p.json").exists()
    profile = tmp_path / "profile.json"
    profile.write_text(json.dumps({"views": 8, "slant": -0.2, "period": 9.5, "offset": 1.25, "reference_view": 0.0,
                                   "width": 320, "height": 180, "provenance": {"notes": ["x" * 8] * 1_000_000}}))
    line = bounded(tmp_path, "profile", "show", profile, inputs=[profile])
    assert str(profile) in line and "more than a profile file can sensibly hold (at most 1.0 MiB)" in line


def test_a_visual_json_field_nested_1000_deep_is_one_line_at_read_time(tmp_path):
    visual = tmp_path / "visual.json"
    visual.write_text(json.dumps({**VISUAL, "extra": _nested(1000)}))
    out = tmp_path / "p.json"
    line = bounded(tmp_path, "profile", "import-lkg", visual, "--views", 48, "-o", out, inputs=[visual])
    assert str(visual) in line and "nested more than 64 levels deep" in line
    assert not out.exists()
    # the same calibration in a unit (the emulator stores it as given): read from the unit, the same line
    made = subprocess.run([sys.executable, "-m", "lenticalib", "emulate", "--looking-glass", visual, "--name", "deep"],
                          cwd=REPO, env={**os.environ, "LENTICALIB_EMULATOR_DIR": str(tmp_path / "emulators")},
                          capture_output=True, text=True, timeout=120)
    assert made.returncode == 0, made.stderr
    line = bounded(tmp_path, "device", "read", "lkg-emu://deep", "--views", 48, "-o", out)
    assert "lkg-emu://deep" in line and "nested more than 64 levels deep" in line
    assert not out.exists()


def test_a_15_mib_document_of_small_values_is_parsed_within_the_limits_or_refused_before_parsing(tmp_path):
    """Under the 16 MiB cap a document of 1.9 M numbers is parsed (and then refused for what it
    is, here not a crosstalk file) within the memory limit; 7 M values in the same bytes are
    refused from a count of the text before anything is built."""
    doc = tmp_path / "numbers.json"
    doc.write_text("[" + ",".join(["0.12345"] * 1_900_000) + "]")
    line = bounded(tmp_path, "crosstalk", "check", doc, "--max-adjacent", 0.1, inputs=[doc])
    assert str(doc) in line and "not a crosstalk file" in line
    doc.write_text("[" + ",".join(["1"] * 7_000_000) + "]")
    line = bounded(tmp_path, "crosstalk", "check", doc, "--max-adjacent", 0.1, inputs=[doc])
    assert str(doc) in line and "JSON values, more than the 2000000" in line


def test_the_number_check_builds_no_path_per_element(tmp_path):
    """1.5 M numbers under 50 levels of 200-character keys: a field path per element (10 KB each)
    would take 15 GB; the one pass builds a path only for the number it refuses."""
    key = "k" * 200
    doc: object = [0] * 1_500_000 + [float("inf")]
    for _ in range(50):
        doc = {key: doc}
    path = tmp_path / "deep-keys.json"
    path.write_text(json.dumps(doc).replace("Infinity", "1e400"))
    line = bounded(tmp_path, "crosstalk", "check", path, "--max-adjacent", 0.1, inputs=[path])
    assert str(path) in line and f"field '{key[:10]}" in line and "[1500000]': 1e400 is too large" in line


def test_a_rig_provenance_nested_100000_deep_is_one_line(tmp_path):
    from lenticalib.render.avatar.demo_avatar import make_demo_avatar
    from lenticalib.render.avatar.rig_file import save_rig

    rig = tmp_path / "rig.npz"
    save_rig(rig, make_demo_avatar(seed=1, count=2000))
    arrays = dict(np.load(rig))
    arrays["provenance"] = np.array('{"a":' * 100_000 + "1" + "}" * 100_000)
    np.savez(rig, **arrays)
    line = bounded(tmp_path, "render", rig, "--profile", REPO / "fixtures" / "panel-4k-32.json",
                   "-o", tmp_path / "out", inputs=[rig], modules="numpy,torch")
    assert str(rig) in line and "array 'provenance'" in line and "nested more than 64 levels deep" in line


# ------------------------------------------------------------------ .cameramodel

def _zip_of_zeros(name: str, size: int) -> bytes:
    """A zip whose member ``name`` (an .npy of float64 zeros) inflates to ``size`` bytes."""
    from numpy.lib import format as npformat
    import io

    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", zipfile.ZIP_DEFLATED) as archive:
        with archive.open(name, "w", force_zip64=True) as member:
            header = io.BytesIO()
            npformat.write_array_header_1_0(header, {"descr": "<f8", "fortran_order": False,
                                                     "shape": (size // 8,)})
            member.write(header.getvalue())
            chunk = bytes(16 * MiB)
            for _ in range(size // len(chunk)):
                member.write(chunk)
    return buf.getvalue()


def _cameramodel(optimization_inputs: bytes | None) -> str:
    import base64

    text = ("{\n    'lensmodel': 'LENSMODEL_OPENCV4',\n"
            "    'intrinsics': [1500.0, 1500.0, 799.5, 599.5, 0.0, 0.0, 0.0, 0.0],\n"
            "    'rt_cam_ref': [0, 0, 0, 0, 0, 0],\n    'imagersize': [1600, 1200],\n")
    if optimization_inputs is not None:
        text += f"    'icam_intrinsics': 0,\n    'optimization_inputs': {base64.b85encode(optimization_inputs)!r},\n"
    return text + "}\n"


@pytest.fixture(scope="module")
def cameramodel_bomb(tmp_path_factory):
    """A 1-2 MB .cameramodel whose optimization_inputs inflate to 1 GiB (mrcal would allocate it all)."""
    path = tmp_path_factory.mktemp("cam") / "bomb.cameramodel"
    path.write_text(_cameramodel(_zip_of_zeros("observations_board.npy", 1 << 30)))
    assert path.stat().st_size < 4 * MB
    return path


def test_a_cameramodel_whose_optimization_inputs_inflate_to_1_gib_is_refused_unread(tmp_path, cameramodel_bomb):
    line = bounded(tmp_path, "fit", tmp_path, "-o", tmp_path / "p.json", "--camera", cameramodel_bomb,
                   "--pixel-pitch", 0.2, inputs=[cameramodel_bomb], modules="numpy,mrcal")
    assert str(cameramodel_bomb) in line and "'optimization_inputs' inflates to 1.0 GiB" in line


def test_cameramodel_size_and_model_text_are_capped(tmp_path):
    from lenticalib.calib.camera.model_file import MAX_CAMERAMODEL_BYTES, MAX_MODEL_TEXT_BYTES, load_camera_model
    from lenticalib.core.errors import InputError

    plain = tmp_path / "plain.cameramodel"
    plain.write_text(_cameramodel(None))
    assert load_camera_model(plain).image_size == (1600, 1200)
    big = tmp_path / "big.cameramodel"
    big.write_text(_cameramodel(None).replace("'imagersize'", "'valid_intrinsics_region': [" + "[1.0, 2.0], "
                                              * (MAX_MODEL_TEXT_BYTES // 12) + "],\n    'imagersize'"))
    assert big.stat().st_size < MAX_CAMERAMODEL_BYTES
    with pytest.raises(InputError, match="of text besides 'optimization_inputs'"):
        load_camera_model(big)
    huge = tmp_path / "huge.cameramodel"
    huge.write_bytes(b"#" * (MAX_CAMERAMODEL_BYTES + 1))
    with pytest.raises(InputError, match=r"more than a camera model file can sensibly hold \(at most 8.0 MiB\)"):
        load_camera_model(huge)


# ------------------------------------------------------------------ meshes

@pytest.fixture(scope="module")
def avatar(tmp_path_factory):
    """A small 3DGS PLY avatar, a unit sphere of 400 Gaussians."""
    from lenticalib.render.avatar.gaussians import Gaussians
    from lenticalib.render.avatar.ply import save_ply

    rng = np.random.default_rng(0)
    n = 400
    means = rng.normal(size=(n, 3))
    means /= np.linalg.norm(means, axis=1, keepdims=True)
    f = np.float32
    path = tmp_path_factory.mktemp("avatar") / "ok.ply"
    save_ply(path, Gaussians(means.astype(f), np.tile(np.array([1, 0, 0, 0], f), (n, 1)), np.full((n, 3), 0.02, f),
                             np.full(n, 0.9, f), np.full((n, 1, 3), 0.5, f)))
    return path


def test_a_226_byte_mesh_ply_claiming_400_m_faces_is_refused_from_its_header(tmp_path, avatar):
    bomb = tmp_path / "bomb.ply"
    bomb.write_bytes(b"ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
                     b"property float z\nelement face 400000000\nproperty list uchar int vertex_indices\nend_header\n"
                     + bytes(36))
    line = bounded(tmp_path, "avatar", "diagnose", avatar, "--mesh", bomb, inputs=[avatar, bomb],
                   modules="numpy,torch,plyfile")
    assert str(bomb) in line and "the header claims 400000000 'face' rows" in line


def test_a_10_mb_obj_fan_is_refused_by_its_line_and_its_triangle_count(tmp_path, avatar):
    fan = tmp_path / "fan.obj"
    fan.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf " + " ".join(["1 2 3"] * 1_700_000) + "\n")
    assert fan.stat().st_size > 10 * MB
    line = bounded(tmp_path, "avatar", "diagnose", avatar, "--mesh", fan, inputs=[avatar, fan],
                   modules="numpy,torch,plyfile")
    assert str(fan) in line and "line 4 is longer than 64.0 KiB" in line
    fan.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\n" + ("f " + " ".join(["1 2 3"] * 2000) + "\n") * 800)
    assert fan.stat().st_size > 9 * MB
    line = bounded(tmp_path, "avatar", "diagnose", avatar, "--mesh", fan, inputs=[avatar, fan],
                   modules="numpy,torch,plyfile")
    assert str(fan) in line and "more than 2000000 triangles" in line


def test_mesh_polygons_are_split_into_fans_in_one_pass():
    from lenticalib.render.avatar.mesh import fan_triangles

    tris = fan_triangles(np.arange(9), np.array([3, 6]))  # a triangle, then a hexagon
    assert tris.tolist() == [[0, 1, 2], [3, 4, 5], [3, 5, 6], [3, 6, 7], [3, 7, 8]]


def test_ply_faces_of_one_size_are_read_as_one_array_and_row_by_row_reading_is_capped(tmp_path, monkeypatch):
    import plyfile

    from lenticalib.core.errors import InputError
    from lenticalib.render.avatar import mesh

    vert = np.array([(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0)], dtype=[("x", "f4"), ("y", "f4"), ("z", "f4")])
    quads = np.array([([0, 1, 2, 3],)], dtype=[("vertex_indices", "i4", (4,))])
    mixed = np.empty(2, dtype=[("vertex_indices", "O")])
    mixed["vertex_indices"][0], mixed["vertex_indices"][1] = np.array([0, 1, 2], "i4"), np.array([0, 1, 2, 3], "i4")
    for name, faces, text in (("quads.ply", quads, False), ("mixed.ply", mixed, False), ("ascii.ply", quads, True)):
        plyfile.PlyData([plyfile.PlyElement.describe(vert, "vertex"), plyfile.PlyElement.describe(faces, "face")],
                        text=text).write(str(tmp_path / name))
    assert mesh.load_mesh_file(tmp_path / "quads.ply").triangles.tolist() == [[0, 1, 2], [0, 2, 3]]
    assert mesh.load_mesh_file(tmp_path / "mixed.ply").triangles.tolist() == [[0, 1, 2], [0, 1, 2], [0, 2, 3]]
    monkeypatch.setattr(mesh, "MAX_POLYGON_ROWS", 0)
    assert len(mesh.load_mesh_file(tmp_path / "quads.ply").triangles) == 2  # one array: no row limit
    with pytest.raises(InputError, match="the mesh has 2 faces of mixed sizes, more than the 0 read that way"):
        mesh.load_mesh_file(tmp_path / "mixed.ply")
    with pytest.raises(InputError, match="the mesh has 1 faces in ASCII, more than the 0 read that way"):
        mesh.load_mesh_file(tmp_path / "ascii.ply")


# ------------------------------------------------------------------ videos

def test_a_video_whose_frames_are_wider_than_any_raster_is_refused_before_a_frame_is_read(tmp_path):
    import cv2

    from lenticalib.core.errors import InputError
    from lenticalib.render.student.frames import open_frames

    path = tmp_path / "wide.avi"
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"MJPG"), 30.0, (16400, 16))
    for _ in range(3):
        writer.write(np.zeros((16, 16400, 3), np.uint8))
    writer.release()
    assert 0 < path.stat().st_size < MB
    with pytest.raises(InputError, match=r"its frames are 16400x16 pixels, more than 16384 a side"):
        open_frames(path)


# ------------------------------------------------------------------ FIFOs and devices

@pytest.fixture()
def fifo(tmp_path):
    path = tmp_path / "pipe"
    os.mkfifo(path)
    return path


@pytest.fixture(scope="module")
def student(tmp_path_factory):
    """An untrained student driver, saved as 'driver distill' saves one (no distillation)."""
    torch = pytest.importorskip("torch")
    from lenticalib.render.avatar.rig import DEFAULT_LAYOUT
    from lenticalib.render.student.model import build_student
    from lenticalib.render.student.student_file import save_student

    torch.manual_seed(0)
    d = DEFAULT_LAYOUT.dim
    path = tmp_path_factory.mktemp("student") / "s.pt"
    save_student(path, {"layout": [[g, n] for g, n in DEFAULT_LAYOUT.groups],
                        "control_names": list(DEFAULT_LAYOUT.default_names()),
                        "crop": {"kind": "box", "box": [8, 8, 48, 48]}, "input_size": 64, "mean": torch.zeros(d),
                        "std": torch.ones(d), "active": torch.ones(d, dtype=torch.bool), "group_weights": {"jaw": 1.0},
                        "state_dict": build_student(d).state_dict(), "validation": {},
                        "provenance": {"command": "test"}})
    return path


@pytest.mark.parametrize("case", ["emulate", "profile", "mesh", "cameramodel", "frames", "predict", "image"])
def test_fifos_are_refused_at_once_wherever_a_file_is_read(tmp_path, fifo, case, avatar, request):
    names = {"mesh": "m.obj", "cameramodel": "c.cameramodel", "frames": "v.avi", "predict": "v.avi",
             "image": "q_qs8x4a1.7778.png"}
    link = tmp_path / names.get(case, "v.json")
    link.symlink_to(fifo)
    student = request.getfixturevalue("student") if case == "predict" else None
    argv, modules = {
        "emulate": (["emulate", "--looking-glass", link, "--name", "bombtest"], "numpy"),
        "profile": (["profile", "show", link], "numpy"),
        "mesh": (["avatar", "diagnose", avatar, "--mesh", link], "numpy,torch,plyfile"),
        "cameramodel": (["fit", tmp_path, "-o", tmp_path / "p.json", "--camera", link, "--pixel-pitch", 0.2],
                        "numpy,mrcal"),
        "frames": (["driver", "distill", "--frames", link, "--controls", tmp_path / "c.csv", "-o", tmp_path / "s.pt"],
                   "numpy,torch,cv2"),
        "predict": (["driver", "predict", student, "--frames", link, "-o", tmp_path / "c.csv"], "numpy,torch,cv2"),
        "image": (["encode", "--profile", REPO / "fixtures" / "panel-4k-32.json", "--quilt", link,
                   "-o", tmp_path / "out.png"], "numpy,cv2"),
    }[case]
    line = bounded(tmp_path, *argv, modules=modules, timeout=60)
    assert str(link) in line and "is not a regular file (a FIFO, device or socket)" in line


def test_dev_zero_as_a_visual_json_is_one_line(tmp_path):
    line = bounded(tmp_path, "emulate", "--looking-glass", "/dev/zero", "--name", "bombtest", timeout=60)
    assert "/dev/zero: is not a regular file" in line


def test_the_input_helper_never_reads_more_than_its_cap(tmp_path):
    from lenticalib.core.errors import InputError
    from lenticalib.core.files.input_files import check_input, read_input

    path = tmp_path / "f.bin"
    path.write_bytes(b"x" * 100)
    assert read_input(path, "thing", 100) == b"x" * 100 and check_input(path, "thing", 100) == 100
    with pytest.raises(InputError, match=r"is 100 bytes, more than a thing file can sensibly hold \(at most 99 "):
        read_input(path, "thing", 99)
    with pytest.raises(InputError, match="is a folder, not a thing file"):
        read_input(tmp_path, "thing", 99)
    with pytest.raises(InputError, match="no such file"):
        read_input(tmp_path / "absent", "thing", 99)
