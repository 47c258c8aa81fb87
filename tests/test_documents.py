"""The document envelope (lenticalib.core.files.documents): every format lenticalib writes carries
"format" and "format_version", is read through the one reader, and old spellings still read."""

import ast
import json
import os
import re
from pathlib import Path

import numpy as np
import pytest

import lenticalib
from lenticalib.core.files.documents import (FORMATS, DocumentFormat, check_envelope, read_document, read_json_file,
                                       write_document)
from lenticalib.core.errors import InputError, ProfileError
from lenticalib.core.profile import PanelProfile, load_profile, profile_from_dict, save_profile
from .cli_support import raises_one_line as one_line

PACKAGE = Path(lenticalib.__file__).parent
SAMPLE = DocumentFormat("lenticalib.sample", 2, "sample file", "write it again", reads=(1, 2),
                        aliases=("lenticalib-sample",))
PROFILE = PanelProfile(views=8, slant=0.2, period=12.0, offset=1.5, reference_view=0.0, width=64, height=48,
                       subpixel_order="RGB")



def write_json(path, data) -> Path:
    path.write_text(json.dumps(data))
    return path


def envelope_of(path) -> tuple:
    data = json.loads(Path(path).read_text())
    return data["format"], data["format_version"]


# ------------------------------------------------------------------ the table


def test_every_format_has_a_dotted_lenticalib_name_and_a_whole_version():
    assert len(FORMATS) >= 15
    for name, fmt in FORMATS.items():
        assert name == fmt.name and re.fullmatch(r"lenticalib\.[a-z]+(-[a-z]+)*", name), name
        assert isinstance(fmt.version, int) and fmt.version in fmt.versions and fmt.what and fmt.hint
        assert fmt.envelope() == {"format": name, "format_version": fmt.version}


def _sources():
    return {p: p.read_text() for p in PACKAGE.rglob("*.py")}


# Modules whose readers another part of issue 20 switches to core.documents; they write the
# envelope by hand until then (test_pattern_and_crosstalk_formats_match_the_table keeps them equal).
def _hand_written_envelopes(path: Path, text: str) -> list[str]:
    """``file:line`` of each dict literal with a "format_version"/"version" key or a "format"
    key whose value is a literal "lenticalib..." name."""
    found = []
    for node in ast.walk(ast.parse(text)):
        if isinstance(node, ast.Dict):
            for key, value in zip(node.keys, node.values):
                if not isinstance(key, ast.Constant):
                    continue
                literal = isinstance(value, ast.Constant) and str(value.value).startswith("lenticalib")
                if key.value in ("format_version", "version") or (key.value == "format" and literal):
                    found.append(f"{path.relative_to(PACKAGE).as_posix()}:{key.lineno}")
    return found


def test_no_module_spells_an_envelope_by_hand():
    """Every envelope is written from the table (DocumentFormat.envelope, write_document)."""
    found = [hit for p, text in _sources().items()
             if p.relative_to(PACKAGE).as_posix() != "core/files/documents.py"
             for hit in _hand_written_envelopes(p, text)]
    assert found == []


def test_every_format_in_the_table_is_used_by_the_package():
    text = "\n".join(t for p, t in _sources().items() if p.name != "documents.py")
    unused = [name for name in FORMATS if f'FORMATS["{name}"]' not in text and f'"{name}"' not in text]
    assert unused == []


def test_pattern_manifests_and_crosstalk_files_are_read_through_the_envelope(tmp_path):
    from lenticalib.calib.patterns import calibration_patterns as patterns
    from lenticalib.calib.patterns import crosstalk_patterns as xpatterns
    from lenticalib.core import crosstalk_document
    from lenticalib.core.crosstalk_document import read_crosstalk_document
    from lenticalib.core.pattern_sets import MANIFEST_NAME, read_pattern_folder, write_patterns

    assert patterns.DOCUMENT is FORMATS["lenticalib.patterns"]
    assert xpatterns.DOCUMENT is FORMATS["lenticalib.crosstalk-patterns"]
    assert crosstalk_document.DOCUMENT is FORMATS["lenticalib.crosstalk"]
    write_patterns(tmp_path, patterns.design_patterns(64, 64, 8))
    manifest = json.loads((tmp_path / MANIFEST_NAME).read_text())
    assert list(manifest)[:2] == ["format", "format_version"]
    assert (manifest["format"], manifest["format_version"]) == ("lenticalib.patterns", 2)
    (tmp_path / MANIFEST_NAME).write_text(json.dumps({**manifest, "format_version": 1}))
    with pytest.raises(InputError, match=r"field 'format_version': unknown version 1 .*this lenticalib reads version 2"):
        read_pattern_folder(tmp_path)
    crosstalk = tmp_path / "crosstalk.json"
    crosstalk.write_text(json.dumps({"format": "lenticalib.crosstalk", "views": 2, "matrix": [[1, 0], [0, 1]]}))
    with pytest.raises(InputError, match=r"crosstalk.json: field 'format_version' is missing"):
        read_crosstalk_document(crosstalk)
    crosstalk.write_text(json.dumps({"format": "lenticalib.profile", "format_version": 1}))
    with pytest.raises(InputError, match=r"field 'format': expected \"lenticalib.crosstalk\""):
        read_crosstalk_document(crosstalk)


# ------------------------------------------------------------------ check_envelope, read_document


def test_the_current_envelope_and_every_version_read_are_accepted():
    assert check_envelope({"format": "lenticalib.sample", "format_version": 2}, SAMPLE, "s.json") == 2
    assert check_envelope({"format": "lenticalib.sample", "format_version": 1}, SAMPLE, "s.json") == 1


def test_old_spellings_still_read():
    assert check_envelope({"format": "lenticalib-sample", "format_version": 2}, SAMPLE, "s.json") == 2
    assert check_envelope({"format": "lenticalib.sample", "version": 1}, SAMPLE, "s.json") == 1
    assert check_envelope({"format": "lenticalib-sample", "version": 2}, SAMPLE, "s.json") == 2


@pytest.mark.parametrize("data, words", [
    ({"format": "lenticalib.profile", "format_version": 2},
     "s.json: field 'format': expected \"lenticalib.sample\", got 'lenticalib.profile' (write it again)"),
    ({"format_version": 2}, "s.json: field 'format' is missing: not a sample file"),
    ({"format": "lenticalib.sample"}, "s.json: field 'format_version' is missing (this lenticalib reads sample "
                                      "files of version 1 or 2)"),
    ({"format": "lenticalib.sample", "format_version": 3},
     "s.json: field 'format_version': unknown version 3 (this lenticalib reads version 1 or 2; upgrade lenticalib)"),
    ({"format": "lenticalib.sample", "format_version": 0},
     "s.json: field 'format_version': unknown version 0 (this lenticalib reads version 1 or 2; write it again)"),
    ({"format": "lenticalib.sample", "format_version": "2"}, "s.json: field 'format_version': unknown version '2'"),
    ({"format": "lenticalib.sample", "format_version": True}, "s.json: field 'format_version': unknown version True"),
    ({"format": "lenticalib.sample", "version": 7}, "s.json: field 'version': unknown version 7"),
    ([1, 2], "s.json: is not a sample file: not a JSON object"),
])
def test_a_foreign_or_unknown_envelope_is_one_line_naming_the_file_and_field(data, words):
    assert one_line(lambda: check_envelope(data, SAMPLE, "s.json")).startswith(words)


def test_an_implicit_format_reads_a_document_without_envelope_as_the_current_version():
    fmt = DocumentFormat("lenticalib.sample", 2, "sample file", "x", implicit=True)
    assert check_envelope({}, fmt, "s.json") == 2
    assert "field 'format': expected" in one_line(lambda: check_envelope({"format": "x"}, fmt, "s.json"))


def test_read_document_names_the_file_and_field(tmp_path):
    good = write_document(tmp_path / "good.json", SAMPLE, {"value": 1, "format": "stale", "version": 9})
    assert read_document(good, SAMPLE) == {"format": "lenticalib.sample", "format_version": 2, "value": 1}
    wrong = write_json(tmp_path / "wrong.json", {"format": "lenticalib.cameras", "format_version": 1})
    assert one_line(lambda: read_document(wrong, SAMPLE)).startswith(
        f"{wrong}: field 'format': expected \"lenticalib.sample\", got 'lenticalib.cameras'")
    missing = tmp_path / "missing.json"
    assert one_line(lambda: read_document(missing, SAMPLE)) == f"{missing}: no such file (write it again)"
    assert one_line(lambda: read_document(missing, SAMPLE, "check the path")).endswith("(check the path)")
    binary = tmp_path / "photo.json"
    binary.write_bytes(b"\x89PNG\r\n\x1a\n" + bytes(20))
    assert "is a PNG image, not a JSON sample file" in one_line(lambda: read_document(binary, SAMPLE))
    nan = tmp_path / "nan.json"
    nan.write_text('{"format": "lenticalib.sample", "format_version": 2, "value": NaN}')
    assert "field 'value': NaN" in one_line(lambda: read_document(nan, SAMPLE))


def test_read_json_file_raises_the_error_class_it_is_given(tmp_path):
    with pytest.raises(ProfileError):
        read_json_file(tmp_path / "none.json", "profile", "x", ProfileError)
    with pytest.raises(InputError) as info:
        read_json_file(tmp_path / "none.json", "scene", "x")
    assert type(info.value) is InputError


# ------------------------------------------------------------------ each format, written by the package


def test_profile_round_trips_with_its_envelope_and_a_hand_written_one_reads(tmp_path):
    path = save_profile(PROFILE, tmp_path / "p.json")
    assert envelope_of(path) == ("lenticalib.profile", 1)
    assert load_profile(path) == PROFILE
    constants = {k: v for k, v in PROFILE.to_dict().items() if k not in ("format", "format_version")}
    assert profile_from_dict(constants) == PROFILE  # the envelope may be left out of a hand-written profile
    for change, words in (({"format_version": 3}, "field 'format_version': unknown version 3"),
                          ({"format": "lenticalib.cameras"}, "field 'format': expected \"lenticalib.profile\"")):
        bad = write_json(tmp_path / "bad.json", {**PROFILE.to_dict(), **change})
        text = one_line(lambda: load_profile(bad), ProfileError)
        assert text.startswith(f"{bad}: {words}"), text


def test_cameras_file_round_trips_with_its_envelope(tmp_path):
    from lenticalib.render.cameras.models import arc_cameras
    from lenticalib.render.cameras.view_cameras import ViewCameras

    cams = arc_cameras((-0.1, -0.1, -0.1), (0.1, 0.1, 0.1), n_views=4, view_size=(64, 48))
    path = tmp_path / "cameras.json"
    cams.write_json(path)
    assert envelope_of(path) == ("lenticalib.cameras", 1)
    back = ViewCameras.from_json(path)
    np.testing.assert_allclose(back.K, cams.K)
    np.testing.assert_allclose(back.viewmats, cams.viewmats)
    data = json.loads(path.read_text())
    del data["format_version"]
    write_json(path, data)
    assert one_line(lambda: ViewCameras.from_json(path)).startswith(f"{path}: field 'format_version' is missing")


def test_board_manifest_round_trips_and_an_old_version_key_reads(tmp_path):
    from lenticalib.calib.intrinsics.board import panel_board, read_board, write_manifest

    board = panel_board(1920, 1080, 0.25)
    path = write_manifest(board, tmp_path)
    assert envelope_of(path) == ("lenticalib.camera-board", 1)
    assert read_board(path) == board
    old = json.loads(path.read_text())
    old["version"] = old.pop("format_version")  # as lenticalib wrote it before the shared envelope
    write_json(path, old)
    assert read_board(path) == board
    old["version"] = 2
    write_json(path, old)
    assert one_line(lambda: read_board(path)).startswith(f"{path}: field 'version': unknown version 2")


def test_scene_and_simulation_record_carry_their_envelopes_and_read_back(tmp_path):
    from lenticalib.calib.patterns.calibration_patterns import design_patterns
    from lenticalib.sim.capture import SIMULATION_NAME, write_simulation_record
    from lenticalib.sim.scene import Scene, random_scene

    scene = random_scene(3, width=64, height=64, resolution=(320, 240), subsamples=1)
    doc = scene.to_dict()
    assert (doc["format"], doc["format_version"]) == ("lenticalib.simulation", 1)
    assert Scene.from_dict(doc) == scene
    path = write_simulation_record(tmp_path, scene, design_patterns(64, 64, 8), "complete", [], None)
    assert path == tmp_path / SIMULATION_NAME
    assert envelope_of(path) == ("lenticalib.simulation-run", 1)
    assert Scene.from_dict(read_document(path, FORMATS["lenticalib.simulation-run"])) == scene
    record = json.loads(path.read_text())
    record["format"] = "lenticalib.camera-simulation"
    assert one_line(lambda: Scene.from_dict(record, str(path))).startswith(
        f"{path}: field 'format': expected \"lenticalib.simulation-run\"")
    assert one_line(lambda: Scene.from_dict({**doc, "format_version": 5}, "scene.json")).startswith(
        "scene.json: field 'format_version': unknown version 5")


def test_crosstalk_truth_carries_its_envelope(tmp_path):
    from lenticalib.sim.capture import write_crosstalk_truth
    from lenticalib.sim.scene import random_scene

    scene = random_scene(4, width=64, height=48, resolution=(320, 240), subsamples=1)
    path = write_crosstalk_truth(tmp_path / "crosstalk-truth.json", scene, scene.truth_profile(8))
    assert envelope_of(path) == ("lenticalib.crosstalk-truth", 1)
    read_document(path, FORMATS["lenticalib.crosstalk-truth"])


def test_controller_description_is_read_through_the_envelope(tmp_path):
    from lenticalib.device.controller_families import load_family

    text = (PACKAGE.parent / "drivers" / "lc32.toml").read_text()
    assert load_family(PACKAGE.parent / "drivers" / "lc32.toml")
    other = tmp_path / "other.toml"
    other.write_text(text.replace('format = "lenticalib.driver"', 'format = "lenticalib.profile"'))
    assert one_line(lambda: load_family(other)).startswith(
        f"{other}: field 'format': expected \"lenticalib.driver\", got 'lenticalib.profile'")
    newer = tmp_path / "newer.toml"
    newer.write_text(text.replace("format_version = 1", "format_version = 2"))
    assert one_line(lambda: load_family(newer)).startswith(f"{newer}: field 'format_version': unknown version 2")


def test_emulator_announcements_carry_the_envelope_and_foreign_ones_are_skipped(tmp_path, monkeypatch):
    from lenticalib.device.emulator import serve
    from lenticalib.device.emulator.controller import EmulatedController, ensure_image

    monkeypatch.setenv("XDG_RUNTIME_DIR", str(tmp_path))
    controller = EmulatedController(ensure_image(tmp_path / "flash.img"))
    try:
        announcement = serve._Announcement("emu://test", controller, "pty")
    finally:
        controller.close()
    assert envelope_of(announcement.path) == ("lenticalib.emulator-announcement", 1)
    folder = announcement.path.parent
    mine = {"url": "emu://older", "pid": os.getpid()}  # as an older lenticalib announced: no envelope
    write_json(folder / "older.json", mine)
    write_json(folder / "foreign.json", {**mine, "url": "emu://foreign", "format": "lenticalib.profile"})
    write_json(folder / "newer.json", {**mine, "url": "emu://newer", "format": "lenticalib.emulator-announcement",
                                       "format_version": 9})
    assert sorted(e["url"] for e in serve.running_emulators()) == ["emu://older", "emu://test"]
