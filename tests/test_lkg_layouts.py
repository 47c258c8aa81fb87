"""Looking Glass calibrations with subpixel cells, flips and inverted views: import + encode vs their rule.

The oracle is :mod:`lenticalib.core.looking_glass.vendor_rule`, our float64 port of the Looking Glass lenticular
shader (nearest view), evaluated per colour of every pixel.  lenticalib imports the calibration
(:func:`lkg.profile_from_visual`) and encodes a view stack in which view ``v`` is filled with the
value ``v``: every colour of the raster then names the view it shows, and it must be the view
their rule gives, on every colour but exact ties (their ``phase * N`` within 1e-6 of an integer).
The calibrations are composed for every flip and every documented cell pattern (CellPatternMode
0 to 4, numbered as Looking Glass's shaders number them), with cell offsets modelled on real gen3
units (R and G on one row, B on the other, mirrored between columns).  tests/test_lkg_vendor_rule.py
holds lkg_rule itself against a separate transcription of the vendor's shader, on real calibrations.
"""

from __future__ import annotations

import itertools
import json

import numpy as np
import pytest

from lenticalib.core.looking_glass import convert as lkg, vendor_rule as lkg_rule
from lenticalib.core import routing
from lenticalib.core.errors import ProfileError
from lenticalib.core.layout import SubpixelLayout
from lenticalib.core.profile import PanelProfile, load_profile, save_profile
from lenticalib.render.encoders import encode

N = 45
BASE = {
    "configVersion": "3.0", "serial": "LKG-TEST", "pitch": {"value": 52.563}, "slope": {"value": -7.24467},
    "center": {"value": 0.4017}, "fringe": {"value": 0.0}, "viewCone": {"value": 40.0},
    "invView": {"value": 1.0}, "verticalAngle": {"value": 0.0}, "DPI": {"value": 324.0},
    "screenW": {"value": 70.0}, "screenH": {"value": 52.0}, "flipImageX": {"value": 0.0},
    "flipImageY": {"value": 0.0}, "flipSubp": {"value": 0.0},
}
GEN3_CELLS = [  # two cells, mirrored between columns (pixels, y up)
    {"ROffsetX": -0.25, "ROffsetY": -0.31, "GOffsetX": -0.25, "GOffsetY": 0.28, "BOffsetX": 0.25, "BOffsetY": 0.0},
    {"ROffsetX": 0.25, "ROffsetY": -0.31, "GOffsetX": 0.25, "GOffsetY": 0.28, "BOffsetX": -0.25, "BOffsetY": 0.0},
]
FOUR_CELLS = GEN3_CELLS + [
    {"ROffsetX": -0.1, "ROffsetY": 0.2, "GOffsetX": 0.3, "GOffsetY": -0.2, "BOffsetX": 0.0, "BOffsetY": 0.4},
    {"ROffsetX": 0.33, "ROffsetY": 0.0, "GOffsetX": 0.0, "GOffsetY": 0.1, "BOffsetX": -0.33, "BOffsetY": -0.1},
]
MODES = (0, 1, 2, 3, 4)
ENCODERS = ("reference", "tables", "fast", "torch")


def calibration(mode=None, *, slope=-7.24467, inv_view=1.0, flip_x=0.0, flip_y=0.0, flip_subp=0.0, **extra):
    visual = dict(BASE, slope={"value": slope}, invView={"value": inv_view}, flipImageX={"value": flip_x},
                  flipImageY={"value": flip_y}, flipSubp={"value": flip_subp}, **extra)
    if mode is not None:
        visual["CellPatternMode"] = {"value": float(mode)}
        visual["subpixelCells"] = FOUR_CELLS if mode == 3 else GEN3_CELLS
    return visual


def shown_views(profile, method):
    """The view every colour shows after encoding with ``method``: the raster of a stack whose view v is v."""
    views = np.broadcast_to(np.arange(profile.views, dtype=np.uint8)[:, None, None, None],
                            (profile.views, 13, 17, 3)).copy()
    return encode(views, profile, method, allow_stretch=True).astype(np.int64)


def assert_matches_their_rule(visual, profile, raster):
    theirs = lkg_rule.lkg_view_map(visual, N) % N
    ties = lkg_rule.lkg_ties(visual, N)
    differ = (raster != theirs) & ~ties
    assert ties.mean() < 0.01
    assert not differ.any(), f"{differ.sum()} of {differ.size} colours show another view than their rule"


CASES = [(mode, slope, inv, fx, fy, fs)
         for mode, slope, inv, fx, fy, fs in itertools.product((None,) + MODES, (-7.24467, 6.1), (1.0, 0.0),
                                                                (0.0, 1.0), (0.0, 1.0), (0.0, 1.0))
         if not (mode is not None and fs)]


@pytest.mark.parametrize("mode, slope, inv, fx, fy, fs", CASES)
def test_import_routes_every_colour_as_their_rule(mode, slope, inv, fx, fy, fs):
    visual = calibration(mode, slope=slope, inv_view=inv, flip_x=fx, flip_y=fy, flip_subp=fs)
    profile = lkg.profile_from_visual(visual, N)
    slots = routing.view_map(profile).astype(np.int64).reshape(profile.height, profile.width, 3)
    assert_matches_their_rule(visual, profile, slots[:, :, list(profile.rho)])
    assert profile.is_stripe == (mode is None)
    assert (profile.views_reversed, profile.flip_image_x, profile.flip_image_y) == (inv == 0.0, fx == 1.0, fy == 1.0)


@pytest.mark.parametrize("method", ENCODERS)
@pytest.mark.parametrize("mode, fx, inv", [(None, 1.0, 0.0), (None, 0.0, 1.0)] + [(m, float(m % 2), 1.0 - (m == 3))
                                                                                 for m in MODES])
def test_import_and_encode_agree_with_their_rule(method, mode, fx, inv):
    visual = calibration(mode, flip_x=fx, inv_view=inv, flip_subp=1.0 if mode is None and fx else 0.0)
    profile = lkg.profile_from_visual(visual, N)
    assert_matches_their_rule(visual, profile, shown_views(profile, method))


def test_reading_a_cell_calibration_as_a_stripe_misroutes_most_colours():
    """The test above can fail: the stripe rule on a gen3 calibration (what import did before)
    shows another view on most colours, by a different amount per channel."""
    visual = calibration(4)
    profile = lkg.profile_from_visual(visual, N)
    as_stripe = profile.replace(subpixel_layout=None, offset=profile.offset + 1.0)
    raster = shown_views(as_stripe, "reference")
    theirs = lkg_rule.lkg_view_map(visual, N) % N
    wrong = (raster != theirs) & ~lkg_rule.lkg_ties(visual, N)
    assert wrong.mean() > 0.5
    per_channel = [wrong[:, :, c].mean() for c in range(3)]
    assert max(per_channel) - min(per_channel) > 0.1


def test_cell_layout_in_the_profile():
    profile = lkg.profile_from_visual(calibration(4), N)
    layout = profile.subpixel_layout
    assert profile.subpixel_order == "RGB" and profile.rho == (0, 1, 2)
    # mode 4 alternates rows, counted by the vendor from the bottom: the top row of this 52-row panel is odd
    assert layout.pattern == ((1,), (0,))
    assert layout.cells[0][0] == (-0.25, 0.31)  # y up in the file, y down in the profile
    assert lkg.profile_from_visual(calibration(2), N).subpixel_layout.pattern == ((0, 1),)  # alternating columns
    # a 4-row pattern is re-indexed from their bottom-up rows to lenticalib's top-down rows
    four = lkg.profile_from_visual(calibration(3), N)
    h = four.height
    assert [four.subpixel_layout.cell_of(0, y) for y in range(h)] == [(h - 1 - y) % 4 for y in range(h)]


@pytest.mark.parametrize("mode", MODES)
@pytest.mark.parametrize("flip_x, inv", [(0.0, 1.0), (1.0, 0.0)])
def test_cell_calibrations_round_trip(tmp_path, mode, flip_x, inv):
    visual = calibration(mode, flip_x=flip_x, inv_view=inv)
    profile = lkg.profile_from_visual(visual, N)
    path = save_profile(profile, tmp_path / "p.json")
    assert json.loads(path.read_text())["format_version"] == 2
    loaded = load_profile(path)
    assert loaded.routing_key() == profile.routing_key()
    out = lkg.visual_from_profile(loaded)
    assert out["CellPatternMode"]["value"] in MODES
    assert out["subpixelCells"] == visual["subpixelCells"]
    for key in ("pitch", "slope", "invView", "flipImageX", "flipSubp", "screenW", "screenH", "fringe"):
        assert out[key]["value"] == pytest.approx(visual[key]["value"], rel=1e-12), key
    assert out["configVersion"] == "3.0"
    back = lkg.profile_from_visual(out, N)
    assert np.array_equal(routing.view_map(back), routing.view_map(profile))


def test_stripe_calibration_of_version_3_keeps_its_empty_cells():
    visual = calibration(None, subpixelCells=[], CellPatternMode={"value": 0.0})
    profile = lkg.profile_from_visual(visual, N)
    assert profile.is_stripe
    out = lkg.visual_from_profile(profile)
    assert out["subpixelCells"] == [] and out["CellPatternMode"] == {"value": 0}
    v1 = lkg.visual_from_profile(lkg.profile_from_visual(dict(calibration(None), configVersion="1.0"), N))
    assert "subpixelCells" not in v1 and "CellPatternMode" not in v1


def test_profiles_without_new_fields_stay_version_1(tmp_path):
    profile = lkg.profile_from_visual(calibration(None), N)
    path = save_profile(profile, tmp_path / "p.json")
    assert json.loads(path.read_text())["format_version"] == 1


@pytest.mark.parametrize("change, field", [
    ({"CellPatternMode": {"value": 7.0}}, "CellPatternMode"),
    ({"CellPatternMode": {"value": 1.5}}, "CellPatternMode"),
    ({"subpixelCells": "cells"}, "subpixelCells"),
    ({"subpixelCells": [{"ROffsetX": 0.1}]}, "subpixelCells[0]"),
    ({"subpixelCells": [dict(GEN3_CELLS[0], GOffsetY="up")]}, "subpixelCells[0].GOffsetY"),
    ({"subpixelCells": [dict(GEN3_CELLS[0], BOffsetX=4.0)]}, "subpixelCells"),
    ({"subpixelCells": GEN3_CELLS * 9}, "subpixelCells"),
    ({"subpixelCells": GEN3_CELLS, "flipSubp": {"value": 1.0}}, "flipSubp"),
    ({"flipImageX": {"value": 0.5}}, "flipImageX"),
    ({"invView": {"value": 2.0}}, "invView"),
])
def test_unrepresentable_calibrations_are_refused_naming_the_field(tmp_path, change, field):
    path = tmp_path / "visual.json"
    path.write_text(json.dumps(dict(calibration(None), **change)), encoding="utf-8")
    with pytest.raises(ProfileError) as err:
        lkg.import_visual_json(path, N)
    text = str(err.value)
    assert str(path) in text and f"'{field}" in text and "\n" not in text


def test_export_refuses_a_pattern_no_cell_mode_draws():
    profile = lkg.profile_from_visual(calibration(4), N)
    odd = profile.replace(subpixel_layout=SubpixelLayout(cells=profile.subpixel_layout.cells,
                                                         pattern=((0, 1), (0, 0))))
    with pytest.raises(ProfileError) as err:
        lkg.visual_from_profile(odd)
    assert "subpixel_layout.pattern" in str(err.value) and "CellPatternMode" in str(err.value)


def test_export_refuses_a_direction_that_disagrees_with_inv_view():
    profile = lkg.profile_from_visual(calibration(None, inv_view=0.0), N)
    assert profile.view_direction == -1
    with pytest.raises(ProfileError) as err:
        lkg.visual_from_profile(profile.replace(view_direction=1))
    assert "invView = 0" in str(err.value)
    assert lkg.visual_from_profile(profile)["invView"] == {"value": 0.0}


def test_profile_with_cells_reads_back(tmp_path):
    layout = SubpixelLayout(cells=(((-0.25, 0.3), (-0.25, -0.3), (0.25, 0.0)),
                                   ((0.25, 0.3), (0.25, -0.3), (-0.25, 0.0))), pattern=((0, 1),))
    profile = PanelProfile(views=32, slant=0.18, period=19.5, offset=3.0, reference_view=16.0, width=40, height=30,
                           subpixel_layout=layout, views_reversed=True, flip_image_y=True)
    back = load_profile(save_profile(profile, tmp_path / "p.json"))
    assert back == profile and back.subpixel_layout == layout
    with pytest.raises(ProfileError) as err:
        PanelProfile(views=32, slant=0.18, period=19.5, offset=3.0, reference_view=16.0, width=40, height=30,
                     subpixel_order="BGR", subpixel_layout=layout)
    assert "subpixel_order" in str(err.value)
