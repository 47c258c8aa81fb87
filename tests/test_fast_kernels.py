"""The fast encoder's kernels one by one: ``permute`` (AVX-512 VBMI), ``gather`` and ``scalar``.

Through ``encode`` the fast encoder runs the fastest kernel that applies; here every kernel that
can run on this machine is forced on the same views, so the slower ones stay covered where the
faster one would take over.  Routing must equal ``view_map`` exactly (numbered views), values
stay within 1 LSB of the float64 reference.
"""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from lenticalib.core.layout import SubpixelLayout, pattern_for_mode
from lenticalib.core.profile import PanelProfile
from lenticalib.core.routing import view_map
from lenticalib.render.encoders import _permute, encode
from lenticalib.render.encoders.fast import KERNELS, encode_fast, usable_kernels

from .strategies import profiles, tie_profiles
from .test_encoders import _in_output_order, _numbered_views

CELLS = (((-0.25, -0.31), (-0.25, 0.28), (0.25, 0.0)), ((0.25, -0.31), (0.25, 0.28), (-0.25, 0.0)),
         ((0.1, 0.2), (-0.3, 0.0), (0.3, -0.2)), ((-0.1, 0.4), (0.0, -0.4), (0.2, 0.1)))


def _check_every_kernel(profile, hv, wv, seed=0):
    """Every usable kernel routes exactly like view_map and is within 1 LSB of the reference;
    returns the kernels that ran."""
    numbered = _numbered_views(profile, np.uint8, hv, wv)
    kernels = usable_kernels(numbered, profile)
    expected = _in_output_order(profile, view_map(profile)).astype(np.int64)
    views = np.random.default_rng(seed).integers(0, 256, (profile.views, hv, wv, 3), dtype=np.uint8)
    ref = encode(views, profile, "reference", allow_stretch=True).astype(np.int32)
    for kernel in kernels:
        chosen = encode_fast(numbered, profile, kernel=kernel).astype(np.int64) - 1
        np.testing.assert_array_equal(chosen, expected, err_msg=kernel)
        values = encode_fast(views, profile, kernel=kernel).astype(np.int32)
        assert np.abs(values - ref).max() <= 1, kernel
    return kernels


PANELS = [  # (views, period, layout mode or None, reversed, flip x, flip y, view width): dark bands where period > N
    (5, 9.7, None, False, False, False, 40),  # 16 bytes per transposed byte, views nearly the panel's width
    (8, 11.3, 4, True, True, False, 30),
    (32, 19.47, None, False, False, False, 24),  # the 4K case at a smaller size: 32 bytes
    (32, 19.47, 1, False, False, True, 30),
    (32, 40.3, 2, True, False, False, 25),  # dark bands
    (48, 29.9, 3, False, True, True, 22),  # 64 bytes: views a sixth of the panel
    (64, 45.5, None, True, False, False, 22),
]


@pytest.mark.parametrize("n, period, mode, reverse, flip_x, flip_y, wv", PANELS)
def test_every_kernel_routes_canonically_and_samples_within_one_level(n, period, mode, reverse, flip_x, flip_y, wv):
    width, height = 151 if n <= 32 else 140, 13  # 453 / 420 values: the last block overlaps
    layout = None if mode is None else SubpixelLayout(cells=CELLS, pattern=pattern_for_mode(mode, 4 if mode else 2, height))
    profile = PanelProfile(views=n, slant=-0.1835, period=period, offset=5.1, reference_view=n / 2, width=width,
                           height=height, subpixel_order="RGB" if layout else "BGR", subpixel_layout=layout,
                           views_reversed=reverse, flip_image_x=flip_x, flip_image_y=flip_y)
    kernels = _check_every_kernel(profile, 7, wv, seed=n)
    assert kernels[-2:] == ["gather", "scalar"]
    assert ("permute" in kernels) == _permute.available()


@given(st.one_of(profiles(max_width=200), tie_profiles(min_width=22, max_width=200)), st.integers(22, 60),
       st.integers(1, 9), st.booleans(), st.booleans(), st.booleans())
@settings(max_examples=40, deadline=None)
def test_every_kernel_on_drawn_profiles(profile, wv, hv, reverse, flip_x, flip_y):
    profile = profile.replace(width=max(profile.width, 22), views_reversed=reverse, flip_image_x=flip_x,
                              flip_image_y=flip_y)
    _check_every_kernel(profile, hv, wv)


def test_a_kernel_that_cannot_encode_the_views_is_refused():
    profile = PanelProfile(views=32, slant=0.18, period=19.47, offset=3.0, reference_view=16, width=30, height=8)
    views = np.zeros((32, 8, 30, 3), np.uint8)  # views as wide as the panel: too many windows for 32 views
    assert usable_kernels(views, profile) == ["gather", "scalar"]
    with pytest.raises(ValueError, match="kernel 'permute' cannot"):
        encode_fast(views, profile, kernel="permute")
    assert usable_kernels(views.astype(np.uint16), profile) == ["scalar"]
    assert set(KERNELS) == {"permute", "gather", "scalar"}


@pytest.mark.parametrize("n", [3, 16, 17, 32, 45, 64])
def test_source_rows_transpose_view_minor(n):
    if not _permute.available():  # no VBMI here: the fast encoder must not offer the kernel
        views = np.zeros((n, 4, 240, 3), np.uint8)
        profile = PanelProfile(views=n, slant=0.1, period=n * 0.7, offset=0.0, reference_view=0.0, width=1920, height=32)
        assert "permute" not in usable_kernels(views, profile)
        return
    vs = _permute.view_slots(n)
    assert vs == min(s for s in _permute.VIEW_SLOTS if s >= n)
    views = np.random.default_rng(n).integers(0, 256, (n, 4, 37, 3), dtype=np.uint8)  # 111-byte rows
    row_bytes, plane = 37 * 3, 4 * 37 * 3
    dest = np.zeros(row_bytes * vs + 64, np.uint8)
    for row in (0, 3):
        _permute._transpose_row(views.reshape(-1), row * row_bytes, plane, n, row_bytes, vs, dest)
        got = dest[:row_bytes * vs].reshape(row_bytes, vs)[:, :n]
        np.testing.assert_array_equal(got, views[:, row].reshape(n, -1).T)


def test_block_tables_address_every_tap_once():
    rng = np.random.default_rng(5)
    length, vs = 300, 32
    s_left = np.sort(rng.integers(0, 60, length))
    s_right = s_left + 3
    starts, s_min_bytes, tables, windows = _permute.block_tables(s_left, s_right, rng.random(length), vs)
    assert tables is not None and starts[-1] == length - _permute.LANES
    masks = tables[:, 6 * _permute.LANES:].view(np.uint64).reshape(len(starts), windows, 2)
    for blk, o0 in enumerate(starts):
        for tap, s in ((0, s_left), (1, s_right)):
            bits = masks[blk, :, tap]
            assert np.bitwise_or.reduce(bits) == np.uint64(2**64 - 1)  # every lane in some window ...
            assert sum(bin(int(b)).count("1") for b in bits) == _permute.LANES  # ... and in one only
            window = np.array([next(k for k in range(windows) if int(bits[k]) >> lane & 1) for lane in range(64)])
            base = tables[blk, tap * 64:(tap + 1) * 64].astype(np.int64)
            np.testing.assert_array_equal(s_min_bytes[blk] + window * _permute.WINDOW + base,
                                          s[o0:o0 + 64] * vs)  # the byte of view 0 of the tap
