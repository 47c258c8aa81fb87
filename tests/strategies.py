"""Hypothesis strategies shared by the tests: random but valid panel profiles."""

import math

from hypothesis import strategies as st

from lenticalib.core.profile import PanelProfile

VIEW_COUNTS = (2, 8, 32, 48, 64)


@st.composite
def profiles(draw, views=st.sampled_from(VIEW_COUNTS), max_width=61, max_height=40, dark_ok=True):
    n = draw(views)
    slant = draw(st.floats(0.0, 0.4, allow_subnormal=False)) * draw(st.sampled_from([-1.0, 1.0]))
    top = 2.0 * n if dark_ok else float(n)
    period = draw(st.floats(0.5, top, allow_subnormal=False))
    narrowest = max(3, math.ceil(period / 3))  # a valid profile's lens is no wider than a row
    return PanelProfile(
        views=n, slant=slant, period=period,
        offset=draw(st.floats(-60.0, 60.0, allow_subnormal=False)),
        reference_view=draw(st.floats(0.0, float(n), allow_subnormal=False)),
        width=draw(st.integers(narrowest, max(max_width, narrowest))), height=draw(st.integers(2, max_height)),
        subpixel_order=draw(st.sampled_from(["RGB", "BGR"])))


@st.composite
def tie_profiles(draw, views=st.sampled_from(VIEW_COUNTS), min_width=3, max_width=61, max_height=40):
    """Profiles built so that ``w`` lands exactly on decision boundaries (exact ties).

    ``period = N k / 16``, ``slant = c / 16``, ``offset = (k t + e) / 16``, integer ``i_ref``: all
    exact binary floats, and ``w(x_s, y) = i_ref + t + (3 c y + e - 16 x_s) / k`` is a multiple of
    ``1/k``, so many subpixels sit exactly on a boundary.  With ``e = 0`` subpixel ``(0, 0)`` has an
    integer ``w`` (a view boundary); with ``e = 16`` (drawn only when ``k > 16``, i.e.
    ``period > N``) it sits exactly on the dark boundary ``frac(w) = N / period``.
    """
    n = draw(views)
    k = draw(st.integers(max(1, -(-8 // n)), 32))  # period >= 0.5 subpixel
    e = draw(st.sampled_from([0, 16])) if k > 16 else 0
    t = draw(st.integers(-20, 20))
    period = n * k / 16
    # a lens no wider than the panel's row (profile validation): width >= period / 3
    width = draw(st.integers(max(min_width, int(-(-period // 3))), max(max_width, int(-(-period // 3)))))
    return PanelProfile(
        views=n, slant=draw(st.integers(-6, 6)) / 16, period=period, offset=(k * t + e) / 16,
        reference_view=float(draw(st.integers(0, n))),
        width=width, height=draw(st.integers(2, max_height)),
        subpixel_order=draw(st.sampled_from(["RGB", "BGR"])))
