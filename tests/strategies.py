"""Hypothesis strategies shared by the tests: random but valid panel profiles."""

import math

from hypothesis import strategies as st

from lenticalib.profile import PanelProfile

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
