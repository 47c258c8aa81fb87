import dataclasses
import functools
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from lenticalib.core.errors import ImageError, InputError
from lenticalib.core.layout import LKG_CELL_PATTERNS, SubpixelLayout, pattern_for_mode
from lenticalib.core.profile import PanelProfile
from lenticalib.render.encoders import available_encoders, encode, get_encoder
from lenticalib.core.routing import tie_mask, view_map

from .strategies import VIEW_COUNTS, profiles, tie_profiles

ENCODERS = ("reference", "tables", "fast")
FIXTURES = Path(__file__).resolve().parent.parent / "fixtures"


def _in_output_order(profile, per_subpixel):
    """``(H, 3W)`` indexed ``[y, x_s]`` -> ``(H, W, 3)`` indexed ``[y, x, channel]``."""
    xs = 3 * np.arange(profile.width)[:, None] + np.asarray(profile.rho)[None, :]
    return per_subpixel[:, xs.reshape(-1)].reshape(profile.height, profile.width, 3)


@functools.lru_cache(maxsize=1)
def bundled_4k():
    """The bundled 4K, 32-view profile and what the whole-panel tests compare with, computed once
    a session (here and in test_encoder_torch.py): ``(profile, ties, expected, views, reference)``
    -- the count of its tie subpixels, the canonical view of every subpixel in output order
    (int8 ``(H, W, 3)``, -1 where dark), the demo quilt's views and their reference encoding."""
    from lenticalib.core.profile import load_profile
    from lenticalib.render.compose.views import load_quilt

    profile = load_profile(FIXTURES / "panel-4k-32.json")
    expected = _in_output_order(profile, view_map(profile)).astype(np.int8)
    views, _ = load_quilt(FIXTURES / "demo_qs8x4a1.7778.png", profile.views)
    for array in (expected, views):
        array.flags.writeable = False
    reference = encode(views, profile, "reference")
    reference.flags.writeable = False
    return profile, int(tie_mask(profile).sum()), expected, views, reference


def _numbered_views(profile, dtype, hv=3, wv=5):
    """View i filled with i + 1: a raster of these is the chosen view + 1 (0 where dark)."""
    number = np.arange(1, profile.views + 1).astype(dtype)
    return np.broadcast_to(number[:, None, None, None], (profile.views, hv, wv, 3)).copy()


def _chosen_views(name, profile, dtype):
    """The view ``name`` picks for every subpixel, in output order, -1 where it lights none."""
    out = encode(_numbered_views(profile, dtype), profile, name, allow_stretch=True)
    return out.astype(np.int64) - 1


def _random_views(profile, data, dtype):
    hv = data.draw(st.integers(1, 2 * profile.height), label="H_v")
    wv = data.draw(st.integers(1, 2 * profile.width), label="W_v")
    rng = np.random.default_rng(data.draw(st.integers(0, 2**32 - 1), label="seed"))
    if dtype == np.uint8:
        return rng.integers(0, 256, (profile.views, hv, wv, 3), dtype=np.uint8)
    if dtype == np.uint16:
        return rng.integers(0, 65536, (profile.views, hv, wv, 3), dtype=np.uint16)
    return rng.random((profile.views, hv, wv, 3)).astype(dtype)


@pytest.mark.parametrize("name", ENCODERS)
@pytest.mark.parametrize("dtype", [np.uint8, np.uint16, np.float64])
@given(st.one_of(profiles(), tie_profiles(min_width=22)))
@settings(max_examples=25)
def test_every_encoder_chooses_the_canonical_view_everywhere(name, dtype, profile):
    # uint8 on panels >= 22 pixels wide runs the vectorized block kernel, the others the scalar one
    expected = _in_output_order(profile, view_map(profile)).astype(np.int64)
    np.testing.assert_array_equal(_chosen_views(name, profile, dtype), expected)


@pytest.mark.slow
def test_encoders_agree_on_the_bundled_profile_everywhere():
    # no tie exclusion: the demo profile has ~2,500 subpixels whose w sits on a view boundary
    # (to float64 precision), where the float64 evaluation of the routing rule used to light two views or the other one
    profile, ties, expected, views, ref = bundled_4k()
    assert ties > 1000
    for name in ENCODERS:
        np.testing.assert_array_equal(_chosen_views(name, profile, np.uint8), expected, err_msg=name)
    np.testing.assert_array_equal(encode(views, profile, "tables"), ref)
    assert np.abs(encode(views, profile, "fast").astype(np.int32) - ref).max() <= 1
    wide = views.astype(np.uint16) * 257  # uint16: the scalar kernel, identical to the reference
    np.testing.assert_array_equal(encode(wide, profile, "fast"), encode(wide, profile, "reference"))


@given(st.one_of(profiles(), tie_profiles()), st.data())
@settings(max_examples=80)
def test_fast_matches_reference_within_one_lsb_uint8(profile, data):
    _assert_fast_within_one_level_uint8(profile, data)


def _assert_fast_within_one_level_uint8(profile, data):
    views = _random_views(profile, data, np.uint8)
    ref = encode(views, profile, "reference", allow_stretch=True).astype(np.int32)
    fast = encode(views, profile, "fast", allow_stretch=True).astype(np.int32)
    assert np.abs(ref - fast).max(initial=0) <= 1


@given(st.one_of(profiles(), tie_profiles()), st.data(), st.sampled_from([np.uint16, np.float32, np.float64]))
@settings(max_examples=40)
def test_fast_matches_reference_bit_for_bit_other_dtypes(profile, data, dtype):
    views = _random_views(profile, data, dtype)
    ref = encode(views, profile, "reference", allow_stretch=True)
    fast = encode(views, profile, "fast", allow_stretch=True)
    assert fast.dtype == views.dtype
    np.testing.assert_array_equal(ref, fast)


@given(st.one_of(profiles(max_width=30, max_height=16), tie_profiles(max_width=30, max_height=16)), st.data())
@settings(max_examples=30)
def test_table_encoder_matches_reference(profile, data):
    views = _random_views(profile, data, np.uint8)
    np.testing.assert_array_equal(encode(views, profile, "tables", allow_stretch=True),
                                  encode(views, profile, "reference", allow_stretch=True))


@pytest.mark.parametrize("n", VIEW_COUNTS)
@pytest.mark.parametrize("order", ["RGB", "BGR"])
@pytest.mark.parametrize("sign", [-1, 1])
def test_fast_block_kernel_on_a_wide_panel(n, order, sign):
    # wide enough for the vectorized uint8 path, odd width so the last block overlaps
    profile = PanelProfile(views=n, slant=sign * 0.2113, period=0.61 * n + 0.37, offset=3.3,
                           reference_view=n / 2, width=331, height=19, subpixel_order=order)
    rng = np.random.default_rng(n)
    views = rng.integers(0, 256, (n, 10, 173, 3), dtype=np.uint8)
    ref = encode(views, profile, "reference").astype(np.int32)
    fast = encode(views, profile, "fast").astype(np.int32)
    assert np.abs(ref - fast).max() <= 1
    assert (np.abs(ref - fast) == 0).mean() > 0.5


@st.composite
def cell_layout_profiles(draw, max_width=61, max_height=20):
    """Profiles with a subpixel layout of every Looking Glass cell pattern (1x1, 2x2, 4x1, 4x2, 1x2),
    either view direction, and dark bands allowed.  Half of them are built for exact ties: dyadic
    slant, period, offset and channel offsets, so many slots sit on a view or dark boundary."""
    n = draw(st.sampled_from(VIEW_COUNTS))
    mode = draw(st.sampled_from(sorted(LKG_CELL_PATTERNS)))
    n_cells = draw(st.integers(1, 4))
    height = draw(st.integers(2, max_height))
    pattern = pattern_for_mode(mode, n_cells, height)
    if draw(st.booleans(), label="ties"):
        k = draw(st.integers(max(1, -(-8 // n)), 32))
        period, slant = n * k / 16, draw(st.integers(-6, 6)) / 16
        offset = (k * draw(st.integers(-20, 20)) + draw(st.sampled_from([0, 16]))) / 16
        offsets = st.integers(-8, 8).map(lambda i: i / 16)
    else:
        period = draw(st.floats(0.5, 2.0 * n, allow_subnormal=False))
        slant = draw(st.floats(-0.4, 0.4, allow_subnormal=False))
        offset = draw(st.floats(-60.0, 60.0, allow_subnormal=False))
        offsets = st.floats(-0.5, 0.5, allow_subnormal=False)
    cells = tuple(tuple((draw(offsets), draw(offsets)) for _ in range(3)) for _ in range(n_cells))
    # the block kernel needs 3 * width >= 64; widths that are not a multiple of the block
    width = draw(st.integers(max(22, -(-int(period) // 3) + 1), max_width))
    return PanelProfile(views=n, slant=slant, period=period, offset=offset,
                        reference_view=float(draw(st.integers(0, n))), width=width, height=height,
                        subpixel_order="RGB", subpixel_layout=SubpixelLayout(cells=cells, pattern=pattern),
                        views_reversed=draw(st.booleans(), label="views_reversed"))


@st.composite
def reversed_stripe_profiles(draw):
    """Stripe profiles (exact-tie ones included) with the view direction reversed, wide enough for the block kernel."""
    profile = draw(st.one_of(profiles(), tie_profiles(min_width=22)))
    return dataclasses.replace(profile, width=max(22, profile.width), views_reversed=True)


@pytest.mark.parametrize("dtype", [np.uint8, np.uint16])
@given(st.one_of(cell_layout_profiles(), reversed_stripe_profiles()))
@settings(max_examples=60)
def test_fast_routes_cell_layouts_and_reversed_views_canonically(dtype, profile):
    # uint8: the vectorized block kernel (lane table with slot shifts); uint16: the scalar kernel
    expected = _in_output_order(profile, view_map(profile)).astype(np.int64)
    np.testing.assert_array_equal(_chosen_views("fast", profile, dtype), expected)


def test_fast_block_kernel_on_every_lkg_cell_pattern():
    # fixed profiles: a 4K-like slant and period, dark bands (period > N), both view directions,
    # 2 and 4 cells; width 97 (291 values: 4 full blocks and an overlapping last one)
    cells = (((-0.25, -0.31), (-0.25, 0.28), (0.25, 0.0)), ((0.25, -0.31), (0.25, 0.28), (-0.25, 0.0)),
             ((0.1, 0.2), (-0.3, 0.0), (0.3, -0.2)), ((-0.1, 0.4), (0.0, -0.4), (0.2, 0.1)))
    rng = np.random.default_rng(21)
    for mode in sorted(LKG_CELL_PATTERNS):
        for n, period in ((32, 19.47), (8, 11.3)):
            for reverse in (False, True):
                layout = SubpixelLayout(cells=cells, pattern=pattern_for_mode(mode, 4 if mode else 2, 13))
                profile = PanelProfile(views=n, slant=-0.1835, period=period, offset=5.1, reference_view=n / 2,
                                       width=97, height=13, subpixel_order="RGB", subpixel_layout=layout,
                                       views_reversed=reverse)
                expected = _in_output_order(profile, view_map(profile)).astype(np.int64)
                np.testing.assert_array_equal(_chosen_views("fast", profile, np.uint8), expected,
                                              err_msg=f"mode {mode} N {n} reversed {reverse}")
                views = rng.integers(0, 256, (n, 7, 51, 3), dtype=np.uint8)
                ref = encode(views, profile, "reference", allow_stretch=True).astype(np.int32)
                fast = encode(views, profile, "fast", allow_stretch=True).astype(np.int32)
                assert np.abs(ref - fast).max() <= 1


@given(cell_layout_profiles(), st.data())
@settings(max_examples=40)
def test_fast_matches_reference_within_one_lsb_on_cell_layouts(profile, data):
    _assert_fast_within_one_level_uint8(profile, data)


def test_constant_views_encode_to_their_view_number():
    # view i filled with value i: the raster is the view map itself (routing, no sampling blur)
    profile = PanelProfile(views=48, slant=-0.177, period=29.9, offset=11.0, reference_view=7.0,
                           width=200, height=30, subpixel_order="BGR")
    views = np.broadcast_to(np.arange(48, dtype=np.uint8)[:, None, None, None], (48, 15, 100, 3)).copy()
    out = encode(views, profile)
    from lenticalib.core.routing import view_map
    vm = view_map(profile)
    xs = 3 * np.arange(200)[:, None] + np.asarray(profile.rho)[None, :]
    np.testing.assert_array_equal(out, vm[:, xs.reshape(-1)].reshape(30, 200, 3))


def test_registry_and_errors():
    assert {"reference", "tables", "fast"} <= set(available_encoders())
    with pytest.raises(InputError, match="unknown encoder 'nope'"):
        get_encoder("nope")
    profile = PanelProfile(views=8, slant=0.1, period=7.0, offset=0.0, reference_view=0.0, width=16, height=9)
    with pytest.raises(ImageError, match="got 7 views, the profile has 8"):
        encode(np.zeros((7, 9, 16, 3), np.uint8), profile)
    with pytest.raises(ImageError, match="expected shape"):
        encode(np.zeros((8, 9, 16), np.uint8), profile)
    with pytest.raises(ImageError, match="aspect"):
        encode(np.zeros((8, 16, 16, 3), np.uint8), profile)
    with pytest.raises(ImageError, match="unsupported pixel type"):
        encode(np.zeros((8, 9, 16, 3), np.int32), profile)


def test_fast_writes_into_a_preallocated_raster():
    profile = PanelProfile(views=8, slant=0.1, period=7.0, offset=0.0, reference_view=0.0, width=64, height=36)
    views = np.random.default_rng(0).integers(0, 256, (8, 18, 32, 3), dtype=np.uint8)
    out = np.empty((36, 64, 3), np.uint8)
    assert encode(views, profile, out=out) is out
    np.testing.assert_array_equal(out, encode(views, profile))
