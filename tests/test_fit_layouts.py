"""The fit finds a subpixel layout: cell patterns, the decision from measured shifts, and (slow) a
simulated cell panel fitted end to end."""

import json
import shutil

import numpy as np
import pytest

from lenticalib.calib.routing import layout_fit
from lenticalib.calib.routing.compare import compare_profiles
from lenticalib.calib.patterns.calibration_patterns import (CELL_CLASSES, CELL_GROUPS, CELL_WIDE_GROUPS, CELL_WIDER_GROUPS, CELL_X_GROUPS,
                                       CELL_Y_GROUPS, cell_class_of,
                                       design_patterns, read_manifest, render_pattern)
from lenticalib.core.colour import srgb_encode8
from lenticalib.core.errors import CalibrationError
from lenticalib.core.pattern_sets import write_patterns
from lenticalib.core.profile import PanelProfile, load_profile
from lenticalib.sim.layouts import NAMED_LAYOUTS

MAX_RMS, MAX_WORST, MAX_CENTRING = 0.05, 0.15, 0.25  # views (docs/optics.md section 6)


def _profile(layout=None, order="RGB", slant=0.21, period=19.5):
    return PanelProfile(views=32, slant=slant, period=period, offset=4.0, reference_view=16.0, width=640, height=360,
                        subpixel_order=order, subpixel_layout=layout)


# 1. The cell patterns ------------------------------------------------------------------------------
def test_cell_patterns_light_one_channel_in_one_class(tmp_path):
    plain, cells = design_patterns(64, 64, 8), design_patterns(64, 64, 8, cells=True)
    assert cells.names == (plain.names + list(CELL_GROUPS) + list(CELL_Y_GROUPS) + list(CELL_WIDE_GROUPS)
                           + list(CELL_WIDER_GROUPS))
    assert len(CELL_GROUPS) == len(CELL_Y_GROUPS) == len(CELL_WIDE_GROUPS) == len(CELL_WIDER_GROUPS) == 3 * CELL_CLASSES
    # the x photos at 16, 20 and 26 subpixels: a lens period up to about 23.5 has one that measures
    # it (docs/calibration.md, the working range)
    assert {period: [p.period for name in names for p in cells.group(name)] == [period] * len(names)
            for period, names in CELL_X_GROUPS.items()} == {16.0: True, 20.0: True, 26.0: True}
    assert cells.set_id != plain.set_id and "cells" not in plain.to_dict()
    reference = render_pattern(plain.group("f16")[0], 64, 64)  # the fine sinusoid, step 0, green
    classes = cell_class_of(np.arange(64)[None, :], np.arange(64)[:, None])
    inner = (slice(2, -2), slice(2, -2))  # inside the registration frame
    for name, channel in (("cell-g3", 1), ("cell-r0", 0), ("cell-b7", 2), ("cellv-g6", 1), ("cellw-r1", 0)):
        image = render_pattern(cells.group(name)[0], 64, 64)[inner]
        k = int(name[-1])
        lit = classes[inner] == k
        assert not np.delete(image, channel, axis=2).any()
        assert not image[..., channel][~lit].any()
        if name == "cell-g3":
            np.testing.assert_array_equal(image[..., 1][lit], reference[inner][..., 1][lit])
        period = {"cell": 16.0, "cellw": 20.0, "cellv": 26.0}[name.split("-")[0]]
        row = srgb_encode8(0.5 + 0.45 * np.cos(2 * np.pi * (3 * np.arange(64)[inner[1]] + channel + 0.5) / period))
        np.testing.assert_array_equal(image[..., channel][lit], np.broadcast_to(row, image.shape[:2])[lit])
    image = render_pattern(cells.group("celly-b5")[0], 64, 64)[inner]  # along y, blue, class 5
    lit = classes[inner] == 5
    assert not image[..., :2].any() and not image[..., 2][~lit].any()
    column = srgb_encode8(0.5 + 0.45 * np.cos(2 * np.pi * (np.arange(64)[inner[0]] + 0.5) / 16.0))[:, None]
    np.testing.assert_array_equal(image[..., 2][lit], np.broadcast_to(column, image.shape[:2])[lit])
    write_patterns(tmp_path / "set", cells)
    assert read_manifest(tmp_path / "set") == cells
    manifest = json.loads((tmp_path / "set" / "patterns.json").read_text())
    manifest["cells"] = False  # a set that says it has no cell patterns but lists them is not ours
    (tmp_path / "set" / "patterns.json").write_text(json.dumps(manifest))
    with pytest.raises(Exception, match="did not draw"):
        read_manifest(tmp_path / "set")


# 2. The decision, on shifts made from known layouts -------------------------------------------------
def _measured(truth, sigma=0.01, seed=0):
    """The shifts a measurement of ``truth`` gives: its class shifts in the layout's gauge plus noise."""
    e = layout_fit.class_shifts(truth)
    r = e - e[:, 1].mean() + np.random.default_rng(seed).normal(0.0, sigma, e.shape)
    return layout_fit.CellShifts(r, np.full(e.shape, sigma), np.ones(e.shape), 16.0)


@pytest.mark.parametrize("order", ["RGB", "BGR"])
def test_a_stripe_is_reported_as_its_order(order):
    decision = layout_fit.decide_layout(_measured(_profile(order=order)), 32 / 19.5)
    assert decision.layout is None and decision.order == order and decision.problem is None
    assert "stripe " + order in layout_fit.describe(decision)


@pytest.mark.parametrize("name", sorted(NAMED_LAYOUTS))
@pytest.mark.parametrize("slant", [0.3, -0.17])
def test_a_cell_layout_is_recovered_with_its_pattern(name, slant):
    truth = _profile(NAMED_LAYOUTS[name], slant=slant)
    decision = layout_fit.decide_layout(_measured(truth), 32 / 19.5)
    assert decision.problem is None and decision.layout is not None
    # the fit's plane sits at the green light's mean position (offset s - mean e_G), then regauged
    green_offset = truth.offset - layout_fit.class_shifts(truth)[:, 1].mean()
    fitted = truth.replace(subpixel_layout=decision.layout,
                           offset=layout_fit.regauged_offset(green_offset, truth.period, decision))
    assert layout_fit.same_cells(fitted, truth)
    assert len(decision.layout.cells) == len(NAMED_LAYOUTS[name].cells)
    assert layout_fit.shift_error(fitted, truth) < 0.03
    assert all(dy == 0.0 for cell in decision.layout.cells for _, dy in cell)  # only dx is measurable
    # the layout routes like the truth up to a common shift, which the fitted offset carries
    diff = compare_profiles(fitted, truth)
    assert diff.rms < 0.03 and diff.worst < 0.08 and abs(diff.centring) < 0.03
    # written in the stripe's gauge: the channel centres average to the pixel centre
    dx = np.array([[dx for dx, _ in cell] for cell in decision.layout.cells])
    cell = [int(decision.layout.cell_of(k % 2, k // 2)) for k in range(CELL_CLASSES)]
    assert abs(dx[cell].mean()) < 0.01


def test_a_layout_that_cannot_be_told_is_refused_in_one_line():
    truth = _profile(NAMED_LAYOUTS["lkg-columns"])
    decision = layout_fit.decide_layout(_measured(truth, sigma=0.2), 32 / 19.5)
    assert decision.problem and "not resolved" in decision.problem
    with pytest.raises(CalibrationError, match="not resolved") as info:
        layout_fit.refuse_if_unresolved(decision, "cal/captures")
    assert "\n" not in str(info.value)
    # classes that belong to no cell: every class's shifts scattered by far more than their sigma
    scattered = layout_fit.CellShifts(np.random.default_rng(3).uniform(-1, 1, (CELL_CLASSES, 3)),
                                      np.full((CELL_CLASSES, 3), 0.01), np.ones((CELL_CLASSES, 3)), 16.0)
    decision = layout_fit.decide_layout(scattered, 32 / 19.5)
    assert decision.layout is not None and len(decision.layout.cells) == CELL_CLASSES  # no two classes agree


def test_two_periods_combine_by_their_sigma_and_floor():
    truth = _profile(NAMED_LAYOUTS["lkg-checker"])
    good = _measured(truth, sigma=0.01, seed=1)
    # near its blind spot a period's phase is garbage and its jackknife sigma large
    blind = layout_fit.CellShifts(good.shift + np.random.default_rng(2).uniform(-2, 2, good.shift.shape),
                                  np.full(good.shift.shape, 1.5), np.ones(good.shift.shape), 20.0)
    for parts, floors in (([good, blind], [0.015, 0.03]), ([blind, good], [0.03, 0.015])):
        combined, floor = layout_fit.combine_periods(parts, floors)
        assert np.max(np.abs(combined.shift - good.shift)) < 0.01
        assert np.all(combined.sigma < 0.016) and np.allclose(floor, 0.015, atol=0.001)
        decision = layout_fit.decide_layout(combined, 32 / 19.5, floor)
        assert decision.problem is None and len(decision.layout.cells) == 2
    # a period whose systematic floor is large (strong alias) counts less than one measuring well
    far = layout_fit.CellShifts(good.shift + 0.2, np.full(good.shift.shape, 0.01), np.ones(good.shift.shape), 16.0)
    combined, floor = layout_fit.combine_periods([far, good], [0.2, 0.015])
    assert np.max(np.abs(combined.shift - good.shift)) < 0.01
    # two periods that disagree by more than they claim: the sigma grows (honest), and a blind
    # period alone is refused in one line
    off = layout_fit.CellShifts(good.shift + 0.3, good.sigma, good.amplitude, 20.0)
    combined, floor = layout_fit.combine_periods([good, off], [0.015, 0.015])
    assert np.all(2 * np.hypot(combined.sigma, floor) > np.abs(combined.shift - good.shift))  # 0.15 off: 2 sigma
    combined, floor = layout_fit.combine_periods([blind], [0.015])
    assert "known only to" in layout_fit.decide_layout(combined, 32 / 19.5, floor).problem


# 3. A simulated cell panel, fitted end to end -------------------------------------------------------
@pytest.mark.slow
def test_simulated_cell_panel_fit_recovers_the_layout_and_meets_the_targets(tmp_path):
    from lenticalib.calib.routing.fit import fit_capture_set
    from lenticalib.sim.capture import simulate_capture_set
    from lenticalib.sim.scene import random_scene

    layout = NAMED_LAYOUTS["lkg-columns"]
    directory = tmp_path / "sim"
    write_patterns(directory, design_patterns(1280, 720, 32, cells=True))
    # a lens period where the cell photos measure well (docs/calibration.md: about 14.5 to 21 subpixels)
    scene = random_scene(5, width=1280, height=720, resolution=(1250, 800), slant=-0.27, period=18.5, layout=layout,
                         subsamples=1, jpeg_quality=90)
    simulate_capture_set(directory, scene)
    fit_dir = tmp_path / "fit"  # what a user has: the manifest and the photos
    fit_dir.mkdir()
    shutil.copy2(directory / "patterns.json", fit_dir / "patterns.json")
    shutil.copytree(directory / "captures", fit_dir / "captures")
    truth = load_profile(directory / "truth.json")
    result = fit_capture_set(fit_dir)
    assert result.trusted, result.problems
    fitted = result.profile
    assert not fitted.is_stripe and layout_fit.same_cells(fitted, truth)
    sigma = float(result.layout.cell_sigma.max())
    assert layout_fit.shift_error(fitted, truth) <= 3 * sigma
    diff = compare_profiles(fitted, truth)
    assert diff.rms <= MAX_RMS and diff.worst <= MAX_WORST and abs(diff.centring) <= MAX_CENTRING, diff
    assert result.quality["subpixel_layout"]["layout"] == fitted.subpixel_layout.to_dict()
