"""Looking Glass's own lenticular rule, transcribed here apart from lenticalib.core.looking_glass.vendor_rule, against import + encode.

THE REFERENCE.  ``vendor_views`` below is a line-by-line transcription, in the shader's own names,
of Looking Glass's lenticular shader as their WebXR library generates it:
Looking-Glass/looking-glass-webxr, ``dist/bundle/webxr.js`` at b44ed27fea197f28fbe4cb669bc350d141a9f8b1
(the merge of ``feat/spatial-display-support``): ``GetCellForPixel`` lines 6792-6826,
``GetSubpixelViews`` lines 6855-6891, ``GetViewsColors`` line 6901, and the getters ``tilt``,
``subp``, ``pitch`` lines 7413-7421.  The same cell table is in the Unity plugin's
``LookingGlass/Lenticular`` shader, whose header says it was converted by hand from Bridge's
``Lenticular_RGBA_With_Aspect``.  ``invView`` and ``flipSubp`` (which the newer shaders no longer
read) follow the older HoloPlay shader (``HoloPlay/Lenticular``, 2017: ``nuv.z = (1.0 - invView) *
nuv.z + invView * (1.0 - nuv.z)`` and ``float4(rgb[ri].r, rgb[1].g, rgb[bi].b, 1)``).  It is
written separately from :mod:`lenticalib.core.looking_glass.vendor_rule` so that the port is held against the
vendor's code, not against itself.

THE CALIBRATIONS (fixtures/lkg/README.md): real units (a gen3 16" landscape with two cells and no
``invView``, a first-generation 8.9", two Portraits, a Go) and every device template of Looking
Glass's LKG-Toolkit,
every subpixel of each; then each with ``invView`` 0 and with the slope's sign turned, the real
units and the gen3 templates with ``flipImageX``, ``flipImageY`` and (stripes) ``flipSubp`` set,
and the two-cell calibrations under every ``CellPatternMode``, on their first and last 64 rows.  Every
colour must show the view the vendor's rule gives it (ties excepted: ``phase * N`` within 1e-6 of
an integer).
"""

from __future__ import annotations

import copy
import json
import math
from pathlib import Path

import numpy as np
import pytest

from lenticalib.core.looking_glass import convert as lkg
from lenticalib.core import routing
from lenticalib.render.encoders import encode

FIXTURES = Path(__file__).resolve().parent.parent / "fixtures" / "lkg"
N = 48
TIE = 1e-6
ROWS = 512  # rows per chunk: bounded temporaries on 8K panels


def _value(cal, key, default):
    field = cal.get(key, default)
    return float(field["value"]) if isinstance(field, dict) else float(field)


def vendor_views(cal: dict, tile_count: int, rows: slice) -> tuple[np.ndarray, np.ndarray]:
    """(view, tie) of every colour of the panel rows ``rows`` (top-down), ``[y, x, channel]``, by their shader."""
    screenW, screenH = _value(cal, "screenW", 0), _value(cal, "screenH", 0)
    flipImageX = _value(cal, "flipImageX", 0.0)
    slope_cal = _value(cal, "slope", 0)
    # LookingGlassConfig getters (webxr.js 7413-7421)
    tilt = screenH / (screenW * slope_cal) * (-1 if flipImageX else 1)
    subp = 1 / (screenW * 3) * (-1 if flipImageX else 1)
    pitch = _value(cal, "pitch", 0) * screenW / _value(cal, "DPI", 0) * math.cos(math.atan(1 / slope_cal))
    center = _value(cal, "center", 0)
    invView = _value(cal, "invView", 1.0)
    flipSubp = _value(cal, "flipSubp", 0.0)
    cellPatternType = int(_value(cal, "CellPatternMode", 0))
    cells = cal.get("subpixelCells") or []
    subpixelCellCount = len(cells)

    width, height = int(screenW), int(screenH)
    y_top = np.arange(height)[rows]
    # v_texcoord of the pixel centres: x from the left, y from the bottom (GL)
    screen_uv_x = ((np.arange(width) + 0.5) / screenW)[None, :]
    screen_uv_y = (((height - 1 - y_top) + 0.5) / screenH)[:, None]
    xPos = (screen_uv_x * screenW).astype(np.int64)
    yPos = (screen_uv_y * screenH).astype(np.int64)

    views = np.empty((y_top.size, width, 3))
    if subpixelCellCount <= 0:
        for i in range(3):
            views[:, :, i] = screen_uv_x + subp * i + screen_uv_y * tilt
    else:
        # GetCellForPixel
        if cellPatternType == 1:
            cell = np.where(((yPos % 2 == 0) & (xPos % 2 == 0)) | ((yPos % 2 != 0) & (xPos % 2 != 0)), 0, 1)
        elif cellPatternType == 2:
            cell = np.broadcast_to(xPos % 2, (y_top.size, width))
        elif cellPatternType == 3:
            offset = (xPos % 2) * 2
            cell = (yPos + offset) % 4
        elif cellPatternType == 4:
            cell = np.broadcast_to(yPos % 2, (y_top.size, width))
        else:
            cell = np.zeros((y_top.size, width), dtype=np.int64)
        cell = cell % subpixelCellCount
        # subpixelData: offsets divided by screenW (x) and screenH (y)
        data = np.array([[c["ROffsetX"] / screenW, c["ROffsetY"] / screenH, c["GOffsetX"] / screenW,
                          c["GOffsetY"] / screenH, c["BOffsetX"] / screenW, c["BOffsetY"] / screenH] for c in cells])
        for subPixel in range(3):
            views[:, :, subPixel] = screen_uv_x + data[cell, subPixel * 2 + 0]
            views[:, :, subPixel] += (screen_uv_y + data[cell, subPixel * 2 + 1]) * tilt
    views *= pitch
    views -= center
    tie = np.abs(views * tile_count - np.round(views * tile_count)) < TIE
    z = views - np.floor(views)                      # fract (HoloPlay: fmod(nuv.z + pad, 1.0))
    z = (1.0 - invView) * z + invView * (1.0 - z)    # HoloPlay's invView; Bridge's shader: always 1 - fract
    z = np.clip(z, 0.00001, 0.999999)
    viewIndex = (z * tile_count).astype(np.int64)
    ri, bi = (2, 0) if flipSubp else (0, 2)
    shown = np.stack([viewIndex[:, :, ri], viewIndex[:, :, 1], viewIndex[:, :, bi]], axis=-1)
    tie = np.stack([tie[:, :, ri], tie[:, :, 1], tie[:, :, bi]], axis=-1)
    return shown, tie


def lenticalib_views(profile, rows: slice) -> np.ndarray:
    """The view lenticalib's routing (every encoder's) shows on each colour of ``rows``, ``[y, x, channel]``."""
    slots = routing.view_map(profile, rows=rows).astype(np.int64)
    slots = slots.reshape(slots.shape[0], profile.width, 3)
    return slots[:, :, list(profile.rho)]


def disagreement(cal: dict, views: int = N, bands: int | None = None) -> tuple[int, int, int]:
    """(colours on another view than the vendor's rule, ties, colours) over the whole panel, or over
    its first and last ``bands`` rows (every row parity and both ends of the GL row count)."""
    profile = lkg.profile_from_visual(cal, views)
    if bands is None:
        chunks = [slice(start, start + ROWS) for start in range(0, profile.height, ROWS)]
    else:
        chunks = [slice(0, bands), slice(profile.height - bands, profile.height)]
    wrong = ties = total = 0
    for rows in chunks:
        theirs, tie = vendor_views(cal, views, rows)
        ours = lenticalib_views(profile, rows)
        wrong += int(((ours % views != theirs % views) & ~tie).sum())
        ties += int(tie.sum())
        total += ours.size
    return wrong, ties, total


def _load(name):
    return json.loads((FIXTURES / name).read_text())


TEMPLATES = _load("toolkit_templates.json")
REAL = {name: _load(f"{name}.json") for name in ("LKG-J00332", "LKG-2K-04409", "LKG-P03996", "LKG-P00655",
                                                 "LKG-E05304")}


def variants(cal):
    """The calibration, with invView 0, and with the slope's sign turned."""
    inv = copy.deepcopy(cal)
    inv["invView"] = {"value": 0.0}
    positive = copy.deepcopy(cal)
    positive["slope"] = {"value": -_value(cal, "slope", 0)}
    return {"as is": cal, "invView 0": inv, "slope sign turned": positive}


def flipped(cal):
    """The calibration with each flag the shader reads set: flipImageX, flipImageY, and on a stripe
    panel flipSubp (alone and with flipImageX; with cells it is refused, docs/looking-glass.md)."""
    out = {}
    for label, flags in [("flipImageX 1", {"flipImageX": 1.0}), ("flipImageY 1", {"flipImageY": 1.0}),
                         ("flipSubp 1", {"flipSubp": 1.0}), ("flipImageX 1 flipSubp 1", {"flipImageX": 1.0,
                                                                                        "flipSubp": 1.0})]:
        if "flipSubp" in flags and cal.get("subpixelCells"):
            continue
        visual = copy.deepcopy(cal)
        visual.update({key: {"value": value} for key, value in flags.items()})
        out[label] = visual
    return out


def with_mode(cal, mode):
    out = copy.deepcopy(cal)
    out["CellPatternMode"] = {"value": float(mode)}
    return out


def _large(cal):
    return cal["screenW"]["value"] * cal["screenH"]["value"] > 3840 * 2160


# every subpixel of every real calibration and every template (the 8K panels take ~5 s each)
FULL = [pytest.param(name, cal, id=name) for name, cal in REAL.items()]
FULL += [pytest.param(name, cal, id=name, marks=[pytest.mark.slow] if _large(cal) else [])
         for name, cal in TEMPLATES.items()]
# variants and every CellPatternMode of the two-cell calibrations: the first and last 64 rows
BANDS = [(f"{name} {label}", visual) for name, cal in {**REAL, **TEMPLATES}.items()
         for label, visual in variants(cal).items() if label != "as is"]
BANDS += [(f"{name} {label}", visual) for name, cal in
          [*REAL.items()] + [(key, TEMPLATES[key]) for key in ("_8_9inGen1", "_16inPortraitGen3",
                                                               "_16inLandscapeGen3", "_32inPortraitGen3")]
          for label, visual in flipped(cal).items()]
BANDS += [(f"{name} CellPatternMode {mode}", with_mode(cal, mode)) for name, cal in
          [("LKG-J00332", REAL["LKG-J00332"]), ("_16inPortraitGen3", TEMPLATES["_16inPortraitGen3"]),
           ("_32inPortraitGen3", TEMPLATES["_32inPortraitGen3"])] for mode in range(5)]
CASES = [(p.values[0], p.values[1]) for p in FULL] + BANDS


def _check(name, cal, bands=None):
    wrong, ties, total = disagreement(cal, bands=bands)
    assert ties < 0.001 * total
    assert wrong == 0, f"{name}: {wrong} of {total} colours ({wrong / total:.1%}) show another view than Looking Glass's rule"


@pytest.mark.parametrize("name, cal", FULL)
def test_every_colour_shows_the_view_of_the_vendors_rule(name, cal):
    _check(name, cal)


@pytest.mark.parametrize("name, cal", BANDS, ids=[name for name, _ in BANDS])
def test_every_mode_and_flag_follows_the_vendors_rule(name, cal):
    _check(name, cal, bands=64)


def test_the_fixtures_cover_every_model_and_mode():
    assert len(TEMPLATES) == 14  # every LKGDeviceType of HardCodedLKGDeviceTemplates.cs but ThirdParty
    modes = {int(_value(c, "CellPatternMode", 0)) for _, c in CASES}
    assert modes == {0, 1, 2, 3, 4}
    assert any(_value(c, "invView", 1.0) == 0 for _, c in CASES) and any(_value(c, "slope", 0) > 0 for _, c in CASES)
    for flag in ("flipImageX", "flipImageY", "flipSubp"):
        assert any(_value(c, flag, 0.0) == 1 for _, c in CASES), flag
    assert any(_value(c, "flipImageX", 0.0) == 1 and c.get("subpixelCells") for _, c in CASES)


@pytest.mark.parametrize("method", ["tables"])
def test_the_encoders_put_the_real_gen3_unit_on_the_vendors_views(method):
    """Through lenticalib's encoder, not only its routing: a view stack whose view v holds v."""
    cal = REAL["LKG-J00332"]
    profile = lkg.profile_from_visual(cal, N)
    stack = np.broadcast_to(np.arange(N, dtype=np.uint8)[:, None, None, None], (N, 9, 16, 3)).copy()
    raster = encode(stack, profile, method, allow_stretch=True).astype(np.int64)
    theirs, tie = vendor_views(cal, N, slice(None))
    wrong = (raster != theirs % N) & ~tie
    assert not wrong.any(), f"{wrong.mean():.1%} of colours on another view"


def test_the_fork_numbering_is_not_the_vendors():
    """The test can fail: the third-party fork's numbering (mode 2 = y_gl % 4, mode 4 = x % 2) is
    the vendor's modes 4 and 2 swapped; on the gen3 16" landscape unit it misplaces many colours."""
    cal = REAL["LKG-J00332"]
    swapped = with_mode(cal, 4)  # the fork's mode 2 with two cells is row parity: the vendor's mode 4
    profile = lkg.profile_from_visual(swapped, N)
    theirs, tie = vendor_views(cal, N, slice(0, 64))
    ours = lenticalib_views(profile, slice(0, 64))
    assert ((ours % N != theirs % N) & ~tie).mean() > 0.2


# --------------------------------------------------------------------------------------------
# profile compare: a unit's visual.json against a measured layout, in one line


def _small_unit():
    """LKG-J00332 on a 384 x 216 crop of its raster (same lens, same cells): quick to compare."""
    cal = copy.deepcopy(REAL["LKG-J00332"])
    cal["screenW"], cal["screenH"] = {"value": 384.0}, {"value": 216.0}
    return cal


def test_compare_says_whether_a_visual_json_and_a_measured_layout_agree(tmp_path):
    from .cli_support import run_main

    from lenticalib.calib.routing.compare import AGREE_FRACTION, compare_profiles
    from lenticalib.core.profile import save_profile

    cal = _small_unit()
    visual = tmp_path / "visual.json"
    visual.write_text(json.dumps(cal))
    truth = lkg.profile_from_visual(cal, N)
    measured = save_profile(truth.replace(offset=truth.offset + 0.02), tmp_path / "measured.json")  # a fit's error
    other_rule = save_profile(lkg.profile_from_visual(with_mode(cal, 4), N), tmp_path / "rows.json")

    code, out, err = run_main("profile", "compare", visual, measured)
    assert code == 0, err
    line = [ln for ln in out.splitlines() if "same view" in ln]
    assert len(line) == 1 and "they agree" in line[0]
    near = compare_profiles(truth, lkg.profile_from_visual(cal, N).replace(offset=truth.offset + 0.02))
    assert AGREE_FRACTION <= near.same_view < 1.0 and near.agree

    code, out, err = run_main("profile", "compare", other_rule, visual, "--json")
    assert code == 0, err
    report = json.loads(out)
    assert report["agree"] is False and 0.6 < report["same_view"] < AGREE_FRACTION
    code, out, _ = run_main("profile", "compare", visual, other_rule)
    assert "they DISAGREE" in [ln for ln in out.splitlines() if "same view" in ln][0]


def test_compare_refuses_two_visual_jsons_in_one_line(tmp_path):
    from .cli_support import refused

    visual = tmp_path / "visual.json"
    visual.write_text(json.dumps(_small_unit()))
    line = refused("profile", "compare", visual, visual, source=visual)
    assert "number of views" in line
