"""Calibration tools on panels that are not a plain stripe: crosstalk patterns and profile comparison
with cell layouts and reversed views."""

import numpy as np
import pytest

from lenticalib.calib.routing.compare import compare_profiles
from lenticalib.calib.patterns.crosstalk_patterns import band_centre, design_crosstalk_patterns
from lenticalib.calib.patterns.calibration_patterns import frame_width
from lenticalib.core.errors import InputError
from lenticalib.core.files.imageio import read_image
from lenticalib.core.layout import SubpixelLayout, pattern_for_mode
from lenticalib.core.profile import PanelProfile
from lenticalib.core.routing import view_map

# gen3-like cells (pixels, y down): R and G on one row, B on the other, mirrored between columns
GEN3 = (((-0.25, 0.31), (-0.25, -0.28), (0.25, 0.0)), ((0.25, 0.31), (0.25, -0.28), (-0.25, 0.0)))


def _cell_panel(reversed_views=False, n=8, period=7.7, width=150, height=48):
    stripe = PanelProfile(views=n, slant=-0.19, period=period, offset=1.9, reference_view=0.6, width=width,
                          height=height)
    layout = SubpixelLayout(cells=GEN3, pattern=pattern_for_mode(2, 2, height))  # alternating columns
    return stripe, stripe.replace(subpixel_layout=layout, views_reversed=reversed_views)


def _circular(a, n):
    return np.abs(np.mod(a + n / 2.0, n) - n / 2.0)


@pytest.mark.parametrize("reversed_views", [False, True])
def test_crosstalk_patterns_light_the_slots_the_routing_gives_each_view(reversed_views):
    stripe, profile = _cell_panel(reversed_views)
    n = profile.views
    views = view_map(profile).astype(np.float64)  # [y, 3 x + slot], slot = channel with a layout
    assert np.mean(views != view_map(stripe)) > 0.5  # read as a stripe, most slots show another view
    pattern_set = design_crosstalk_patterns(profile)
    f = frame_width(profile.height)
    inner = (slice(f, profile.height - f), slice(3 * f, 3 * (profile.width - f)))
    xs = np.arange(profile.subpixels_per_row)
    for pattern in pattern_set.patterns:
        image = pattern_set.render(pattern)  # (H, W, 3): channel c of pixel x is slot 3 x + c
        lit = (image.reshape(profile.height, -1) == 255)[inner]
        if pattern.kind in ("black", "white"):
            assert lit.all() == (pattern.kind == "white") and lit.any() == (pattern.kind == "white")
            continue
        if pattern.kind == "level":  # whole panel rows, whatever view a slot shows
            rows = np.arange(profile.height)[inner[0]]
            assert np.array_equal(lit.all(axis=1), rows % pattern.row_period == 0) and lit.all(axis=1).any()
            assert not lit[rows % pattern.row_period != 0].any()
            continue
        # the band (half) is one view (N/2 views) wide about b (b + N/2 for the complement): a lit
        # slot's view holds a point within half a view (N/4 views) of it; a layout's slot shift
        # moves b by far less than 0.1 view
        centre = band_centre(pattern_set, xs, pattern.shift)[inner[1]] + (n / 2.0 if pattern.complement else 0.0)
        distance = _circular(views[inner] + 0.5 - centre, n)
        width = 0.5 if pattern.kind == "band" else n / 4.0
        assert distance[lit].max() < width + 0.5 + 0.1
        assert np.mean(lit) > 0.5 / n
        if pattern.kind == "half":
            assert distance[~lit].min() > width - 0.5 - 0.1


def test_comparison_routes_each_slot_by_its_layout():
    stripe, profile = _cell_panel()
    same = compare_profiles(profile, profile)
    assert (same.centring, same.rms, same.worst, same.order_match) == (0.0, 0.0, 0.0, True)
    # every channel one subpixel right of its stripe place: every slot's w is N / period lower
    shifted = stripe.replace(subpixel_layout=SubpixelLayout(cells=(((0.0, 0.0), (1 / 3, 0.0), (2 / 3, 0.0)),)))
    moved = compare_profiles(shifted, stripe)
    assert moved.centring == pytest.approx(-stripe.views / stripe.period, abs=1e-9)
    assert moved.rms < 1e-9 and moved.worst < 1e-9 and not moved.order_match
    # the gen3 cells: per channel and per cell another shift, e = 1 + 3 dx - 3 C_r dy - c
    slant = stripe.slant
    shifts = np.array([[1 + 3 * dx - 3 * slant * dy - c for c, (dx, dy) in enumerate(cell)] for cell in GEN3])
    d = -shifts.ravel() * stripe.views / stripe.period  # equal shares of slots (an even width)
    cells = compare_profiles(profile, stripe)
    assert cells.centring == pytest.approx(d.mean(), abs=1e-9)
    assert cells.rms == pytest.approx(d.std(), abs=1e-9)
    assert cells.worst == pytest.approx(np.abs(d - d.mean()).max(), abs=1e-9)


def test_comparison_sees_reversed_views():
    stripe, _ = _cell_panel()
    reversed_stripe = stripe.replace(views_reversed=True)
    diff = compare_profiles(reversed_stripe, stripe)
    # shown w' = N - w: d = N - 2 w, which runs over the whole cycle across the panel
    assert diff.rms > 1.0 and diff.order_match
    assert compare_profiles(reversed_stripe, reversed_stripe).rms == 0.0


def test_crosstalk_pattern_folder_of_a_cell_panel_reads_back_with_its_layout(tmp_path):
    from lenticalib.calib.crosstalk.measure import open_crosstalk_set
    from lenticalib.core.pattern_sets import read_pattern_folder, write_patterns

    stripe, profile = _cell_panel(reversed_views=True)
    profile = profile.replace(flip_image_x=True)
    written = design_crosstalk_patterns(profile)
    write_patterns(tmp_path / "xt", written)
    again = read_pattern_folder(tmp_path / "xt")
    assert again.profile.routing_key() == profile.routing_key() and again.set_id == written.set_id
    for pattern in again.patterns:
        np.testing.assert_array_equal(read_image(tmp_path / "xt" / pattern.file), again.render(pattern))
    # the measurement refuses the stripe reading of the same panel: another routing
    with pytest.raises(InputError, match="not the profile the crosstalk patterns were drawn from"):
        open_crosstalk_set(tmp_path / "xt", stripe)


@pytest.mark.slow
@pytest.mark.parametrize("name", ["lkg-columns", "lkg-checker"])
def test_crosstalk_of_a_cell_panel_is_measured_as_its_truth(name, capture_set):
    # the virtual panel with gen3-like cells, its crosstalk patterns drawn from a slightly imperfect
    # profile with the panel's layout, photographed (16-bit linear) and measured against the truth
    import json

    from lenticalib.calib.crosstalk.measure import measure_crosstalk
    from lenticalib.sim.layouts import NAMED_LAYOUTS
    from lenticalib.sim.scene import random_scene

    views = 32
    scene = random_scene(31, width=1280, height=720, resolution=(1500, 1000), subsamples=1, distance=620.0,
                         layout=NAMED_LAYOUTS[name])
    truth = scene.truth_profile(views)
    assert truth.subpixel_layout == NAMED_LAYOUTS[name]
    profile = truth.replace(offset=truth.offset + 0.05 * truth.period / views, period=truth.period * (1 + 2e-6))
    folder = capture_set(scene, design_crosstalk_patterns(profile), raw=True)
    measured = measure_crosstalk(folder, photos="linear")
    true_matrix = np.asarray(json.loads((folder / "crosstalk-truth.json").read_text())["matrix"])
    sigma = measured.row_sigma[(np.arange(views)[None, :] - np.arange(views)[:, None]) % views]
    error = measured.matrix - true_matrix
    assert np.abs(error).max() < 0.015 and abs(error[0, 0]) < 0.012
    assert np.all(np.abs(error) <= 3 * sigma + 1e-6)
    # the patterns drawn as a stripe would light other subpixels: the layout is what was measured
    drawn = design_crosstalk_patterns(profile)
    as_stripe = design_crosstalk_patterns(profile.replace(subpixel_layout=None))
    band = drawn.bands[0]
    mine, stripes = drawn.render(band), as_stripe.render(band)
    lit = (mine == 255) | (stripes == 255)
    assert np.mean(mine[lit] != stripes[lit]) > 0.3
