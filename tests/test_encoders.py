import functools
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from lenticalib.core.errors import ImageError, InputError
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
    from lenticalib.render.views import load_quilt

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
