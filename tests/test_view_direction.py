"""Which way a profile's views run (``view_direction``): the profile field, ``profile show /
compare / set-direction``, the renderer's warning, Looking Glass import/export, the device record
(which cannot hold it), the simulator's truth, ``fit --moved-right`` and ``patterns --direction``.

The direction is +1 when the view index grows as a viewer in front of the panel moves to the
right, -1 when it falls, None (absent in the file) when unknown.
"""

from __future__ import annotations

import json
import math
import shutil
import types
from pathlib import Path

import numpy as np
import pytest

from lenticalib.core.looking_glass import convert as lkg, vendor_rule as lkg_rule
from lenticalib.calib.routing.direction import (DIRECTION_PATTERN_NAME, add_moved_right, direction_from_moved_right,
                                        direction_raster, direction_view, direction_views)
from lenticalib.core.errors import InputError, ProfileError
from lenticalib.core.profile import PanelProfile, load_profile, make_provenance, save_profile
from lenticalib.core.view_direction import direction_warning, with_direction

from .cli_support import one_error_line

REPO = Path(__file__).resolve().parents[1]
EIGHT = {"views": 8, "slant": 0.19, "period": 7.4, "offset": 1.5, "reference_view": 4,
         "width": 96, "height": 54, "subpixel_order": "BGR"}
PORTRAIT = {"configVersion": "1.0", "serial": "LKG-P-TEST", "pitch": {"value": 52.5630},
            "slope": {"value": -7.24467}, "center": {"value": 0.40170}, "viewCone": {"value": 40.0},
            "invView": {"value": 1.0}, "DPI": {"value": 324.0}, "screenW": {"value": 1536.0},
            "screenH": {"value": 2048.0}, "flipImageX": {"value": 0.0}, "flipImageY": {"value": 0.0},
            "flipSubp": {"value": 0.0}}
SIM_W, SIM_H, SIM_VIEWS, CAMERA = 640, 360, 8, (1200, 900)


def _write(tmp_path, data, name="p.json") -> Path:
    path = tmp_path / name
    path.write_text(data if isinstance(data, str) else json.dumps(data))
    return path


# ---------------------------------------------------------------------------------------------
# 1. the profile field
# ---------------------------------------------------------------------------------------------

def test_old_files_load_as_unknown_and_a_direction_round_trips(tmp_path):
    old = load_profile(_write(tmp_path, EIGHT))
    assert old.view_direction is None
    assert "view_direction" not in old.to_dict()  # an unknown direction is left out of the file
    for value in (1, -1):
        p = PanelProfile(**EIGHT, view_direction=value)
        back = load_profile(save_profile(p, tmp_path / f"d{value}.json"))
        assert back.view_direction == value
        keys = list(json.loads((tmp_path / f"d{value}.json").read_text()))
        assert keys.index("view_direction") == keys.index("subpixel_order") + 1
    assert load_profile(_write(tmp_path, {**EIGHT, "view_direction": None})).view_direction is None


@pytest.mark.parametrize("value", [0, 2, -2, 1.0, -1.0, "+1", "-1", True, False, [1], {"value": 1}])
def test_a_direction_other_than_plus_or_minus_one_is_refused_naming_the_field(tmp_path, value):
    path = _write(tmp_path, {**EIGHT, "view_direction": value})
    with pytest.raises(ProfileError) as err:
        load_profile(path)
    text = str(err.value)
    assert "field 'view_direction'" in text and str(path) in text and "\n" not in text
    with pytest.raises(ProfileError, match="view_direction"):
        PanelProfile(**EIGHT, view_direction=value)


def test_the_direction_does_not_change_routing_or_equality():
    a, b, c = (PanelProfile(**EIGHT, view_direction=d) for d in (1, -1, None))
    assert a == b == c and hash(a) == hash(b) == hash(c)
    assert a.routing_key() == b.routing_key() == c.routing_key()


def test_direction_warning_only_for_an_unknown_direction():
    assert direction_warning(PanelProfile(**EIGHT, view_direction=1)) is None
    assert direction_warning(PanelProfile(**EIGHT, view_direction=-1)) is None
    text = direction_warning(PanelProfile(**EIGHT, name="hall panel"))
    assert text and "\n" not in text
    assert text.startswith("'hall panel': the profile does not say which way its views run: ")
    for part in ("lenticalib patterns --direction", "--moved-right", "set-direction"):
        assert part in text


def test_with_direction_keeps_the_provenance_and_notes_how():
    p = PanelProfile(**EIGHT, provenance=make_provenance("test"))
    q = with_direction(p, -1, "set by hand", previous=None)
    assert q.view_direction == -1 and q.provenance["method"] == "test"
    note = q.provenance["view_direction"]
    assert note["value"] == -1 and note["method"] == "set by hand" and note["set"] and note["lenticalib_version"]
    assert note["evidence"] == {"previous": None}
    assert p.view_direction is None and "view_direction" not in p.provenance  # the original is unchanged


# ---------------------------------------------------------------------------------------------
# 2. profile show / compare / set-direction
# ---------------------------------------------------------------------------------------------

def test_show_prints_the_direction_or_unknown(tmp_path, cli):
    path = _write(tmp_path, EIGHT)
    code, out, _ = cli("profile", "show", path)
    assert code == 0 and "view_direction  unknown" in out
    save_profile(PanelProfile(**EIGHT, view_direction=-1), path)
    code, out, _ = cli("profile", "show", path)
    assert "view_direction  -1 (the view index falls as the viewer moves right)" in out
    code, out, _ = cli("profile", "show", path, "--json")
    assert json.loads(out)["view_direction"] == -1


def test_set_direction_writes_the_field_and_a_provenance_note(tmp_path, cli):
    path = _write(tmp_path, EIGHT)
    code, out, err = cli("profile", "set-direction", path, "+1")
    assert code == 0 and err == "" and "view_direction +1" in out and "(was unknown)" in out
    p = load_profile(path)
    assert p.view_direction == 1
    note = p.provenance["view_direction"]
    assert note["value"] == 1 and "set-direction" in note["method"] and note["evidence"] == {"previous": None}
    code, out, _ = cli("profile", "set-direction", path, "-1")
    assert code == 0 and load_profile(path).view_direction == -1 and "(was +1)" in out
    code, out, _ = cli("profile", "set-direction", path, "unknown")
    assert code == 0 and load_profile(path).view_direction is None
    assert [p.name for p in tmp_path.iterdir()] == ["p.json"]  # nothing but the profile (atomic write)


@pytest.mark.parametrize("value", ["0", "2", "left", "", "+-1"])
def test_set_direction_refuses_a_bad_value_and_leaves_the_file(tmp_path, cli, value):
    path = _write(tmp_path, EIGHT)
    before = path.read_bytes()
    code, out, err = cli("profile", "set-direction", path, value)
    line = one_error_line(err)
    assert code == 2 and "DIRECTION: must be +1, -1 or unknown" in line and out == ""
    assert path.read_bytes() == before


def test_set_direction_on_a_missing_or_invalid_profile_is_one_line(tmp_path, cli):
    code, _, err = cli("profile", "set-direction", tmp_path / "absent.json", "+1")
    assert code == 2 and "no such file" in one_error_line(err)
    bad = _write(tmp_path, {**EIGHT, "period": -1})
    code, _, err = cli("profile", "set-direction", bad, "+1")
    assert code == 2 and "field 'period'" in one_error_line(err)
    assert not (tmp_path / "absent.json").exists()


@pytest.mark.parametrize("a, b, match, text", [(1, 1, True, ""), (1, -1, False, "MISMATCH"),
                                               (None, 1, None, "not compared"), (-1, None, None, "not compared")])
def test_compare_reports_whether_the_directions_match(tmp_path, cli, a, b, match, text):
    pa = save_profile(PanelProfile(**EIGHT, view_direction=a), tmp_path / "a.json")
    pb = save_profile(PanelProfile(**EIGHT, view_direction=b), tmp_path / "b.json")
    code, out, _ = cli("profile", "compare", pa, pb)
    names = {1: "+1", -1: "-1", None: "unknown"}
    line = next(line for line in out.splitlines() if "view direction" in line)
    assert code == 0 and f"{names[a]} vs {names[b]}" in line and text in line
    if match:
        assert "MISMATCH" not in line and "not compared" not in line
    code, out, _ = cli("profile", "compare", pa, pb, "--json")
    data = json.loads(out)
    assert data["view_direction"] == [a, b] and data["view_direction_match"] is match


# ---------------------------------------------------------------------------------------------
# 3. Looking Glass: invView = 1 is view_direction +1
# ---------------------------------------------------------------------------------------------

def test_import_sets_plus_one_and_records_why(tmp_path):
    profile = lkg.import_visual_json(_write(tmp_path, PORTRAIT, "visual.json"), 45)
    assert profile.view_direction == 1
    assert profile.provenance["view_direction"]["value"] == 1
    assert "invView = 1" in profile.provenance["view_direction"]["evidence"]


def test_export_writes_inv_view_one_and_reimports_plus_one(tmp_path):
    for direction in (1, None):
        profile = PanelProfile(**EIGHT, view_direction=direction, looking_glass={"DPI": 100.0})
        path = lkg.export_visual_json(profile, tmp_path / f"v{direction}.json")
        assert json.loads(path.read_text())["invView"] == {"value": 1.0}
        assert lkg.import_visual_json(path, 8).view_direction == 1  # (same routing: test_lkg.py)


def test_export_refuses_minus_one_in_one_line(tmp_path, cli):
    profile = PanelProfile(**EIGHT, view_direction=-1, looking_glass={"DPI": 100.0}, name="mirrored")
    with pytest.raises(ProfileError) as err:
        lkg.visual_from_profile(profile)
    assert "view_direction is -1" in str(err.value) and "invView = 1" in str(err.value)
    path = save_profile(profile, tmp_path / "p.json")
    code, out, err = cli("profile", "export-lkg", path, "-o", tmp_path / "v.json")
    assert code == 2 and "view_direction is -1" in one_error_line(err) and not (tmp_path / "v.json").exists()


def test_export_of_an_unknown_direction_warns_in_one_line(tmp_path, cli):
    path = save_profile(PanelProfile(**EIGHT, looking_glass={"DPI": 100.0}), tmp_path / "p.json")
    code, out, err = cli("profile", "export-lkg", path, "-o", tmp_path / "v.json")
    (line,) = err.strip().splitlines()
    assert code == 0 and line.startswith("lenticalib: warning: ") and "invView = 1" in line
    save_profile(PanelProfile(**EIGHT, looking_glass={"DPI": 100.0}, view_direction=1), path)
    code, out, err = cli("profile", "export-lkg", path, "-o", tmp_path / "v.json")
    assert code == 0 and err == ""


def test_inv_view_one_runs_left_to_right_through_the_simulated_lens_sheet():
    """The physics behind +1, independently of lenticalib's w: their shader's view coordinate
    ``(1 - frac(phase)) N`` (the golden :func:`lkg_rule.lkg_phase`, interpolated: it is linear in the
    subpixel and the row) at the pixel-plane point that a simulated eye sees through the panel
    centre grows when the eye moves right, for both slant signs and any phase."""
    from lenticalib.sim.optics import PanelOptics

    for slope, center in ((-7.24467, 0.4017), (6.5, 0.93)):
        visual = dict(PORTRAIT, slope={"value": slope}, center={"value": center})
        profile = lkg.profile_from_visual(visual, 45)
        phase = lkg_rule.lkg_phase(visual).reshape(profile.height, -1)  # [y, 3 x + position] (RGB stripe)
        optics = PanelOptics.from_routing(profile.period, profile.slant, 600.0, width=profile.width,
                                          height=profile.height, pixel_pitch=25.4 / 324.0)
        zone = optics.view_zone_width(600.0, 45)

        def their_view(eye):
            x_p, y_p = optics.seen_point(eye, 0.0, 0.0)
            X, Y = (float(c) for c in optics.world_to_raster(x_p, y_p))
            xs, y = int(X), int(Y)
            value = (phase[y, xs] + (X - 0.5 - xs) * (phase[y, xs + 1] - phase[y, xs])
                     + (Y - 0.5 - y) * (phase[y + 1, xs] - phase[y, xs]))
            return (1.0 - (value - math.floor(value))) * 45

        for start in (0.0, 0.37 * zone, 0.81 * zone):
            before, after = their_view((start, 0.0, -600.0)), their_view((start + 0.25 * zone, 0.0, -600.0))
            step = (after - before + 22.5) % 45 - 22.5
            assert step == pytest.approx(0.25, abs=0.01), (slope, start, before, after)


# ---------------------------------------------------------------------------------------------
# 4. the device record has no room: flashing drops the direction, reading says unknown
# ---------------------------------------------------------------------------------------------

def test_the_record_is_unchanged_by_a_direction_and_reads_back_unknown():
    from lenticalib.device.record import encode_record, parse_record, record_from_profile

    base = PanelProfile(**{**EIGHT, "width": 3840, "height": 2160, "views": 32, "period": 19.47})
    records = [encode_record(record_from_profile(base.replace(view_direction=d), serial="S", sequence=1, written=9))
               for d in (None, 1, -1)]
    assert records[0] == records[1] == records[2]
    assert parse_record(records[1]).to_profile().view_direction is None


def test_the_spare_record_bits_are_refused_by_layout_one_peers():
    """Why the direction is not stored: a flag bit or reserved byte set is OUT_OF_RANGE for every
    layout-1 reader (the emulated firmware's COMMIT and boot, and the host's read)."""
    import struct
    import zlib

    from lenticalib.device.record import RecordFormatError, encode_record, parse_record, record_from_profile

    data = bytearray(encode_record(record_from_profile(PanelProfile(**{**EIGHT, "width": 3840, "height": 2160}),
                                                       serial="S", sequence=1)))
    for index, value in ((35, 0x02), (35, 0x04), (100, 0x01), (123, 0x01)):
        bad = bytearray(data)
        bad[index] |= value
        struct.pack_into("<I", bad, 124, zlib.crc32(bytes(bad[:124])))
        with pytest.raises(RecordFormatError) as info:
            parse_record(bytes(bad))
        assert info.value.status == "OUT_OF_RANGE"


def test_flash_warns_and_read_says_the_direction_is_unknown(tmp_path, cli_process):
    env = {"LENTICALIB_EMULATOR_DIR": str(tmp_path / "emu")}
    profile = PanelProfile(views=32, slant=0.1835, period=19.47, offset=7.3, reference_view=16.0,
                           width=3840, height=2160, subpixel_order="RGB", view_direction=1)
    original = save_profile(profile, tmp_path / "p.json")
    flashed = cli_process("device", "flash", "emu://dir", original, env=env)
    assert flashed.returncode == 0, flashed.stderr
    (warning,) = flashed.stderr.strip().splitlines()
    assert warning.startswith("lenticalib: warning: ") and "no room for view_direction (+1)" in warning
    back = tmp_path / "back.json"
    read = cli_process("device", "read", "emu://dir", "-o", back, env=env)
    assert read.returncode == 0 and read.stderr == ""
    (note,) = [line for line in read.stdout.splitlines() if line.startswith("note:")]
    assert "no room for the view direction" in note and f"set-direction {back} +1|-1" in note
    assert load_profile(back).view_direction is None
    assert load_profile(back).routing_key() == profile.routing_key()
    assert cli_process("device", "verify", "emu://dir", original, env=env).returncode == 0  # still holds the profile


# ---------------------------------------------------------------------------------------------
# 5. the simulator's truth and the two-position rule
# ---------------------------------------------------------------------------------------------

@pytest.mark.parametrize("seed", [1, 2, 3, 4, 5])
def test_the_simulated_panel_runs_left_to_right_and_a_move_shows_in_the_offsets(seed):
    """Truth: +1 by ray tracing (:func:`truth_view_direction`); and the rule of the two fits,
    applied to the true profiles of two camera positions, finds +1 for a move right, -1 for a
    move left, with ``dw`` equal to the move in view zones."""
    from lenticalib.sim.scene import random_scene

    scene = random_scene(seed, width=SIM_W, height=SIM_H, resolution=CAMERA)
    truth = scene.truth_profile(SIM_VIEWS)
    assert truth.view_direction == 1
    zone = scene.optics.view_zone_width(scene.camera.distance, SIM_VIEWS)
    ex, ey, ez = scene.eye
    first = truth.replace(uncertainty={"offset": 0.02})
    for moved in (0.5, 1.5, 3.0, -1.0, -3.0):
        other = scene.replace_camera(position=(ex + moved * zone, ey, ez)).truth_profile(SIM_VIEWS)
        assert other.view_direction == 1
        evidence = direction_from_moved_right(first, other.replace(uncertainty={"offset": 0.02}))
        assert evidence.dw == pytest.approx(moved, abs=1e-6)
        assert evidence.direction == (1 if moved > 0 else -1) and evidence.reason is None


def _pair(dw, sigma_offset=0.02, n=8, period=7.4, **second):
    a = PanelProfile(**{**EIGHT, "views": n, "period": period, "reference_view": n / 2},
                     uncertainty={"offset": sigma_offset})
    b = a.replace(offset=a.offset - dw * period / n, **second)
    return a, b


def test_the_rule_leaves_the_direction_unknown_when_the_move_is_too_small_or_too_large():
    a, b = _pair(1.2)
    assert direction_from_moved_right(a, b).direction == 1
    sigma = direction_from_moved_right(a, b).sigma
    assert sigma == pytest.approx(8 / 7.4 * math.hypot(0.02, 0.02))
    small = direction_from_moved_right(*_pair(2.5 * sigma))
    assert small.direction is None and "move the camera further" in small.reason
    assert direction_from_moved_right(*_pair(3.5 * sigma)).direction == 1
    assert direction_from_moved_right(*_pair(-3.5 * sigma)).direction == -1
    near_half = direction_from_moved_right(*_pair(4 - 2 * sigma))
    assert near_half.direction is None and "half the view cone" in near_half.reason
    wrapped = direction_from_moved_right(*_pair(5.0))  # more than N/2 wraps: it reads as a move left
    assert wrapped.dw == pytest.approx(-3.0) and wrapped.direction == -1
    a, b = _pair(1.2)
    none = direction_from_moved_right(a.replace(uncertainty=None), b)
    assert none.direction is None and none.sigma is None and "uncertainty" in none.reason
    json.dumps(none.to_dict(), allow_nan=False)  # evidence is valid JSON


def test_the_rule_refuses_two_different_panels_and_distrusts_two_subpixel_orders():
    a, b = _pair(1.0)
    with pytest.raises(InputError, match="different panels") as err:
        direction_from_moved_right(a, b.replace(views=16, reference_view=8.0))
    assert err.value.source == "moved_right"
    with pytest.raises(InputError):
        direction_from_moved_right(a, b.replace(width=192))
    order = direction_from_moved_right(a, b.replace(subpixel_order="RGB"))
    assert order.direction is None and "subpixel order" in order.reason


def test_an_untrustworthy_second_fit_gives_no_direction():
    a, b = _pair(1.5)
    result = types.SimpleNamespace(profile=a, warnings=[], direction=None)
    second = types.SimpleNamespace(profile=b, trusted=False, problems=["fine fringes are weak"])
    add_moved_right(result, second, "moved")
    assert result.profile.view_direction is None
    (warning,) = result.warnings
    assert warning.startswith("view_direction left unknown: ") and "fine fringes are weak" in warning
    assert result.direction["delta_w_views"] == pytest.approx(1.5) and result.direction["capture_set"] == "moved"
    result = types.SimpleNamespace(profile=a, warnings=[], direction=None)
    add_moved_right(result, types.SimpleNamespace(profile=b, trusted=True, problems=[]), "moved")
    assert result.profile.view_direction == 1 and result.warnings == []
    assert result.profile.provenance["view_direction"]["evidence"]["delta_w_views"] == pytest.approx(1.5)


# ---------------------------------------------------------------------------------------------
# 6. fit --moved-right on simulated capture sets
# ---------------------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def moved_sets(tmp_path_factory, capture_set):
    """A 640x360, 8-view virtual panel photographed from the calibration position (``first``) and
    from 1.5 view zones (about 7 cm) to the right at the same distance (``right``); the sets hold
    what a user has (no simulation.json)."""
    from lenticalib.calib.patterns.calibration_patterns import design_patterns
    from lenticalib.core.pattern_sets import write_patterns
    from lenticalib.sim.scene import random_scene

    root = tmp_path_factory.mktemp("moved")
    patterns = design_patterns(SIM_W, SIM_H, SIM_VIEWS)
    write_patterns(root / "patterns", patterns)
    # one ray per sensor pixel: the direction comes from the offsets of two whole-panel fits, which
    # the 3x3 rays of the default only anti-alias
    scene = random_scene(3, width=SIM_W, height=SIM_H, resolution=CAMERA, subsamples=1)
    zone = scene.optics.view_zone_width(scene.camera.distance, SIM_VIEWS)
    ex, ey, ez = scene.eye
    moved = scene.replace_camera(position=(ex + 1.5 * zone, ey, ez))
    sets = {name: capture_set(s, patterns, keep_simulation=False) for name, s in (("first", scene), ("right", moved))}
    return types.SimpleNamespace(root=root, zone_mm=zone, scene=scene, **sets)


@pytest.fixture(scope="module")
def moved_fit(moved_sets):
    """``fit_capture_sets(first, output=out/profile.json, moved_right=right)``: what ``lenticalib fit
    first -o out/profile.json --moved-right right`` runs."""
    from lenticalib.calib.routing.fit_pipeline import fit_capture_sets

    out = moved_sets.root / "out"
    out.mkdir()
    run = fit_capture_sets(moved_sets.first, output=out / "profile.json", moved_right=moved_sets.right)
    return types.SimpleNamespace(run=run, summary=run.summary, profile_path=out / "profile.json")


@pytest.mark.slow
def test_fit_with_moved_right_finds_the_true_direction(moved_sets, moved_fit):
    assert moved_fit.run.trusted and moved_fit.run.profile_written, moved_fit.run.result.problems
    truth = load_profile(moved_sets.first / "truth.json")
    assert truth.view_direction == 1
    profile = load_profile(moved_fit.profile_path)
    assert profile.view_direction == truth.view_direction
    summary = moved_fit.summary
    evidence = summary["view_direction"]
    assert evidence["result"] == 1 and evidence["method"] == "moved-right"
    assert evidence["capture_set"] == str(moved_sets.right) and evidence["moved_right_trusted"] is True
    assert evidence["delta_w_views"] == pytest.approx(1.5, abs=0.15)
    assert abs(evidence["delta_w_views"]) > 3 * evidence["sigma_views"]
    assert len(evidence["moved_right_inputs"]) == 24 and all("sha256" in e for e in evidence["moved_right_inputs"])
    note = profile.provenance["view_direction"]
    assert note["value"] == 1 and note["evidence"]["delta_w_views"] == evidence["delta_w_views"]
    assert summary["profile"]["view_direction"] == 1
    assert (moved_fit.profile_path.parent / "profile-report" / "summary.json").exists()


@pytest.mark.slow
def test_photos_taken_moving_left_instead_give_minus_one(moved_fit):
    """The sign follows the camera's move: swapping the two sets (the 'moved' camera is then to
    the LEFT of the first) gives -1; a user who moved the wrong way gets the wrong sign, which is
    why the option is named for the direction to move."""
    evidence = moved_fit.summary["view_direction"]  # the two fits, rebuilt from it
    base = {k: v for k, v in load_profile(moved_fit.profile_path).to_dict().items()
            if k in ("views", "width", "height")}
    first, right = evidence["first"], evidence["moved_right"]

    def profile(d):
        return PanelProfile(**base, slant=d["slant"], period=d["period"], offset=d["offset"],
                            reference_view=d["reference_view"], subpixel_order=d["subpixel_order"],
                            uncertainty={"offset": d["offset_sigma"]})

    swapped = direction_from_moved_right(profile(right), profile(first))
    assert swapped.direction == -1 and swapped.dw == pytest.approx(-evidence["delta_w_views"], abs=1e-3)


@pytest.mark.slow
def test_fit_without_moved_right_says_the_direction_is_unknown(moved_sets, tmp_path, monkeypatch, cli):
    import lenticalib.calib.routing.fit as fit_module

    real = fit_module.fit_capture_set
    calls = []

    def recording(*args, **kwargs):
        calls.append(args[0])
        return real(*args, **kwargs)

    monkeypatch.setattr(fit_module, "fit_capture_set", recording)
    code, out, err = cli("fit", moved_sets.first, "-o", tmp_path / "p.json")
    assert code == 0 and "view_direction" not in err and len(calls) == 1  # no warning: a note on stdout
    assert "view direction unknown" in out and "--moved-right" in out
    assert load_profile(tmp_path / "p.json").view_direction is None


@pytest.mark.slow
def test_moved_right_is_checked_before_any_fit(moved_sets, tmp_path, monkeypatch, cli):
    import lenticalib.calib.routing.fit as fit_module
    from lenticalib.calib.patterns.calibration_patterns import design_patterns
    from lenticalib.core.pattern_sets import write_patterns

    def no_fit(*args, **kwargs):
        raise AssertionError("the fit started before the arguments were checked")

    monkeypatch.setattr(fit_module, "fit_capture_set", no_fit)
    other = tmp_path / "other-set"  # photos of another pattern set (16 views: another set id)
    write_patterns(other, design_patterns(SIM_W, SIM_H, 16))
    shutil.copytree(moved_sets.right / "captures", other / "captures")
    empty = tmp_path / "empty"
    shutil.copytree(moved_sets.root / "patterns", empty)
    cases = [(moved_sets.first, "--moved-right: is the same capture set as DIR"),
             (str(moved_sets.first) + "/", "--moved-right: is the same capture set as DIR"),
             (tmp_path / "absent", "is not a folder"),
             (empty, "no captures folder"),
             (other, "holds photos of pattern set")]
    for dir2, expected in cases:
        code, out, err = cli("fit", moved_sets.first, "-o", tmp_path / "p.json", "--moved-right", dir2)
        line = one_error_line(err)
        assert code == 2 and expected in line, (dir2, line)
    assert not (tmp_path / "p.json").exists() and not (tmp_path / "p-report").exists()


# ---------------------------------------------------------------------------------------------
# 7. patterns --direction
# ---------------------------------------------------------------------------------------------

def test_views_below_half_say_left_the_others_right():
    profile = PanelProfile(**{**EIGHT, "views": 7, "reference_view": 3.5})
    views = direction_views(profile)
    assert views.shape == (7, 540, 960, 3) and views.dtype == np.uint8
    left, right = direction_view("LEFT", (960, 540)), direction_view("RIGHT", (960, 540))
    body = slice(0, 460)  # above the small "view i" caption
    for i in range(7):
        expected = left if i < 3.5 else right
        assert np.array_equal(views[i, body], expected[body]), i
    # the arrow points the labelled way: the head (tall, near the tip) is on that side
    head_rows = slice(int(0.68 * 540) - 50, int(0.68 * 540) - 25)
    assert left[head_rows, 200:300].mean() > 100 > left[head_rows, 660:760].mean()
    assert right[head_rows, 660:760].mean() > 100 > right[head_rows, 200:300].mean()


def test_the_raster_routes_left_to_low_views_and_right_to_high_views():
    from lenticalib.render.encoders import encode
    from lenticalib.core.routing import view_map

    profile = PanelProfile(**EIGHT)
    raster = direction_raster(profile, encode)
    assert raster.shape == (54, 96, 3) and raster.dtype == np.uint8
    views = direction_views(profile)
    all_left = encode(np.repeat(views[:1], 8, axis=0), profile, "reference")
    all_right = encode(np.repeat(views[-1:], 8, axis=0), profile, "reference")
    vmap = view_map(profile)  # (H, 3W): the view of every subpixel, -1 where none
    channel_at = {pos: ch for ch, pos in enumerate(profile.rho)}
    flat = np.stack([raster[:, xs // 3, channel_at[xs % 3]] for xs in range(3 * 96)], axis=1)
    lefts = np.stack([all_left[:, xs // 3, channel_at[xs % 3]] for xs in range(3 * 96)], axis=1)
    rights = np.stack([all_right[:, xs // 3, channel_at[xs % 3]] for xs in range(3 * 96)], axis=1)
    low, high = (vmap >= 0) & (vmap < 4), vmap >= 4
    differs = lefts != rights
    assert (low & differs).sum() > 100 and (high & differs).sum() > 100
    # view i's own captions ("view i") differ; compare above them only (rows of the views' top 85 %)
    top = np.arange(54)[:, None] < int(0.85 * 54)
    assert np.array_equal(flat[low & top], lefts[low & top])
    assert np.array_equal(flat[high & top], rights[high & top])


def test_patterns_direction_writes_the_raster_and_the_instruction(tmp_path, cli):
    profile_path = save_profile(PanelProfile(**EIGHT, view_direction=1), tmp_path / "panel.json")
    out = tmp_path / "check"
    code, stdout, err = cli("patterns", "--direction", "--profile", profile_path, "-o", out)
    assert code == 0 and err == "", err
    from lenticalib.core.files.imageio import read_image
    from lenticalib.render.encoders import encode

    raster = read_image(out / DIRECTION_PATTERN_NAME)
    assert raster.shape == (54, 96, 3) and raster.dtype == np.uint8
    assert np.array_equal(raster, direction_raster(load_profile(profile_path), encode))
    assert f"lenticalib show {out / DIRECTION_PATTERN_NAME}" in stdout
    assert f"set-direction {profile_path} +1" in stdout and f"set-direction {profile_path} -1" in stdout
    assert sorted(p.name for p in out.iterdir()) == [DIRECTION_PATTERN_NAME]
    # again into the same folder: replaced
    code, _, err = cli("patterns", "--direction", "--profile", profile_path, "-o", out)
    assert code == 0 and err == ""


def test_patterns_direction_refusals_are_one_line(tmp_path, cli):
    profile_path = save_profile(PanelProfile(**EIGHT), tmp_path / "panel.json")
    (tmp_path / "file").write_text("x")
    cases = [(["--direction", "-o", tmp_path / "a"], "--direction: needs the panel's profile"),
             (["--profile", profile_path, "-o", tmp_path / "a"], "--profile: is used only with --direction"),
             (["--direction", "--profile", profile_path, "--width", "96", "-o", tmp_path / "a"],
              "--width: is taken from the profile"),
             (["--direction", "--profile", tmp_path / "absent.json", "-o", tmp_path / "a"], "no such file"),
             (["--direction", "--profile", profile_path, "-o", tmp_path / "file"], "is a file, not a folder"),
             (["--direction", "--profile", profile_path, "-o", tmp_path / "no" / "a"], "does not exist")]
    for args, expected in cases:
        code, out, err = cli("patterns", *args)
        assert code == 2 and expected in one_error_line(err), (args, err)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["file", "panel.json"]


def test_a_camera_to_the_right_of_the_calibration_position_sees_right(tmp_path):
    """The pattern on the virtual panel, encoded with the true profile for the calibration camera
    and photographed (noise-free radiance) from 2 view zones to its right and to its left: the
    photo correlates with the RIGHT view on the right and the LEFT view on the left (the
    simulated panel runs +1)."""
    from lenticalib.render.encoders import encode
    from lenticalib.sim.panel_light import render_radiance
    from lenticalib.sim.scene import random_scene

    scene = random_scene(5, width=SIM_W, height=SIM_H, resolution=CAMERA)
    truth = scene.truth_profile(SIM_VIEWS)
    raster = direction_raster(truth, encode)
    size = (960, 540)
    left = direction_view("LEFT", size).mean(axis=2)
    right = direction_view("RIGHT", size).mean(axis=2)
    zone = scene.optics.view_zone_width(scene.camera.distance, SIM_VIEWS)
    ex, ey, ez = scene.eye
    panel_w, panel_h = scene.optics.panel_size
    seen = {}
    for side, moved in (("right", 2.0), ("left", -2.0)):
        s = scene.replace_camera(position=(ex + moved * zone, ey, ez))
        photo = render_radiance(raster, s)
        luma = photo.mean(axis=2) if photo.ndim == 3 else photo
        py, px = np.mgrid[0:CAMERA[1]:3, 0:CAMERA[0]:3].astype(np.float64)
        x, y = s.camera.lens_plane_points(px, py)
        u, v = x / panel_w + 0.5, y / panel_h + 0.5
        inside = (u > 0.02) & (u < 0.98) & (v > 0.02) & (v < 0.98)
        col = np.clip((u[inside] * size[0]).astype(int), 0, size[0] - 1)
        row = np.clip((v[inside] * size[1]).astype(int), 0, size[1] - 1)
        values = luma[py[inside].astype(int), px[inside].astype(int)]
        seen[side] = (np.corrcoef(values, right[row, col])[0, 1], np.corrcoef(values, left[row, col])[0, 1])
    # (the two views share the background and much of their layout, so both correlate somewhat)
    assert seen["right"][0] > seen["right"][1] + 0.2 and seen["right"][0] > 0.6, seen
    assert seen["left"][1] > seen["left"][0] + 0.2 and seen["left"][1] > 0.6, seen
