"""Encoders and sampling on panels that are not a plain stripe: cell layouts, reversed views, flips.

The golden routing is :func:`lenticalib.core.routing.view_map` (tested against exact arithmetic
and the Looking Glass rule elsewhere); here every encoder must choose its view for every slot,
with a layout's slot ``c`` being channel ``c``, and must sample like the reference encoder.  The
flips are checked against their definition: the view images shown mirrored.
"""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from lenticalib.core.layout import LKG_CELL_PATTERNS, SubpixelLayout, pattern_for_mode
from lenticalib.core.profile import PanelProfile
from lenticalib.core.routing import view_map
from lenticalib.render.encoders import encode
from lenticalib.render.compose.sampling import column_sampling, row_sampling

from .strategies import profiles
from .test_encoders import _chosen_views, _in_output_order, _random_views

ENCODERS = ("reference", "tables", "fast", "torch")
CELLS_OF_MODE = {0: 1, 1: 2, 2: 4, 3: 4, 4: 2}  # cells a Looking Glass calibration of each mode lists


def _layout(rng: np.random.Generator, mode: int, height: int) -> SubpixelLayout:
    """Random channel positions (within half a pixel of the centre) in the cells of ``mode``."""
    count = CELLS_OF_MODE[mode]
    cells = tuple(tuple((float(rng.uniform(-0.5, 0.5)), float(rng.uniform(-0.5, 0.5))) for _ in range(3))
                  for _ in range(count))
    return SubpixelLayout(cells=cells, pattern=pattern_for_mode(mode, count, height))


@st.composite
def layout_profiles(draw, min_width=3):
    """Profiles with a cell layout of every Looking Glass pattern, reversed views and flips drawn too."""
    base = draw(profiles())
    if base.width < min_width:
        base = base.replace(width=min_width)
    mode = draw(st.sampled_from(sorted(LKG_CELL_PATTERNS)), label="CellPatternMode")
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1), label="layout seed"))
    return base.replace(subpixel_order="RGB", subpixel_layout=_layout(rng, mode, base.height),
                        views_reversed=draw(st.booleans()), flip_image_x=draw(st.booleans()),
                        flip_image_y=draw(st.booleans()))


def _panel(mode=4, reversed_views=False, flip_x=False, flip_y=False, n=8, period=7.5, width=40, height=12, seed=3):
    """A small cell-layout panel whose layout moves many slots to another view than the stripe's."""
    profile = PanelProfile(views=n, slant=-0.21, period=period, offset=2.7, reference_view=1.3, width=width,
                           height=height)
    return profile.replace(subpixel_layout=_layout(np.random.default_rng(seed), mode, height),
                           views_reversed=reversed_views, flip_image_x=flip_x, flip_image_y=flip_y)


@pytest.mark.parametrize("name", ENCODERS)
@pytest.mark.parametrize("mode", sorted(LKG_CELL_PATTERNS))
@pytest.mark.parametrize("reversed_views", [False, True])
def test_every_encoder_routes_each_cell_pattern_by_the_view_map(name, mode, reversed_views):
    profile = _panel(mode, reversed_views, flip_x=True)
    expected = _in_output_order(profile, view_map(profile)).astype(np.int64)
    stripe = _in_output_order(profile, view_map(profile.replace(subpixel_layout=None,
                                                                views_reversed=False))).astype(np.int64)
    assert np.mean(expected != stripe) > 0.3  # the layout (or the reversal) moves most slots
    for dtype in (np.uint8, np.float64):  # uint8 on a 40-pixel panel: the fast block kernel where it applies
        np.testing.assert_array_equal(_chosen_views(name, profile, dtype), expected)


@pytest.mark.parametrize("name", ENCODERS)
@given(layout_profiles(min_width=22))
@settings(max_examples=20, deadline=None)
def test_every_encoder_chooses_the_view_map_on_random_layouts(name, profile):
    expected = _in_output_order(profile, view_map(profile)).astype(np.int64)
    np.testing.assert_array_equal(_chosen_views(name, profile, np.uint8), expected)


@pytest.mark.parametrize("name, dtype", [("tables", np.uint8), ("tables", np.float32), ("torch", np.uint8),
                                         ("torch", np.uint16), ("torch", np.float64), ("fast", np.uint16),
                                         ("fast", np.float64)])
@given(profile=layout_profiles(), data=st.data())
@settings(max_examples=15, deadline=None)
def test_encoders_equal_the_reference_bit_for_bit_on_layouts_and_flips(name, dtype, profile, data):
    views = _random_views(profile, data, dtype)
    expected = encode(views, profile, "reference", allow_stretch=True)
    np.testing.assert_array_equal(encode(views, profile, name, allow_stretch=True), expected)


@given(profile=layout_profiles(min_width=22), data=st.data())
@settings(max_examples=20, deadline=None)
def test_fast_uint8_is_within_one_level_of_the_reference_on_layouts_and_flips(profile, data):
    views = _random_views(profile, data, np.uint8)
    expected = encode(views, profile, "reference", allow_stretch=True).astype(np.int64)
    assert np.abs(encode(views, profile, "fast", allow_stretch=True).astype(np.int64) - expected).max() <= 1


@pytest.mark.parametrize("flip_x, flip_y", [(True, False), (False, True), (True, True)])
@pytest.mark.parametrize("mode", [0, 3])
def test_a_flip_shows_every_view_mirrored(flip_x, flip_y, mode):
    # flipImageX / flipImageY: the panel shows the view images mirrored, routed as before
    plain = _panel(mode, reversed_views=mode == 3, width=30, height=17)
    flipped = plain.replace(flip_image_x=flip_x, flip_image_y=flip_y)
    views = np.random.default_rng(5).random((plain.views, 11, 19, 3))
    mirrored = views[:, ::-1 if flip_y else 1, ::-1 if flip_x else 1]
    expected = encode(np.ascontiguousarray(mirrored), plain, "reference", allow_stretch=True)
    got = encode(views, flipped, "reference", allow_stretch=True)
    np.testing.assert_allclose(got, expected, rtol=0, atol=1e-12)
    assert np.abs(got - encode(views, plain, "reference", allow_stretch=True)).max() > 0.1


def test_flipped_sample_points_are_the_mirror_images():
    profile = _panel(width=25, height=9)
    for view_size in (1, 2, 7, 64):
        for axis, sampling, count in (("x", column_sampling, 75), ("y", row_sampling, 9)):
            flipped = profile.replace(**{f"flip_image_{axis}": True})
            a, b = sampling(profile, view_size), sampling(flipped, view_size)
            # u' = n_src - 1 - u at every output index (u = lo + weight)
            np.testing.assert_allclose(b.lo + b.weight, view_size - 1 - (a.lo + a.weight), atol=1e-12)
            assert b.lo.shape == (count,) and np.all(b.lo >= 0) and np.all(b.hi <= view_size - 1)
            assert np.all(b.hi - b.lo == (1 if view_size > 1 else 0))
