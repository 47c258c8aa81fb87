"""Looking Glass visual.json import/export (lenticalib.core.looking_glass.convert).

The golden model is :func:`lenticalib.core.looking_glass.vendor_rule.lkg_view_map`, our float64 port of the
Looking Glass shader's rule; lenticalib's canonical :func:`routing.view_map` of the imported
profile must agree with it on every colour of every pixel except exact ties (their ``phase * N``
within 1e-6 of an integer, where float evaluations may legitimately differ).  Cell layouts and
flips: test_lkg_layouts.py.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from lenticalib.core.looking_glass import convert as lkg, vendor_rule as lkg_rule
from lenticalib.core.errors import ProfileError
from lenticalib.core.profile import PanelProfile
from lenticalib.core import routing

SETTINGS = settings(max_examples=30, derandomize=True, deadline=None, database=None,
                    suppress_health_check=[HealthCheck.too_slow])

PORTRAIT = {
    "configVersion": "1.0",
    "serial": "LKG-P-TEST",
    "pitch": {"value": 52.5630},
    "slope": {"value": -7.24467},
    "center": {"value": 0.40170},
    "viewCone": {"value": 40.0},
    "invView": {"value": 1.0},
    "verticalAngle": {"value": 0.0},
    "DPI": {"value": 324.0},
    "screenW": {"value": 1536.0},
    "screenH": {"value": 2048.0},
    "flipImageX": {"value": 0.0},
    "flipImageY": {"value": 0.0},
    "flipSubp": {"value": 0.0},
}

TIE_TOL = 1e-6


def channel_views(profile):
    """lenticalib's view of every colour, int32 ``(H, W, 3)`` ``[y, x, channel]`` (-1 dark)."""
    slots = routing.view_map(profile).astype(np.int32).reshape(profile.height, profile.width, 3)
    return slots[:, :, list(profile.rho)]


def _compare(visual, n, profile=None):
    """Compare lenticalib's view map with the golden model; returns (ours, theirs, ties, lit)."""
    profile = profile if profile is not None else lkg.profile_from_visual(visual, n)
    ours = channel_views(profile)
    theirs = lkg_rule.lkg_view_map(visual, n)
    assert ours.shape == theirs.shape == (profile.height, profile.width, 3)
    assert theirs.min() >= 0 and theirs.max() <= n
    ties = lkg_rule.lkg_ties(visual, n, TIE_TOL)
    lit = ours >= 0
    theirs = theirs % n
    # on ties the two may pick either neighbouring view, never anything else
    d = (ours - theirs) % n
    assert np.isin(d[ties & lit], (0, 1, n - 1)).all()
    return ours, theirs, ties, lit


# ---------------------------------------------------------------------------------------------
# 1. Portrait anchor


def test_portrait_constants():
    profile = lkg.profile_from_visual(lkg.normalize_visual(PORTRAIT, "PORTRAIT"), 45)
    assert abs(profile.period - 18.668) < 0.002
    assert profile.slant < 0
    assert abs(abs(profile.slant) - 0.1380) < 0.0002
    assert profile.reference_view == 0.0
    assert 0.0 <= profile.offset < profile.period
    assert profile.subpixel_order == "RGB"
    assert (profile.width, profile.height, profile.views) == (1536, 2048, 45)
    # the offset from the derivation, reduced modulo Delta
    s_ref = profile.period * 0.40170 - 1.5 - 3 * (2048 - 0.5) * profile.slant
    assert math.isclose((s_ref - profile.offset) / profile.period,
                        round((s_ref - profile.offset) / profile.period), abs_tol=1e-9)


@pytest.mark.parametrize("n", [45, 48])
def test_portrait_matches_lkg_rule_full_panel(n):
    ours, theirs, ties, lit = _compare(PORTRAIT, n)
    assert lit.all()  # Delta ~ 18.7 <= N: every subpixel shows a view
    assert ties.mean() < 1e-3
    differ = ours != theirs
    assert not (differ & ~ties).any(), f"{(differ & ~ties).sum()} non-tie subpixels differ"
    # every view is used, and the map is not trivially constant
    assert set(np.unique(ours)) == set(range(n))


def test_comparison_detects_wrong_conventions():
    """The equality above must fail for a half-subpixel offset, the wrong row direction, the
    wrong reference view or a mirrored slant, so it really tests the derivation."""
    visual = dict(PORTRAIT, screenW={"value": 300.0}, screenH={"value": 200.0})
    n = 45
    good = lkg.profile_from_visual(visual, n)
    ours, theirs, ties, _ = _compare(visual, n, good)
    assert not ((ours != theirs) & ~ties).any()
    h = good.height
    mutants = {
        "half subpixel": good.replace(offset=good.offset + 0.5),
        "one view": good.replace(reference_view=1.0),
        "mirrored slant": good.replace(slant=-good.slant),
        # rows counted from the top instead of the bottom
        "row direction": good.replace(slant=-good.slant,
                                      offset=good.offset + 3 * (h - 1) * good.slant),
    }
    for name, bad in mutants.items():
        ours, theirs, ties, _ = _compare(visual, n, bad)
        assert ((ours != theirs) & ~ties).mean() > 0.3, name


def test_flip_subp_gives_bgr_and_same_positions():
    visual = dict(PORTRAIT, flipSubp={"value": 1.0}, screenW={"value": 120.0},
                  screenH={"value": 90.0})
    profile = lkg.profile_from_visual(visual, 48)
    assert profile.subpixel_order == "BGR"
    assert profile.rho == (2, 1, 0)  # red is read from position 2
    ours, theirs, ties, _ = _compare(visual, 48, profile)
    assert not ((ours != theirs) & ~ties).any()


def test_golden_model_gives_n_on_exact_tie():
    w, h, n = 64, 32, 8
    v = lkg.normalize_visual(dict(PORTRAIT, screenW={"value": w}, screenH={"value": h}), "t")
    p = v["pitch"] * w / v["DPI"] * math.cos(math.atan(1.0 / v["slope"]))
    tilt = h / (w * v["slope"])
    # make the phase of pixel (0, bottom row), position 0 exactly 0
    v["center"] = (0.5 / w + 0.5 / h * tilt) * p
    views = lkg_rule.lkg_view_map(v, n)
    assert views[h - 1, 0, 0] == n
    assert lkg_rule.lkg_phase(v)[h - 1, 0, 0] == 0.0


# ---------------------------------------------------------------------------------------------
# 2. Random calibrations


@st.composite
def visuals(draw):
    slope = draw(st.floats(3.0, 12.0)) * draw(st.sampled_from([-1.0, 1.0]))
    return {
        "pitch": {"value": draw(st.floats(30.0, 80.0))},
        "slope": {"value": slope},
        "center": {"value": draw(st.floats(-2.0, 2.0))},
        "DPI": {"value": draw(st.floats(100.0, 500.0))},
        "screenW": {"value": float(draw(st.integers(50, 400)))},
        "screenH": {"value": float(draw(st.integers(40, 300)))},
        "flipSubp": {"value": float(draw(st.integers(0, 1)))},
        "invView": {"value": float(draw(st.integers(0, 1)))},
        "flipImageX": {"value": float(draw(st.integers(0, 1)))},
        "flipImageY": {"value": float(draw(st.integers(0, 1)))},
        "viewCone": {"value": 40.0},
        "serial": "R-" + str(draw(st.integers(0, 999))),
    }


@SETTINGS
@given(visual=visuals(), n=st.integers(2, 64))
def test_random_calibrations_match_lkg_rule(visual, n):
    profile = lkg.profile_from_visual(visual, n)
    ours, theirs, ties, lit = _compare(visual, n, profile)
    # "round" draws (slope -3, center 0) put exact ties on a whole diagonal: 1 / (3 W) per line
    assert ties.mean() < 0.02
    differ = ours != theirs
    assert not (differ & lit & ~ties).any(), f"{(differ & lit & ~ties).sum()} subpixels differ"
    if profile.period <= n:
        assert lit.all()
    else:
        # The LentiAvatar routing rule darkens frac(w) >= N/Delta where their shader still shows a view;
        # the continuous coordinate agrees with theirs there too.
        w = routing.view_coordinate(profile).reshape(profile.height, profile.width, 3)[:, :, list(profile.rho)]
        cont = np.floor(w).astype(np.int64) % n
        assert not ((cont != theirs) & ~ties).any()
        assert abs((~lit).mean() - (1 - n / profile.period)) < 0.05


# ---------------------------------------------------------------------------------------------
# 3. Round trips


@st.composite
def profiles(draw, canonical=True):
    n = draw(st.integers(2, 64))
    period = draw(st.floats(3.0, 60.0))
    slant = draw(st.floats(1 / 12, 1 / 3)) * draw(st.sampled_from([-1.0, 1.0]))
    if canonical:
        offset = draw(st.floats(0.0, 1.0, exclude_max=True)) * period
        i_ref = 0.0
    else:
        offset = draw(st.floats(-100.0, 100.0))
        i_ref = draw(st.floats(-5.0, 5.0))
    reversed_views = draw(st.booleans())
    return PanelProfile(views=n, slant=slant, period=period, offset=offset, reference_view=i_ref,
                        width=draw(st.integers(20, 200)), height=draw(st.integers(20, 150)),
                        subpixel_order=draw(st.sampled_from(["RGB", "BGR"])),
                        views_reversed=reversed_views, view_direction=-1 if reversed_views else 1,
                        flip_image_x=draw(st.booleans()), flip_image_y=draw(st.booleans()))


def _close(a, b, scale=None):
    return abs(a - b) <= 1e-9 * (scale if scale is not None else max(abs(a), abs(b)))


def _circular_close(a, b, period):
    d = (a - b) / period
    return abs(d - round(d)) <= 1e-9


@SETTINGS
@given(profile=profiles(), dpi=st.floats(100.0, 500.0))
def test_profile_visual_profile_round_trip(profile, dpi):
    visual = lkg.visual_from_profile(profile, dpi=dpi)
    json.dumps(visual, allow_nan=False)  # ready for json.dumps
    back = lkg.profile_from_visual(visual, profile.views)
    assert _close(back.slant, profile.slant)
    assert _close(back.period, profile.period)
    assert _circular_close(back.offset, profile.offset, profile.period)
    assert back.reference_view == 0.0
    assert (back.width, back.height, back.subpixel_order, back.views) == (
        profile.width, profile.height, profile.subpixel_order, profile.views)
    assert (back.views_reversed, back.flip_image_x, back.flip_image_y) == (
        profile.views_reversed, profile.flip_image_x, profile.flip_image_y)
    assert back.looking_glass["DPI"] == dpi
    ties = routing.tie_mask(profile, 1e-9)
    a, b = routing.view_map(profile), routing.view_map(back)
    assert not ((a != b) & ~ties).any()


@SETTINGS
@given(profile=profiles(canonical=False), dpi=st.floats(100.0, 500.0))
def test_general_profile_exports_same_routing(profile, dpi):
    """Any i_ref / unreduced s_ref exports to a visual.json that routes the same."""
    visual = lkg.visual_from_profile(profile, dpi=dpi)
    assert 0.0 <= visual["center"]["value"] < 1.0
    back = lkg.profile_from_visual(visual, profile.views)
    ties = routing.tie_mask(profile, 1e-9)
    a, b = routing.view_map(profile), routing.view_map(back)
    assert not ((a != b) & ~ties).any()
    # and exporting the re-imported profile gives the same file
    again = lkg.visual_from_profile(back)
    for key in ("pitch", "slope", "DPI", "screenW", "screenH", "flipSubp"):
        assert _close(again[key]["value"], visual[key]["value"]), key
    assert _circular_close(again["center"]["value"], visual["center"]["value"], 1.0)


def test_portrait_profile_round_trip_identical_view_map():
    profile = lkg.profile_from_visual(PORTRAIT, 48)
    back = lkg.profile_from_visual(lkg.visual_from_profile(profile), 48)
    assert _close(back.slant, profile.slant) and _close(back.period, profile.period)
    assert _circular_close(back.offset, profile.offset, profile.period)
    assert np.array_equal(routing.view_map(profile), routing.view_map(back))


@SETTINGS
@given(visual=visuals(), n=st.integers(2, 64))
def test_visual_profile_visual_round_trip(visual, n):
    profile = lkg.profile_from_visual(visual, n)
    out = lkg.visual_from_profile(profile)
    for key in ("pitch", "slope", "DPI", "screenW", "screenH", "flipSubp", "viewCone", "invView",
                "flipImageX", "flipImageY"):
        assert _close(out[key]["value"], visual[key]["value"]), key
    assert _circular_close(out["center"]["value"], visual["center"]["value"], 1.0)
    assert out["serial"] == visual["serial"]


def test_file_round_trip_keeps_extras(tmp_path):
    src = tmp_path / "visual.json"
    original = dict(PORTRAIT, futureField={"value": 3.5}, someText="keep me",
                    someList=[1, 2, 3])
    src.write_text(json.dumps(original, indent=4), encoding="utf-8")
    profile = lkg.import_visual_json(src, 45)
    assert profile.provenance["method"] == "import-lkg"
    assert profile.provenance["inputs"][0]["path"] == str(src)
    assert len(profile.provenance["inputs"][0]["sha256"]) == 64
    extras = profile.looking_glass
    assert extras["DPI"] == 324.0 and extras["viewCone"] == 40.0
    assert extras["serial"] == "LKG-P-TEST" and extras["configVersion"] == "1.0"
    assert extras["verticalAngle"] == 0.0 and extras["futureField"] == 3.5
    assert "pitch" not in extras and "center" not in extras

    dst = tmp_path / "out" / "visual.json"
    dst.parent.mkdir()
    lkg.export_visual_json(profile, dst)
    written = json.loads(dst.read_text(encoding="utf-8"))
    assert set(written) == set(original)
    for key, value in original.items():
        if isinstance(value, dict):
            assert set(written[key]) == {"value"}, key
            assert _close(written[key]["value"], value["value"]) or (
                key == "center" and _circular_close(written[key]["value"], value["value"], 1.0)), key
        else:
            assert written[key] == value, key
    assert list(written)[:3] == ["configVersion", "serial", "pitch"]

    again = lkg.import_visual_json(dst, 45)
    assert _close(again.period, profile.period) and _close(again.slant, profile.slant)
    assert _circular_close(again.offset, profile.offset, profile.period)
    assert np.array_equal(routing.view_map(again), routing.view_map(profile))
    assert again.looking_glass == profile.looking_glass


def test_export_defaults_and_dpi_argument(tmp_path):
    profile = PanelProfile(views=32, slant=0.2, period=10.0, offset=3.0, reference_view=0.0,
                           width=100, height=80)
    visual = lkg.visual_from_profile(profile, dpi=200)
    assert visual["viewCone"] == {"value": 40.0}
    assert visual["serial"] == ""
    assert visual["DPI"] == {"value": 200.0}
    assert visual["flipSubp"] == {"value": 0.0}
    # the dpi argument wins over the stored one
    stored = profile.replace(looking_glass={"DPI": 300.0})
    assert lkg.visual_from_profile(stored)["DPI"] == {"value": 300.0}
    assert lkg.visual_from_profile(stored, dpi=150.0)["DPI"] == {"value": 150.0}
    path = lkg.export_visual_json(stored, tmp_path / "v.json")
    assert lkg.read_visual_json(path)["DPI"] == 300.0


# ---------------------------------------------------------------------------------------------
# 4. Errors


def _write(tmp_path, data, name="visual.json"):
    path = tmp_path / name
    path.write_text(data if isinstance(data, str) else json.dumps(data), encoding="utf-8")
    return path


def test_missing_file(tmp_path):
    path = tmp_path / "nope.json"
    with pytest.raises(ProfileError) as err:
        lkg.import_visual_json(path, 45)
    assert str(path) in str(err.value)


def test_folder_instead_of_file(tmp_path):
    with pytest.raises(ProfileError) as err:
        lkg.read_visual_json(tmp_path)
    assert str(tmp_path) in str(err.value)


@pytest.mark.parametrize("text", ["{not json", "", "[1, 2]", '{"pitch": NaN}', "null"])
def test_unreadable_json(tmp_path, text):
    path = _write(tmp_path, text)
    with pytest.raises(ProfileError) as err:
        lkg.read_visual_json(path)
    assert str(path) in str(err.value)


@pytest.mark.parametrize("field", lkg.REQUIRED_FIELDS)
def test_missing_field(tmp_path, field):
    data = {k: v for k, v in PORTRAIT.items() if k != field}
    path = _write(tmp_path, data)
    with pytest.raises(ProfileError) as err:
        lkg.read_visual_json(path)
    assert str(path) in str(err.value) and field in str(err.value)
    with pytest.raises(ProfileError) as err:  # also from a dict, no KeyError
        lkg.profile_from_visual(data, 45)
    assert field in str(err.value)


@pytest.mark.parametrize("field, value", [
    ("pitch", {"value": "52.5"}), ("slope", {"value": None}), ("center", {"value": True}),
    ("DPI", {"value": [324]}), ("screenW", {"wrong": 1536}), ("pitch", "52.5"),
    ("center", {"value": 1e400}), ("viewCone", {"value": "wide"}),
    ("DPI", {"value": 0.0}), ("DPI", {"value": -324.0}), ("pitch", {"value": 0.0}),
    ("slope", {"value": 0.0}), ("screenW", {"value": 1536.5}), ("screenH", {"value": 0}),
    ("serial", 12345), ("flipSubp", {"value": 0.5}),
])
def test_bad_values(tmp_path, field, value):
    raw = '{"value": 1e400}' if value == {"value": 1e400} else json.dumps(value)
    text = json.dumps({k: v for k, v in PORTRAIT.items() if k != field})[:-1]
    path = _write(tmp_path, text + f', "{field}": {raw}}}')
    with pytest.raises(ProfileError) as err:
        lkg.import_visual_json(path, 45)
    assert str(path) in str(err.value) and field in str(err.value)


@pytest.mark.parametrize("field, attribute", [("invView", "views_reversed"), ("flipImageX", "flip_image_x"),
                                              ("flipImageY", "flip_image_y")])
def test_inverted_and_flipped_calibrations_import(tmp_path, field, attribute):
    value = 0.0 if field == "invView" else 1.0
    path = _write(tmp_path, dict(PORTRAIT, screenW={"value": 120.0}, screenH={"value": 90.0},
                                 **{field: {"value": value}}))
    profile = lkg.import_visual_json(path, 45)
    assert getattr(profile, attribute) is True
    assert profile.view_direction == (-1 if field == "invView" else 1)
    ours, theirs, ties, _ = _compare(lkg.read_visual_json(path), 45, profile)
    assert not ((ours != theirs) & ~ties).any()


def test_invview_absent_means_one_and_says_so():
    data = {k: v for k, v in PORTRAIT.items() if k != "invView"}
    profile = lkg.profile_from_visual(data, 45)
    assert profile.routing_key() == lkg.profile_from_visual(PORTRAIT, 45).routing_key()
    (note,) = profile.provenance["assumptions"]
    assert "no invView" in note and "invView = 1" in note
    assert lkg.profile_from_visual(PORTRAIT, 45).provenance["assumptions"] == []


@pytest.mark.parametrize("views", [1, 255, 45.0, True, "45"])
def test_bad_views(views):
    with pytest.raises(ProfileError) as err:
        lkg.profile_from_visual(PORTRAIT, views)
    assert "views" in str(err.value)


@pytest.mark.parametrize("visual", [None, [1, 2], "visual"])
def test_not_an_object(visual):
    with pytest.raises(ProfileError) as err:
        lkg.profile_from_visual(visual, 45, source="given.json")
    assert "given.json" in str(err.value)


def test_export_vertical_lenses_refused():
    profile = PanelProfile(views=8, slant=0.0, period=10.0, offset=0.0, reference_view=0.0,
                           width=10, height=10, looking_glass={"DPI": 300.0})
    with pytest.raises(ProfileError) as err:
        lkg.visual_from_profile(profile)
    assert "slant" in str(err.value)


def test_export_without_dpi_refused(tmp_path):
    profile = PanelProfile(views=8, slant=0.2, period=10.0, offset=0.0, reference_view=0.0,
                           width=10, height=10)
    with pytest.raises(ProfileError) as err:
        lkg.export_visual_json(profile, tmp_path / "v.json")
    assert "DPI" in str(err.value) and "`dpi`" in str(err.value)
    assert not (tmp_path / "v.json").exists()
    for bad in (0, -1.0, float("nan"), "300", True):
        with pytest.raises(ProfileError) as err:
            lkg.visual_from_profile(profile, dpi=bad)
        assert "dpi" in str(err.value).lower()


def test_import_runs_the_views_left_to_right_and_export_refuses_the_other_way(tmp_path):
    """invView = 1: the view index grows as the viewer moves right (view_direction +1, derivation
    in the lkg module docstring; the physics is checked in test_view_direction.py)."""
    profile = lkg.profile_from_visual(PORTRAIT, 45)
    assert profile.view_direction == 1
    assert lkg.visual_from_profile(profile)["invView"] == {"value": 1.0}
    with pytest.raises(ProfileError) as err:
        lkg.export_visual_json(profile.replace(view_direction=-1), tmp_path / "v.json")
    assert "view_direction is -1" in str(err.value) and not (tmp_path / "v.json").exists()
