from fractions import Fraction

import numpy as np
from hypothesis import given, settings

from lenticalib.core.profile import PanelProfile
from lenticalib.core.routing import routing_plan, rule_views, tie_mask, view_coordinate, view_map

from lenticalib.render.compose.sampling import NO_VIEW, sampling_tables

from .exact import exact_view_map
from .strategies import profiles, tie_profiles


@given(profiles(max_width=40, max_height=24))
@settings(max_examples=60)
def test_view_map_equals_exact_arithmetic_everywhere(profile):
    # the fixed-point phase resolves exact ties like exact arithmetic; only values within 1e-12
    # view below a boundary (not on it) are beyond its resolution
    exact, near = exact_view_map(profile)
    np.testing.assert_array_equal(view_map(profile)[~near], exact[~near])


@given(tie_profiles(max_width=40, max_height=24))
@settings(max_examples=60)
def test_view_map_resolves_constructed_exact_ties_like_exact_arithmetic(profile):
    exact, near = exact_view_map(profile)
    assert not near.any()  # w is a multiple of 1/k: nothing lies just below a boundary
    p = Fraction(profile.period)
    w0 = Fraction(profile.reference_view) + Fraction(profile.offset) * profile.views / p
    assert (w0 - (w0.numerator // w0.denominator)) in (0, profile.views / p)  # (0, 0) is a tie
    np.testing.assert_array_equal(view_map(profile), exact)


@given(profiles())
def test_brute_force_rule_agrees_except_on_exact_ties(profile):
    count, views = rule_views(profile)
    ties = tie_mask(profile)
    canonical = view_map(profile)
    brute = np.where(count >= 1, views[0].astype(np.int16), -1)
    off_tie = ~ties
    np.testing.assert_array_equal(brute[off_tie], canonical[off_tie])
    assert count.max() <= 2  # only exact float ties can double up
    assert (count[off_tie] <= 1).all()
    if profile.period <= profile.views:
        assert (count[off_tie] == 1).all(), "every subpixel shows exactly one view when period <= N"


def test_period_larger_than_views_leaves_dark_subpixels():
    p = PanelProfile(views=8, slant=0.17, period=12.3, offset=1.1, reference_view=0.5, width=40, height=10)
    vm = view_map(p)
    dark = (vm == -1).mean()
    # a fraction N/period of the subpixels is lit
    assert abs((1 - dark) - 8 / 12.3) < 0.01
    w = view_coordinate(p)
    frac = w - np.floor(w)
    assert ((frac < 8 / 12.3) == (vm >= 0))[~tie_mask(p)].all()


def test_views_follow_the_optics_convention():
    # w falls by N/period per subpixel to the right; view = floor(w) mod N
    p = PanelProfile(views=32, slant=-0.12, period=18.5, offset=4.0, reference_view=16.0, width=64, height=8)
    w = view_coordinate(p)
    assert np.allclose(np.diff(w, axis=1), -32 / 18.5)
    ok = ~tie_mask(p)
    assert (view_map(p)[ok] == (np.floor(w) % 32)[ok]).all()


def test_routing_plan_is_cached_and_read_only():
    p = PanelProfile(views=8, slant=0.1, period=7.0, offset=0.0, reference_view=0.0, width=10, height=4)
    plan = routing_plan(p)
    assert routing_plan(p) is plan
    assert not plan.z0.flags.writeable and plan.dark is None and plan.k == (1 << 64) // 7
    assert plan.is_stripe and not plan.shift.flags.writeable


@given(tie_profiles(max_width=30, max_height=12))
@settings(max_examples=20)
def test_sampling_table_is_the_canonical_view_map(profile):
    tables = sampling_tables(profile, 4, 6)
    expected = view_map(profile)
    assert tables.view.dtype == np.uint8 and not tables.view.flags.writeable
    np.testing.assert_array_equal(tables.view, np.where(expected < 0, NO_VIEW, expected))
