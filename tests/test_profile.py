import dataclasses
import json

import pytest

from lenticalib.core.errors import ProfileError
from lenticalib.core.profile import PanelProfile, load_profile, make_provenance, save_profile

EIGHT = {"views": 32, "slant": -0.138, "period": 18.668, "offset": 5.25, "reference_view": 16,
         "width": 3840, "height": 2160, "subpixel_order": "RGB"}


def _write(tmp_path, data, name="p.json"):
    path = tmp_path / name
    path.write_text(data if isinstance(data, str) else json.dumps(data))
    return path


def test_hand_written_eight_keys_load_as_current_format(tmp_path):
    p = load_profile(_write(tmp_path, EIGHT))
    assert (p.views, p.period, p.reference_view, p.subpixel_order) == (32, 18.668, 16.0, "RGB")
    assert p.to_dict()["format_version"] == 1


def test_round_trip_keeps_the_view_direction_and_old_files_say_unknown(tmp_path):
    assert load_profile(_write(tmp_path, EIGHT)).view_direction is None
    for direction in (1, -1):
        p = PanelProfile(**EIGHT, view_direction=direction)
        assert load_profile(save_profile(p, tmp_path / "d.json")).view_direction == direction


def test_round_trip_keeps_provenance_and_uncertainty(tmp_path):
    p = PanelProfile(**EIGHT, uncertainty={"slant": 1e-5}, provenance=make_provenance("test", inputs=[]))
    path = save_profile(p, tmp_path / "out.json")
    q = load_profile(path)
    assert q == p and q.uncertainty == {"slant": 1e-5} and q.provenance["method"] == "test"
    assert q.provenance["lenticalib_version"]


@pytest.mark.parametrize("change, message", [
    ({"views": "32"}, "field 'views': must be a whole number"),
    ({"views": 1}, "field 'views': must be between 2"),
    ({"period": 0}, "field 'period': must be > 0"),
    ({"period": -3.5}, "field 'period': must be > 0"),
    ({"slant": True}, "field 'slant': must be a number"),
    ({"offset": None}, "field 'offset': must be a number"),
    ({"width": 0}, "field 'width'"),
    ({"subpixel_order": "GRB"}, "field 'subpixel_order'"),
    ({"format_version": 7}, "unknown version 7"),
    ({"format": "something"}, "field 'format'"),
    ({"colour": 1}, "unknown field 'colour'"),
    ({"uncertainty": {"slant": -1}}, "uncertainty.slant"),
    ({"view_direction": 0}, "field 'view_direction': must be 1 or -1"),
    ({"view_direction": "+1"}, "field 'view_direction': must be 1 or -1"),
    ({"view_direction": True}, "field 'view_direction': must be 1 or -1"),
])
def test_bad_fields_name_the_file_and_field(tmp_path, change, message):
    path = _write(tmp_path, {**EIGHT, **change})
    with pytest.raises(ProfileError) as err:
        load_profile(path)
    assert message in str(err.value) and str(path) in str(err.value)


def test_missing_field_non_finite_bad_json_missing_file(tmp_path):
    data = dict(EIGHT)
    del data["period"]
    with pytest.raises(ProfileError, match="missing field"):
        load_profile(_write(tmp_path, data))
    with pytest.raises(ProfileError, match="non-finite"):
        load_profile(_write(tmp_path, json.dumps(EIGHT).replace("-0.138", "NaN")))
    with pytest.raises(ProfileError, match="not valid JSON"):
        load_profile(_write(tmp_path, "{views: 3"))
    with pytest.raises(ProfileError, match="no such file"):
        load_profile(tmp_path / "absent.json")
    with pytest.raises(ProfileError, match="JSON object"):
        load_profile(_write(tmp_path, "[1, 2]"))


def test_failed_save_leaves_the_old_file(tmp_path):
    path = save_profile(PanelProfile(**EIGHT), tmp_path / "p.json")
    before = path.read_text()
    with pytest.raises(ProfileError):
        save_profile(PanelProfile(**{**EIGHT, "period": -1.0}), path)  # invalid: never reaches disk
    from lenticalib.core.errors import InputError
    with pytest.raises(InputError, match="output folder does not exist"):
        save_profile(PanelProfile(**EIGHT), tmp_path / "missing" / "p.json")
    assert path.read_text() == before
    assert [f.name for f in tmp_path.iterdir()] == ["p.json"]


@pytest.mark.parametrize("change,field", [
    ({"period": 1e9}, "period"),                    # the encoder would write an all-black raster
    ({"period": 4097.0, "width": 3840}, "period"),  # above the absolute bound
    ({"period": 40.0, "width": 10}, "period"),      # a lens wider than the panel row (30 subpixels)
    ({"slant": 4.5}, "slant"),
    ({"offset": -2e6}, "offset"),
    ({"reference_view": 70000.0}, "reference_view"),
])
def test_physical_ranges_are_enforced_for_every_profile(tmp_path, change, field):
    path = _write(tmp_path, {**EIGHT, **change})
    with pytest.raises(ProfileError, match=f"field '{field}'"):
        load_profile(path)
    with pytest.raises(ProfileError, match=f"field '{field}'"):
        PanelProfile(**{**EIGHT, **change})


def test_profile_validate_refuses_a_period_of_1e9_in_one_line(tmp_path, cli):
    path = _write(tmp_path, {**EIGHT, "period": 1e9})
    code, _, err = cli("profile", "validate", path)
    assert code == 2
    assert err.count("\n") == 1 and err.startswith(f"lenticalib: error: {path}: field 'period': ")
    assert "1000000000.0" in err


def test_device_record_uses_the_profile_ranges():
    from lenticalib.device.record import CalibrationRecord, RecordRangeError, check_ranges

    record = CalibrationRecord(sequence=1, serial="S", width=10, height=10, views=8, subpixel_order="RGB",
                               slant=0.1, period=31.0, offset=0.0, reference_view=0.0)
    with pytest.raises(RecordRangeError, match="field 'period': 31.0 subpixels is wider"):
        check_ranges(record)
    check_ranges(dataclasses.replace(record, period=30.0))
