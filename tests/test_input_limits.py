"""Inputs that are too large for memory, absurd numbers and misspelt keys (issue 19).

Files that *claim* huge sizes are refused from their headers, in one line, before their data is
read: an .npz member whose .npy header claims 10^12 elements, a rig without its 'format' array
beside 128 MiB of deflated zeros, a PLY header claiming 10^13 vertices, a 20000 x 20000 PNG of
under 400 KB.  None of the tests allocates what the files claim; the memory a refusal takes is
measured (tracemalloc for numpy's allocations, the process's peak RSS for the image decoder).
Every JSON document lenticalib reads refuses a 400-digit integer, 1e400, NaN, Infinity and wrong
types in one line naming the file (and, for unusable numbers, the field).  A misspelt profile key
is named with its close match.
"""

from __future__ import annotations

import copy
import io
import json
import resource
import struct
import zipfile
import zlib

import numpy as np
import pytest

from lenticalib.core.looking_glass import convert as lkg
from lenticalib.calib.patterns.crosstalk_patterns import design_crosstalk_patterns
from lenticalib.calib.crosstalk.result import read_crosstalk
from lenticalib.calib.intrinsics.board import panel_board, read_board, write_manifest
from lenticalib.calib.patterns.calibration_patterns import design_patterns
from lenticalib.core.errors import ImageError, InputError, ProfileError
from lenticalib.core.files.imageio import MAX_IMAGE_PIXELS, check_image_pixels, read_image
from lenticalib.core.files.documents import read_json_file
from lenticalib.core.pattern_sets import read_pattern_folder, write_patterns
from lenticalib.core.profile import PanelProfile, load_profile, save_profile
from lenticalib.render.cameras.view_cameras import ViewCameras
from lenticalib.render.cameras.models import arc_cameras
from lenticalib.sim.scene import Scene, random_scene

from .cli_support import refused
from .cli_support import raises_one_line as _raises_one_line
from .memory_support import peak_traced

SMALL = {"views": 8, "slant": -0.2, "period": 9.5, "offset": 1.25, "reference_view": 0.0, "width": 320,
         "height": 180, "subpixel_order": "RGB"}
VISUAL = {"pitch": {"value": 52.563}, "slope": {"value": -7.24467}, "center": {"value": 0.4017},
          "viewCone": {"value": 40.0}, "invView": {"value": 1.0}, "DPI": {"value": 324.0},
          "screenW": {"value": 1536.0}, "screenH": {"value": 2048.0}, "flipSubp": {"value": 0.0}}
HUGE_INT = "1" + "0" * 400
MiB = 1 << 20


# ------------------------------------------------------------------ numbers in every JSON reader

def _profile_doc(folder):
    path = folder / "profile.json"
    path.write_text(json.dumps(SMALL))
    return path, load_profile


def _visual_doc(folder):
    path = folder / "visual.json"
    path.write_text(json.dumps(VISUAL))
    return path, lambda p: lkg.import_visual_json(p, 45)


def _board_doc(folder):
    write_manifest(panel_board(640, 360, 0.3), folder)
    return folder / "board.json", read_board


def _crosstalk_doc(folder):
    path = folder / "crosstalk.json"
    path.write_text(json.dumps({"format": "lenticalib.crosstalk", "format_version": 1, "views": 2,
                                "matrix": [[0.9, 0.1], [0.1, 0.9]]}))
    return path, read_crosstalk


def _pattern_manifest(folder):
    write_patterns(folder, design_patterns(320, 180, 8))
    return folder / "patterns.json", lambda p: read_pattern_folder(p.parent)


def _crosstalk_manifest(folder):
    write_patterns(folder, design_crosstalk_patterns(PanelProfile(**SMALL)))
    return folder / "patterns.json", lambda p: read_pattern_folder(p.parent)


def _cameras_doc(folder):
    path = folder / "cameras.json"
    arc_cameras(np.array([-0.09, -0.12, -0.1]), np.array([0.09, 0.14, 0.11]), 2, view_size=(320, 180)).write_json(path)
    return path, ViewCameras.from_json


def _scene_doc(folder):
    path = folder / "scene.json"
    path.write_text(json.dumps(random_scene(1).to_dict()))
    return path, lambda p: Scene.from_dict(read_json_file(p, "scene", "check the --scene path"), str(p))


def _camera_model_doc(folder):
    from lenticalib.calib.camera.model_file import load_camera_model

    path = folder / "camera.json"
    path.write_text(json.dumps({"camera_matrix": [[1000.0, 0, 640.0], [0, 1000.0, 360.0], [0, 0, 1]],
                                "distortion": [0.01, 0, 0, 0, 0], "image_size": [1280, 720]}))
    return path, load_camera_model


def _number_paths(doc, path=()):
    """Paths of the numbers in ``doc`` (the first two items of each list)."""
    if isinstance(doc, dict):
        for key, value in doc.items():
            yield from _number_paths(value, path + (key,))
    elif isinstance(doc, list):
        for i, value in enumerate(doc[:2]):
            yield from _number_paths(value, path + (i,))
    elif isinstance(doc, (int, float)) and not isinstance(doc, bool):
        yield path


def _dotted(path) -> str:
    text = ""
    for part in path:
        text += f"[{part}]" if isinstance(part, int) else (f".{part}" if text else part)
    return text


UNUSABLE = [HUGE_INT, "-" + HUGE_INT, "1" + "0" * 5000, "1e400", "-1e400", "NaN", "Infinity", "-Infinity"]
WRONG_TYPES = ["[1]", "true", '"5"', "null", "{}", "1e308", "5e-324"]


@pytest.mark.parametrize("make", [_profile_doc, _visual_doc, _board_doc, _crosstalk_doc, _pattern_manifest,
                                  _crosstalk_manifest, _cameras_doc, _scene_doc, _camera_model_doc])
def test_every_json_reader_refuses_absurd_numbers_in_one_line_naming_file_and_field(tmp_path, make):
    path, read = make(tmp_path)
    read(path)  # the untouched document loads
    original = json.loads(path.read_text())
    paths = list(_number_paths(original))
    assert paths
    for where in paths:
        for literal in UNUSABLE + WRONG_TYPES:
            doc = copy.deepcopy(original)
            target = doc
            for part in where[:-1]:
                target = target[part]
            target[where[-1]] = "@@value@@"
            path.write_text(json.dumps(doc).replace('"@@value@@"', literal))
            try:
                read(path)
            except InputError as exc:
                text = str(exc)
                assert "\n" not in text and str(path) in text, text
                if literal in UNUSABLE:  # refused when read, naming the field
                    assert f"field '{_dotted(where)}': " in text, (where, text)
            # anything else escaping (OverflowError, ValueError, TypeError) fails the test
    path.write_text(json.dumps(original))


def test_a_profile_with_a_400_digit_slant_is_one_line_through_the_cli(tmp_path):
    path = tmp_path / "p.json"
    path.write_text(json.dumps(SMALL).replace('"slant": -0.2', f'"slant": {HUGE_INT}'))
    line = refused("profile", "validate", path, source=path)
    assert "field 'slant': 100000000000...000000 (401 digits) is too large" in line
    with pytest.raises(ProfileError, match="field 'slant': must be finite"):
        PanelProfile(**{**SMALL, "slant": 10 ** 400})  # built in code, no JSON: the same check, no OverflowError


@pytest.mark.parametrize("field, literal, words", [
    ("slope", HUGE_INT, "field 'slope.value': 100000000000...000000 (401 digits) is too large"),
    ("slope", "1e400", "field 'slope.value': 1e400 is too large"),
    ("pitch", "NaN", "field 'pitch.value': NaN is a non-finite number"),
    ("center", "1e308", "field 'center': gives a non-finite offset"),
    ("DPI", "[324]", "field 'DPI': must be a number"),
    ("screenW", "true", "field 'screenW': must be a number"),
])
def test_import_lkg_refuses_absurd_numbers_in_one_line(tmp_path, field, literal, words):
    doc = copy.deepcopy(VISUAL)
    doc[field] = {"value": "@@"}
    path = tmp_path / "visual.json"
    path.write_text(json.dumps(doc).replace('"@@"', literal))
    line = refused("profile", "import-lkg", path, "--views", 45, "-o", tmp_path / "out.json", source=path)
    assert words in line
    assert not (tmp_path / "out.json").exists()


def test_crosstalk_check_refuses_a_matrix_entry_of_1e400_in_one_line(tmp_path):
    path = tmp_path / "crosstalk.json"
    path.write_text('{"format": "lenticalib.crosstalk", "format_version": 1, "views": 2, '
                    '"matrix": [[0.9, 0.1], [1e400, 0.9]]}')
    line = refused("crosstalk", "check", path, "--max-adjacent", "0.1", source=path)
    assert "field 'matrix[1][0]': 1e400 is too large for a number" in line


@pytest.mark.parametrize("figures", ['{"adjacent_crosstalk": {"value": "0.1"}}', '{"adjacent_crosstalk": 0.1}', '[]',
                                     '{"adjacent_crosstalk": {"value": 0.0001, "sigma": 0.0}}'])
def test_crosstalk_check_judges_the_matrix_whatever_the_figures_block_says(tmp_path, cli, figures):
    """A hand-edited 'figures' block (wrong types, or a value that disagrees with the matrix) neither
    ends in a traceback nor bends the verdict: the figures are derived from the checked matrix."""
    path = tmp_path / "crosstalk.json"
    rows = [[0.6, 0.15, 0.1, 0.15], [0.15, 0.6, 0.15, 0.1], [0.1, 0.15, 0.6, 0.15], [0.15, 0.1, 0.15, 0.6]]
    path.write_text('{"format": "lenticalib.crosstalk", "format_version": 1, "views": 4, "matrix": %s, '
                    '"eye_separation_views": 2, "figures": %s}' % (json.dumps(rows), figures))
    code, out, err = cli("crosstalk", "check", path, "--max-adjacent", "40%", "--max-eye-pair", "20%")
    assert (code, err) == (1, ""), (code, err)
    assert out.splitlines() == [f"FAIL {path}: adjacent crosstalk (light from the two neighbouring views over the "
                                "view's own light) 50.00% exceeds the limit 40.00%"], out
    code, out, err = cli("crosstalk", "check", path, "--max-adjacent", "60%", "--max-eye-pair", "20%")
    assert code == 0 and out.startswith(f"PASS {path}: adjacent crosstalk 50.00% <= 60.00%"), (code, out, err)


# ------------------------------------------------------------------ misspelt keys

def test_a_misspelt_profile_key_is_named_with_its_close_match(tmp_path):
    doc = dict(SMALL)
    doc["slnat"] = doc.pop("slant")
    path = tmp_path / "p.json"
    path.write_text(json.dumps(doc))
    line = refused("profile", "validate", path, source=path)
    assert "unknown field 'slnat' (did you mean 'slant'?)" in line
    doc["slant"] = doc.pop("slnat")
    doc["reference_veiw"] = doc.pop("reference_view")
    doc["colour"] = "red"
    path.write_text(json.dumps(doc))
    text = _raises_one_line(lambda: load_profile(path), ProfileError)
    assert "unknown field 'colour'; also unknown: 'reference_veiw'" in text  # no close match for 'colour'
    doc.pop("colour")
    path.write_text(json.dumps(doc))
    assert "unknown field 'reference_veiw' (did you mean 'reference_view'?)" in _raises_one_line(
        lambda: load_profile(path), ProfileError)


def test_misspelt_keys_in_the_physical_block_and_a_scene_are_named_with_their_close_match(tmp_path):
    path = save_profile(PanelProfile(**SMALL), tmp_path / "p.json")
    doc = json.loads(path.read_text())
    doc["physical"] = {"pixel_pich_mm": 0.2}
    path.write_text(json.dumps(doc))
    assert "unknown field 'physical.pixel_pich_mm' (did you mean 'physical.pixel_pitch_mm'?)" in \
        _raises_one_line(lambda: load_profile(path), ProfileError)
    scene = random_scene(1).to_dict()
    scene["optics"]["lens_pich"] = scene["optics"].pop("lens_pitch")
    assert "unknown optics field 'lens_pich' (did you mean 'lens_pitch'?)" in \
        _raises_one_line(lambda: Scene.from_dict(scene, "scene.json"))


# ------------------------------------------------------------------ .npz and .npy headers

def _npy_header(shape, descr="<f4") -> bytes:
    buf = io.BytesIO()
    np.lib.format.write_array_header_1_0(buf, {"descr": descr, "fortran_order": False, "shape": shape})
    return buf.getvalue()


def _rig_arrays():
    from .test_rig import small_arrays

    return small_arrays()


def _npz(path, arrays, raw_members=()):
    """An .npz of ``arrays`` plus members written byte for byte: (name, header, data bytes, repeat)."""
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as archive:
        for name, value in arrays.items():
            buf = io.BytesIO()
            np.lib.format.write_array(buf, np.asanyarray(value), allow_pickle=False)
            archive.writestr(f"{name}.npy", buf.getvalue())
        for name, header, chunk, repeat in raw_members:
            with archive.open(f"{name}.npy", "w", force_zip64=True) as member:
                member.write(header)
                for _ in range(repeat):
                    member.write(chunk)
    return path


def test_a_rig_array_claiming_10_to_the_12_elements_is_refused_from_its_header(tmp_path):
    from lenticalib.render.avatar.rig_file import load_rig

    arrays = _rig_arrays()
    del arrays["means"]
    path = _npz(tmp_path / "rig.npz", arrays, [("means", _npy_header((10 ** 12, 3)), bytes(64), 1)])
    text = _raises_one_line(lambda: load_rig(path))
    assert text.startswith(f"{path}: array 'means' claims shape (1000000000000, 3) of float32") and "holds only" in text
    assert peak_traced(lambda: pytest.raises(InputError, load_rig, path)) < 16 * MiB
    refused("render", path, "--profile", save_profile(PanelProfile(**SMALL), tmp_path / "p.json"),
            "-o", tmp_path / "out.png", source=path)
    assert not (tmp_path / "out.png").exists()


def test_a_missing_rig_array_is_named_before_128_mib_of_deflated_zeros_are_inflated(tmp_path):
    from lenticalib.render.avatar.rig_file import load_rig

    arrays = _rig_arrays()
    del arrays["format"]
    path = _npz(tmp_path / "rig.npz", arrays, [("padding", _npy_header((32 * MiB,)), bytes(MiB), 128)])
    assert path.stat().st_size < 2 * MiB
    assert "array 'format' is missing" in _raises_one_line(lambda: load_rig(path))
    assert peak_traced(lambda: pytest.raises(InputError, load_rig, path)) < 16 * MiB


def test_rig_arrays_over_the_size_limit_are_refused_unread(tmp_path, monkeypatch):
    from lenticalib.render.avatar import rig_file

    path = _npz(tmp_path / "rig.npz", _rig_arrays())
    rig_file.load_rig(path)
    monkeypatch.setattr(rig_file, "MAX_RIG_BYTES", 4096)  # the small rig's arrays claim more than this
    text = _raises_one_line(lambda: rig_file.load_rig(path))
    assert "exceed the limit of 4.0 KiB" in text and text.startswith(str(path))


def test_a_control_npz_claiming_a_huge_track_and_a_pickle_are_one_line(tmp_path):
    from lenticalib.render.controls.files import load_controls

    path = _npz(tmp_path / "c.npz", {"t": np.arange(3.0)}, [("controls", _npy_header((10 ** 12, 70)), bytes(64), 1)])
    assert "array 'controls' claims shape (1000000000000, 70)" in _raises_one_line(lambda: load_controls(path))
    assert peak_traced(lambda: pytest.raises(InputError, load_controls, path)) < 16 * MiB
    np.savez(tmp_path / "p.npz", t=np.arange(3.0), controls=np.array([{"a": 1}] * 3, dtype=object))
    assert "pickled object array" in _raises_one_line(lambda: load_controls(tmp_path / "p.npz"))


# ------------------------------------------------------------------ PLY headers

PLY_PROPERTIES = ("x y z f_dc_0 f_dc_1 f_dc_2 opacity scale_0 scale_1 scale_2 rot_0 rot_1 rot_2 rot_3").split()


@pytest.mark.parametrize("encoding", ["binary_little_endian", "ascii"])
def test_a_ply_header_claiming_10_to_the_13_vertices_is_refused_before_reading(tmp_path, encoding):
    from lenticalib.render.avatar.ply import load_ply

    header = (f"ply\nformat {encoding} 1.0\nelement vertex {10 ** 13}\n"
              + "".join(f"property float {name}\n" for name in PLY_PROPERTIES) + "end_header\n")
    path = tmp_path / "avatar.ply"
    path.write_bytes(header.encode() + bytes(3 * 4 * len(PLY_PROPERTIES)))
    text = _raises_one_line(lambda: load_ply(path))
    assert "the header claims 10000000000000 'vertex' rows" in text and "168 bytes after the header" in text
    assert peak_traced(lambda: pytest.raises(InputError, load_ply, path)) < 16 * MiB
    refused("render", path, "--profile", save_profile(PanelProfile(**SMALL), tmp_path / "p.json"),
            "-o", tmp_path / "out.png", source=path)


# ------------------------------------------------------------------ image pixel limit

def _grey_png(width: int, height: int) -> bytes:
    """A valid all-black 8-bit grey PNG, compressed row by row (never the whole image in memory)."""
    def chunk(kind, data):
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))

    deflate, row = zlib.compressobj(9), bytes(width + 1)
    idat = b"".join([deflate.compress(row) for _ in range(height)] + [deflate.flush()])
    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", width, height, 8, 0, 0, 0, 0))
            + chunk(b"IDAT", idat) + chunk(b"IEND", b""))


@pytest.fixture(scope="module")
def huge_png(tmp_path_factory):
    path = tmp_path_factory.mktemp("png") / "huge_qs8x1a1.png"
    path.write_bytes(_grey_png(20000, 20000))
    return path


def test_a_20000_x_20000_png_is_refused_from_its_header(huge_png):
    assert huge_png.stat().st_size < 500_000
    before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss  # KiB on Linux
    text = _raises_one_line(lambda: read_image(huge_png), ImageError)
    grown = (resource.getrusage(resource.RUSAGE_SELF).ru_maxrss - before) * 1024
    assert text.startswith(f"{huge_png}: is 20000x20000 pixels (400 megapixels), over the limit of 268 megapixels")
    assert grown < 64 * MiB  # decoding would take 400 MB (grey) to 1.2 GB (as RGB)


def test_the_pixel_limit_admits_16k_rasters_and_large_camera_photos():
    assert MAX_IMAGE_PIXELS == 16384 * 16384  # 'lenticalib patterns' writes up to 16384 per side
    check_image_pixels(16384, 16384, "raster.png")
    check_image_pixels(14204, 10652, "photo.jpg")  # a 151-megapixel medium-format photo
    with pytest.raises(ImageError, match="16385x16384 pixels"):
        check_image_pixels(16385, 16384, "raster.png")


def test_huge_images_are_one_line_through_the_cli_and_the_photo_size_check(huge_png, tmp_path):
    from lenticalib.calib.intrinsics.pipeline import photo_size

    profile = save_profile(PanelProfile(**SMALL), tmp_path / "p.json")
    line = refused("encode", "--profile", profile, "--quilt", huge_png, "-o", tmp_path / "out.png", source=huge_png)
    assert "over the limit of 268 megapixels" in line
    assert "over the limit" in _raises_one_line(lambda: photo_size(huge_png), ImageError)
    npy = tmp_path / "views.npy"
    npy.write_bytes(_npy_header((10 ** 6, 10 ** 6, 3), "|u1") + bytes(64))
    assert "claims shape (1000000, 1000000, 3) of uint8" in _raises_one_line(lambda: read_image(npy), ImageError)
    with open(npy, "wb") as fh:  # a sparse file: the 400 MB of data take no disk
        fh.write(_npy_header((20000, 20000), "|u1"))
        fh.truncate(fh.tell() + 20000 * 20000)
    assert "is 20000x20000 pixels" in _raises_one_line(lambda: read_image(npy), ImageError)


def test_an_8000_x_8000_image_where_a_known_size_is_due_is_refused_from_its_header(tmp_path):
    """The issue's 186 KB 8000x8000 PNG (64 megapixels: under the general limit, so decoded today at
    1.3 GB) as one view of a folder, as a slide of a pattern set and as a photo the simulator takes:
    refused from its header, naming the size that was due, with no pixel decoded."""
    from lenticalib.core.slides import slides_from_path

    big = _grey_png(8000, 8000)
    assert len(big) < 200_000
    views = tmp_path / "views"
    views.mkdir()
    small = np.zeros((SMALL["height"] // 2, SMALL["width"] // 4, 3), np.uint8)
    from lenticalib.core.files.imageio import write_image

    for i in range(SMALL["views"]):
        write_image(views / f"v{i}.png", small)
    (views / f"v{SMALL['views'] - 1}.png").write_bytes(big)
    profile = save_profile(PanelProfile(**SMALL), tmp_path / "p.json")
    before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    line = refused("encode", "--profile", profile, "--views-dir", views, "-o", tmp_path / "out.png",
                   source=views / f"v{SMALL['views'] - 1}.png")
    assert f"is 8000x8000 pixels, v0.png is {small.shape[1]}x{small.shape[0]}" in line
    assert "all views must have one size" in line
    grown = (resource.getrusage(resource.RUSAGE_SELF).ru_maxrss - before) * 1024
    assert grown < 64 * 2 ** 20, f"peak RSS grew by {grown / 2 ** 20:.0f} MiB"
    slides = tmp_path / "slides"
    slides.mkdir()
    write_image(slides / "a.png", small)
    (slides / "b.png").write_bytes(big)
    shown, size = slides_from_path(slides)
    with pytest.raises(ImageError, match=r"b.png: is 8000x8000 pixels, a.png is"):
        shown[1].load()


def test_a_damaged_deflate_stream_in_an_npz_is_one_line(tmp_path):
    """A bit flipped inside a compressed member makes zlib fail (not a CRC error): one InputError."""
    from lenticalib.core.files.arrayfile import load_npz

    buf = io.BytesIO()
    np.savez_compressed(buf, a=np.arange(100000) % 7)
    data = bytearray(buf.getvalue())
    data[30 + len("a.npy") + 20] ^= 0xFF  # 20 bytes into member a's deflate stream
    path = tmp_path / "bad.npz"
    path.write_bytes(bytes(data))
    assert "Error -3 while decompressing" in _raises_one_line(lambda: load_npz(path), InputError)
