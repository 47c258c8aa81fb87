"""The torch encoder (render/encoders/torch_encoder.py): bit-identical to the reference, on the device, registered.

CPU only (no GPU here); the CUDA path runs the same torch ops.  Fixed seeds; hypothesis runs
derandomized (conftest).
"""

import dis
import json
import sys

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import torch  # noqa: E402  (a test dependency: pip install -e .[test])

from lenticalib.core.errors import ConfigurationError, ImageError  # noqa: E402
from lenticalib.core.files.imageio import read_image, write_image  # noqa: E402
from lenticalib.core.profile import PanelProfile, load_profile  # noqa: E402
from lenticalib.render.encoders import encode, get_encoder  # noqa: E402
from lenticalib.render.encoders import torch_encoder as te  # noqa: E402
from lenticalib.core.routing import view_map  # noqa: E402
from lenticalib.render.compose.sampling import NO_VIEW, column_sampling, row_sampling  # noqa: E402
from lenticalib.render.compose.views import QuiltGrid, load_quilt, make_quilt  # noqa: E402

from .strategies import profiles, tie_profiles  # noqa: E402
from .test_encoders import _chosen_views, _in_output_order, _random_views, bundled_4k  # noqa: E402


def _profile(n=32, sign=1, period=19.47, order="RGB", width=61, height=19, offset=3.3):
    return PanelProfile(views=n, slant=sign * 0.2113, period=period, offset=offset, reference_view=n / 2,
                        width=width, height=height, subpixel_order=order)


def _views(n, hv, wv, dtype, seed):
    rng = np.random.default_rng(seed)
    if dtype in (np.uint8, np.uint16):
        return rng.integers(0, np.iinfo(dtype).max + 1, (n, hv, wv, 3)).astype(dtype)
    return rng.random((n, hv, wv, 3)).astype(dtype)


def _encode_tensor(views, profile, dtype=torch.float64):
    encoder = te.TorchEncoder(profile, views.shape[1:3], "cpu", dtype)
    return encoder.encode(torch.from_numpy(views)).numpy()


# --- bit-identical to the reference ------------------------------------------------------------

@pytest.mark.slow
def test_bundled_profile_bit_identical_to_reference_everywhere():
    # the demo profile has ~2,500 subpixels on a view boundary (ties): every one routed canonically
    profile, ties, expected, views, reference = bundled_4k()  # shared with test_encoders.py
    assert ties > 1000
    np.testing.assert_array_equal(_chosen_views("torch", profile, np.uint8), expected)
    np.testing.assert_array_equal(encode(views, profile, "torch"), reference)
    wide = views.astype(np.uint16) * 257 + np.arange(3, dtype=np.uint16)  # uint16, odd low bits
    np.testing.assert_array_equal(encode(wide, profile, "torch"), encode(wide, profile, "reference"))
    # the tables of a 4K panel: 5 bytes per subpixel (int32 index, uint8 view) + float64 weights per column/row
    tables = te.cached_encoder(profile, views.shape[1:3]).tables
    subpixels = 3 * profile.width * profile.height
    assert tables.secondary_index is None and tables.primary_index.dtype == torch.int32
    assert tables.nbytes == 5 * subpixels + 8 * 2 * (3 * profile.width + profile.height) == 124_634_880


@pytest.mark.parametrize("order", ["RGB", "BGR"])
@pytest.mark.parametrize("sign", [-1, 1])
@pytest.mark.parametrize("n, period", [(32, 19.47), (8, 8.0), (48, 61.3), (2, 0.75)])  # < N, = N, > N (dark)
def test_matches_reference_at_several_view_sizes(order, sign, n, period):
    profile = _profile(n=n, sign=sign, period=period, order=order)
    for seed, (hv, wv) in enumerate([(1, 1), (1, 9), (7, 1), (10, 17), (19, 61), (45, 150)]):
        for dtype in (np.uint8, np.uint16):
            views = _views(n, hv, wv, dtype, seed)
            ref = encode(views, profile, "reference", allow_stretch=True)
            np.testing.assert_array_equal(_encode_tensor(views, profile), ref, err_msg=f"{dtype} {hv}x{wv}")


@pytest.mark.parametrize("dtype", [np.uint8, np.uint16, np.float64])
@given(st.one_of(profiles(), tie_profiles(min_width=22)))
@settings(max_examples=25)
def test_chooses_the_canonical_view_everywhere(dtype, profile):
    expected = _in_output_order(profile, view_map(profile)).astype(np.int64)
    np.testing.assert_array_equal(_chosen_views("torch", profile, dtype), expected)


@given(st.one_of(profiles(), tie_profiles()), st.data(), st.sampled_from([np.uint8, np.uint16]))
@settings(max_examples=60)
def test_matches_reference_bit_for_bit_random_profiles(profile, data, dtype):
    views = _random_views(profile, data, dtype)
    np.testing.assert_array_equal(encode(views, profile, "torch", allow_stretch=True),
                                  encode(views, profile, "reference", allow_stretch=True))


@given(st.one_of(profiles(), tie_profiles()), st.data(), st.sampled_from([np.float32, np.float64]))
@settings(max_examples=20)
def test_matches_reference_bit_for_bit_float_views(profile, data, dtype):
    views = _random_views(profile, data, dtype)
    out = encode(views, profile, "torch", allow_stretch=True)
    assert out.dtype == views.dtype
    np.testing.assert_array_equal(out, encode(views, profile, "reference", allow_stretch=True))


@pytest.mark.parametrize("dtype", [np.uint8, np.uint16])
def test_full_scale_views_stay_full_scale(dtype):
    # float64 skips the clip: a blend of full-scale values must not round past full scale
    top = np.iinfo(dtype).max
    profile = _profile(n=8, period=7.3)
    views = np.full((8, 13, 29, 3), top, dtype=dtype)
    assert (_encode_tensor(views, profile) == top).all()
    for compute in ([torch.float32, torch.float16] if dtype == np.uint8 else [torch.float32]):
        assert (_encode_tensor(views, profile, compute) == top).all()


@pytest.mark.parametrize("compute, dtypes", [(torch.float32, [np.uint8, np.uint16]), (torch.float16, [np.uint8])])
@pytest.mark.parametrize("order", ["RGB", "BGR"])
def test_reduced_precision_is_within_one_level(compute, dtypes, order):
    for seed, (n, period, sign) in enumerate([(32, 19.47, 1), (8, 11.1, -1), (48, 29.9, -1)]):
        profile = _profile(n=n, sign=sign, period=period, order=order, width=97, height=23)
        for dtype in dtypes:
            views = _views(n, 40, 90, dtype, seed)
            ref = encode(views, profile, "reference", allow_stretch=True).astype(np.int64)
            got = _encode_tensor(views, profile, compute).astype(np.int64)
            assert np.abs(got - ref).max() <= 1


def test_reduced_precision_refuses_views_it_cannot_hold():
    profile = _profile(n=8, period=7.3)
    encoder = te.TorchEncoder(profile, (4, 6), dtype=torch.float16)
    with pytest.raises(ConfigurationError, match="float16 is not allowed for torch.uint16 views"):
        encoder.encode(torch.zeros((8, 4, 6, 3), dtype=torch.uint16))
    with pytest.raises(ConfigurationError, match="unsupported compute dtype"):
        te.TorchEncoder(profile, (4, 6), dtype=torch.bfloat16)


# --- on the device, no host round trip ---------------------------------------------------------

class _StaysOnDevice(torch.overrides.TorchFunctionMode):
    """Fails on any torch call that moves data to the host; checks every tensor result's device."""

    HOST = {"numpy", "cpu", "item", "tolist", "__array__", "__bool__", "__int__", "__float__", "__index__"}

    def __init__(self, device):
        super().__init__()
        self.device = torch.device(device)
        self.calls = []

    def __torch_function__(self, func, types, args=(), kwargs=None):
        name = getattr(func, "__name__", str(func))
        self.calls.append(name)
        if name in self.HOST:
            raise AssertionError(f"host round trip during encode: {name}")
        result = func(*args, **(kwargs or {}))
        for value in (result if isinstance(result, (tuple, list)) else [result]):
            if isinstance(value, torch.Tensor) and value.device != self.device:
                raise AssertionError(f"{name} produced a tensor on {value.device}")
        return result


def _numpy_calls_during(fn):
    """Names of numpy functions (Python or C) entered while ``fn`` runs."""
    hits = []

    def profiler(frame, event, arg):
        if event == "call" and (frame.f_globals.get("__name__") or "").startswith("numpy"):
            hits.append(frame.f_code.co_name)
        elif event == "c_call" and (getattr(arg, "__module__", None) or "").startswith("numpy"):
            hits.append(getattr(arg, "__name__", repr(arg)))

    sys.setprofile(profiler)
    try:
        result = fn()
    finally:
        sys.setprofile(None)
    return result, hits


@pytest.mark.parametrize("dtype", [torch.uint8, torch.uint16, torch.float32])
@pytest.mark.parametrize("period", [19.47, 41.0])  # every subpixel lit / some dark
def test_encode_stays_on_the_device_and_never_touches_numpy(dtype, period):
    profile = _profile(period=period)
    views = torch.from_numpy(_views(32, 10, 17, np.uint16, 3)).to(dtype)
    encoder = te.TorchEncoder(profile, (10, 17), "cpu")
    watch = _StaysOnDevice("cpu")
    with watch:
        raster, numpy_calls = _numpy_calls_during(lambda: encoder.encode(views))
    assert numpy_calls == []
    assert "index_select" in watch.calls
    assert isinstance(raster, torch.Tensor) and raster.device == views.device
    assert raster.dtype == dtype and tuple(raster.shape) == (profile.height, profile.width, 3)
    # a preallocated raster is filled in place
    out = torch.empty_like(raster)
    with _StaysOnDevice("cpu"):
        assert encoder.encode(views, out=out) is out
    assert torch.equal(out, raster)


def test_encode_runs_on_a_device_without_host_access():
    # the meta device has no data at all: any copy to the host, .item() or numpy conversion raises
    for period in (19.47, 41.0):
        profile = _profile(period=period)
        encoder = te.TorchEncoder(profile, (10, 17), "meta")
        assert encoder.tables.primary_index.device.type == "meta"
        for dtype in (torch.uint8, torch.uint16, torch.float32, torch.float64):
            raster = encoder.encode(torch.empty((32, 10, 17, 3), dtype=dtype, device="meta"))
            assert raster.device.type == "meta" and raster.dtype == dtype
            assert tuple(raster.shape) == (profile.height, profile.width, 3)


def test_the_encode_path_has_no_numpy_in_its_code():
    functions = [te.TorchEncoder.encode, te.TorchEncoder._bilinear, te.TorchEncoder._check, te.TorchEncoder._output,
                 te._scale_fused, te._scale_split, te._Workspace.__init__, te._Workspace.rows]
    for function in functions:
        names = {ins.argval for ins in dis.get_instructions(function) if ins.opname in ("LOAD_GLOBAL", "LOAD_NAME")}
        assert not names & {"np", "numpy"}, function.__qualname__


def test_tensor_input_is_checked_in_one_line():
    profile = _profile(n=8, period=7.3)
    encoder = te.TorchEncoder(profile, (4, 6))
    cases = [
        (np.zeros((8, 4, 6, 3), np.uint8), "expected a torch tensor on cpu, got ndarray"),
        (torch.zeros((8, 4, 7, 3), dtype=torch.uint8), r"expected shape \(8, 4, 6, 3\), got \(8, 4, 7, 3\)"),
        (torch.zeros((7, 4, 6, 3), dtype=torch.uint8), r"expected shape \(8, 4, 6, 3\), got \(7, 4, 6, 3\)"),
        (torch.zeros((8, 4, 6, 3), dtype=torch.int32), "unsupported pixel type torch.int32"),
        (torch.zeros((8, 4, 6, 3), dtype=torch.uint8, device="meta"), "views are on meta, the encoder's tables on cpu"),
    ]
    for views, message in cases:
        with pytest.raises(ImageError, match=message) as info:
            encoder.encode(views)
        assert "\n" not in str(info.value)
    with pytest.raises(ImageError, match="output buffer must be a contiguous torch.uint8 tensor"):
        encoder.encode(torch.zeros((8, 4, 6, 3), dtype=torch.uint8), out=torch.empty((profile.height, 3, 3)))


# --- tables -------------------------------------------------------------------------------------

@pytest.mark.parametrize("order", ["RGB", "BGR"])
def test_tables_are_compact_and_hold_the_four_sample_indices(order):
    profile = _profile(n=48, sign=-1, period=61.3, order=order, width=31, height=11)  # period > N: dark subpixels
    hv, wv = 7, 13
    tables = te.build_tables(profile, (hv, wv))
    nsub = profile.subpixels_per_row
    assert tables.primary_view.dtype == torch.uint8 and tables.primary_index.dtype == torch.int32
    assert tables.secondary_view is None and tables.secondary_weight is None and tables.has_dark
    assert tables.nbytes == 5 * nsub * profile.height + 8 * 2 * (nsub + profile.height)
    # independently: view, taps and channel of every lit subpixel, in output order [y, 3 x + c]
    xs = (3 * np.arange(profile.width)[:, None] + np.asarray(profile.rho)[None, :]).reshape(-1)
    chan = np.tile(np.arange(3), profile.width)
    view = view_map(profile)[:, xs]
    np.testing.assert_array_equal(tables.primary_view.numpy(), np.where(view < 0, NO_VIEW, view))
    cols, rows = column_sampling(profile, wv), row_sampling(profile, hv)
    y = np.arange(profile.height)[:, None]
    shape = (profile.views, hv, wv, 3)
    expected = [np.ravel_multi_index((np.maximum(view, 0), ya[y], xa[xs][None, :], chan[None, :]), shape)
                for ya in (rows.lo, rows.hi) for xa in (cols.lo, cols.hi)]  # (y0 x0) (y0 x1) (y1 x0) (y1 x1)
    got = tables.sample_indices().numpy()
    lit = view >= 0
    for k in range(4):
        np.testing.assert_array_equal(got[k][lit], expected[k][lit])
    np.testing.assert_array_equal(tables.col_weight.numpy(), cols.weight[xs])
    np.testing.assert_array_equal(tables.row_weight0.numpy()[:, 0], 1.0 - rows.weight)


def _canonical_lit(profile):
    vm = view_map(profile)
    return (vm >= 0).astype(np.uint8), np.where(vm < 0, 255, vm)[None].astype(np.uint8)


def test_more_than_two_views_on_a_subpixel_is_refused_in_one_line():
    # the canonical routing never lights two (docs/routing.md); a routing handed to the table
    # builder (e.g. a crosstalk-compensating one) can, and more than two do not fit the tables
    profile = _profile(n=8, period=7.3, width=20, height=6)
    count, views = _canonical_lit(profile)
    count[2, 5] = count[4, 1] = 3
    views = np.concatenate([views, (views + 1) % 8, (views + 2) % 8])
    with pytest.raises(ConfigurationError) as info:
        te.build_tables(profile, (3, 10), lit=(count, views), secondary_weight=0.5)
    assert str(info.value) == ("routing: subpixel x_s=5, y=2 is lit by 3 views; the torch encoder's tables "
                               "hold at most two per subpixel (a primary and a secondary)")
    count[2, 5] = count[4, 1] = 2
    with pytest.raises(ConfigurationError, match="x_s=5, y=2 is lit by two views but no secondary_weight"):
        te.build_tables(profile, (3, 10), lit=(count, views))


def test_a_zero_weight_secondary_leaves_the_reference_result():
    profile = _profile(n=32, sign=-1, period=19.47, order="BGR")
    count, views = _canonical_lit(profile)
    count[:, ::2] = 2  # every other subpixel gets a second view, weight 0
    views = np.concatenate([views, (views + 5) % 32])
    tables = te.build_tables(profile, (10, 17), lit=(count, views), secondary_weight=0.0)
    assert tables.secondary_index is not None and tables.nbytes > te.build_tables(profile, (10, 17)).nbytes
    encoder = te.TorchEncoder(profile, (10, 17), tables=tables)
    for dtype in (np.uint8, np.uint16):
        v = _views(32, 10, 17, dtype, 7)
        np.testing.assert_array_equal(encoder.encode(torch.from_numpy(v)).numpy(),
                                      encode(v, profile, "reference", allow_stretch=True))


def _bilinear_model(views, profile, view):
    """float64 bilinear samples of ``view`` ``(H, 3W)`` (output order), the reference's expression."""
    n, hv, wv, _ = views.shape
    xs = (3 * np.arange(profile.width)[:, None] + np.asarray(profile.rho)[None, :]).reshape(-1)
    chan = np.tile(np.arange(3), profile.width)[None, :]
    cols, rows = column_sampling(profile, wv), row_sampling(profile, hv)
    x0, x1, fx = cols.lo[xs][None, :], cols.hi[xs][None, :], cols.weight[xs][None, :]
    y = np.arange(profile.height)
    y0, y1, fy = rows.lo[y][:, None], rows.hi[y][:, None], rows.weight[y][:, None]
    v = np.maximum(view, 0)
    top = views[v, y0, x0, chan] * (1.0 - fx) + views[v, y0, x1, chan] * fx
    bottom = views[v, y1, x0, chan] * (1.0 - fx) + views[v, y1, x1, chan] * fx
    return top * (1.0 - fy) + bottom * fy


def test_two_view_tables_blend_primary_and_secondary():
    profile = _profile(n=8, sign=1, period=7.3, order="RGB", width=40, height=12)
    count, views = _canonical_lit(profile)
    second = (views[0] + 3) % 8
    count[:, 1::3] = 2
    rng = np.random.default_rng(11)
    weight = rng.random(count.shape).astype(np.float32)
    tables = te.build_tables(profile, (6, 20), lit=(count, np.stack([views[0], second])), secondary_weight=weight)
    encoder = te.TorchEncoder(profile, (6, 20), tables=tables)
    v = rng.random((8, 6, 20, 3))
    got = encoder.encode(torch.from_numpy(v)).numpy().reshape(profile.height, -1)
    xs = (3 * np.arange(profile.width)[:, None] + np.asarray(profile.rho)[None, :]).reshape(-1)
    w = np.where(count == 2, weight, 0.0)[:, xs].astype(np.float64)
    expected = (_bilinear_model(v, profile, views[0][:, xs].astype(np.int64)) * (1.0 - w)
                + _bilinear_model(v, profile, second[:, xs].astype(np.int64)) * w)
    np.testing.assert_array_equal(got, expected)


# --- registry, cache and command line -----------------------------------------------------------

def test_registry_gives_encode_torch_and_caches_encoders():
    assert get_encoder("torch") is te.encode_torch
    te.clear_cache()
    profiles_ = [_profile(n=8, period=7.3, offset=o) for o in (0.0, 1.0, 2.0)]
    first = te.cached_encoder(profiles_[0], (4, 6))
    assert te.cached_encoder(profiles_[0].replace(name="renamed"), (4, 6)) is first  # keyed by routing
    assert te.cached_encoder(profiles_[0], (4, 7)) is not first
    for p in profiles_[1:]:
        te.cached_encoder(p, (4, 6))
    assert te.cached_encoder(profiles_[0], (4, 6)) is not first  # evicted after CACHE_SIZE others
    te.clear_cache()


def test_encode_to_file_with_the_torch_encoder(tmp_path):
    """What 'lenticalib encode --encoder torch' runs: the raster file is the reference encoding."""
    from lenticalib.render.pipeline.encode_file import encode_to_file

    profile = {"views": 8, "slant": 0.19, "period": 7.4, "offset": 1.5, "reference_view": 4,
               "width": 96, "height": 54, "subpixel_order": "BGR"}
    (tmp_path / "panel.json").write_text(json.dumps(profile))
    views = np.random.default_rng(0).integers(0, 256, (8, 27, 48, 3), dtype=np.uint8)
    write_image(tmp_path / "q_qs4x2a1.78.png", make_quilt(views, QuiltGrid(4, 2)))
    done = encode_to_file(tmp_path / "panel.json", tmp_path / "o.png", quilt=tmp_path / "q_qs4x2a1.78.png",
                          encoder="torch")
    assert done.summary()["encoder"] == "torch"
    loaded, _ = load_quilt(tmp_path / "q_qs4x2a1.78.png", 8)
    np.testing.assert_array_equal(read_image(tmp_path / "o.png"),
                                  encode(loaded, load_profile(tmp_path / "panel.json"), "reference"))


def test_the_watchers_catch_a_host_round_trip():
    # the two checks above would see a conversion to numpy or a copy to the host
    with pytest.raises(AssertionError, match="host round trip during encode: numpy"):
        with _StaysOnDevice("cpu"):
            torch.zeros(3).numpy()
    with pytest.raises(AssertionError, match="host round trip during encode: item"):
        with _StaysOnDevice("cpu"):
            torch.zeros(3).sum().item()
    with pytest.raises(AssertionError, match="produced a tensor on meta"):
        with _StaysOnDevice("cpu"):
            torch.zeros(3).to("meta")
    _, hits = _numpy_calls_during(lambda: np.zeros(3) + np.arange(3).sum())
    assert hits
