"""The standard 3DGS PLY: round trips, the raw <-> activated transforms, the f_rest order, refusals."""

import numpy as np
import pytest

from lenticalib.core.errors import InputError
from lenticalib.render.avatar.gaussians import Gaussians
from lenticalib.render.avatar.ply import load_ply, save_ply

import plyfile  # noqa: E402  (a dependency of lenticalib)

BASE = ["x", "y", "z", "nx", "ny", "nz", "f_dc_0", "f_dc_1", "f_dc_2"]
TAIL = ["opacity", "scale_0", "scale_1", "scale_2", "rot_0", "rot_1", "rot_2", "rot_3"]


def _gaussians(degree, n=7, seed=0):
    rng = np.random.default_rng(seed)
    q = rng.normal(size=(n, 4))
    f = np.float32
    return Gaussians(rng.normal(size=(n, 3)).astype(f), (q / np.linalg.norm(q, axis=1, keepdims=True)).astype(f),
                     np.exp(rng.normal(-4, 1, (n, 3))).astype(f), rng.uniform(0.01, 0.99, n).astype(f),
                     rng.normal(size=(n, (degree + 1) ** 2, 3)).astype(f))


def _raw_rows(n=3, rest=9, seed=1, drop=(), extra=(), dtype="<f4"):
    """A structured array in the 3DGS vertex layout (raw values), optionally without / with properties."""
    names = BASE + [f"f_rest_{i}" for i in range(rest)] + TAIL
    names = [name for name in names if name not in drop] + list(extra)
    rng = np.random.default_rng(seed)
    rows = np.empty(n, dtype=[(name, dtype) for name in names])
    for name in names:
        rows[name] = rng.normal(size=n)
    return rows


def _write(path, rows, text=False, byte_order="<", element="vertex"):
    plyfile.PlyData([plyfile.PlyElement.describe(rows, element)], text=text, byte_order=byte_order).write(str(path))
    return path


@pytest.mark.parametrize("degree", [0, 1, 2, 3])
def test_round_trip_keeps_the_activated_values(tmp_path, degree):
    g = _gaussians(degree)
    save_ply(tmp_path / "a.ply", g)
    back = load_ply(tmp_path / "a.ply")
    assert back.sh.shape == g.sh.shape and back.sh_degree == degree
    for field in ("means", "quats", "sh"):
        np.testing.assert_array_equal(getattr(back, field), getattr(g, field))
    np.testing.assert_allclose(back.scales, g.scales, rtol=1e-6)
    np.testing.assert_allclose(back.opacities, g.opacities, rtol=1e-6)
    assert all(getattr(back, f).dtype == np.float32 for f in ("means", "quats", "scales", "opacities", "sh"))


def test_saved_file_has_the_standard_header(tmp_path):
    save_ply(tmp_path / "a.ply", _gaussians(1))
    ply = plyfile.PlyData.read(str(tmp_path / "a.ply"))
    assert ply.header.splitlines()[1] == "format binary_little_endian 1.0"
    names = [p.name for p in ply["vertex"].properties]
    assert names == ["x", "y", "z", "f_dc_0", "f_dc_1", "f_dc_2"] + [f"f_rest_{i}" for i in range(9)] + TAIL
    assert all(p.val_dtype == "f4" for p in ply["vertex"].properties)


def test_raw_values_are_activated_and_f_rest_is_channel_major(tmp_path):
    rows = _raw_rows(n=2, rest=9)
    rows["rot_0"], rows["rot_1"], rows["rot_2"], rows["rot_3"] = [2, 0], [0, 0], [0, 3], [0, 4]
    g = load_ply(_write(tmp_path / "a.ply", rows))
    np.testing.assert_allclose(g.opacities, 1 / (1 + np.exp(-rows["opacity"].astype(np.float64))), rtol=1e-6)
    np.testing.assert_allclose(g.scales[:, 1], np.exp(rows["scale_1"].astype(np.float64)), rtol=1e-6)
    np.testing.assert_allclose(g.quats, [[1, 0, 0, 0], [0, 0, 0.6, 0.8]], atol=1e-7)
    np.testing.assert_array_equal(g.sh[:, 0, 2], rows["f_dc_2"])
    # degree 1: f_rest_0..2 are R's three coefficients, f_rest_3..5 G's, f_rest_6..8 B's
    for channel in range(3):
        for k in range(3):
            np.testing.assert_array_equal(g.sh[:, 1 + k, channel], rows[f"f_rest_{3 * channel + k}"])


def test_saturated_opacities_are_written_finite(tmp_path):
    g = _gaussians(0, n=3)
    g.opacities[:] = [0.0, 1.0, 0.5]
    save_ply(tmp_path / "a.ply", g)
    raw = plyfile.PlyData.read(str(tmp_path / "a.ply"))["vertex"]["opacity"]
    assert np.isfinite(raw).all()
    np.testing.assert_allclose(load_ply(tmp_path / "a.ply").opacities, [0.0, 1.0, 0.5], atol=1e-6)


@pytest.mark.parametrize("encoding", ["ascii", "big-endian", "float64", "extras"])
def test_other_encodings_and_extra_properties_are_read(tmp_path, encoding):
    rows = _raw_rows(n=4, rest=24, dtype="<f8" if encoding == "float64" else "<f4",
                     extra=("filter_3D", "red") if encoding == "extras" else ())
    path = _write(tmp_path / "a.ply", rows, text=encoding == "ascii", byte_order=">" if encoding == "big-endian" else "<")
    g = load_ply(path)
    assert g.count == 4 and g.sh_degree == 2
    np.testing.assert_allclose(g.means[:, 0], rows["x"], rtol=1e-6)
    np.testing.assert_allclose(g.sh[:, 8, 2], rows["f_rest_23"], rtol=1e-6)


def _truncated(path):
    save_ply(path, _gaussians(3, n=10))
    data = path.read_bytes()
    path.write_bytes(data[:-100])


def _raw(path, rows, **kw):
    _write(path, rows, **kw)


@pytest.mark.parametrize("make, expected", [
    (lambda p: _raw(p, _raw_rows(drop=("opacity",))), "'opacity' is missing"),
    (lambda p: _raw(p, _raw_rows(drop=("rot_3",))), "'rot_3' is missing"),
    (lambda p: _raw(p, _raw_rows(rest=7)), "'f_rest_*' has 7 coefficients"),
    (lambda p: _raw(p, _raw_rows(rest=8, extra=("f_rest_9",))), "'f_rest_8' is missing"),
    (lambda p: _raw(p, _raw_rows(n=0)), "no rows"),
    (lambda p: _raw(p, _raw_rows(), element="splat"), "no 'vertex' element"),
    (lambda p: p.write_bytes(b""), "empty file"),
    (lambda p: p.write_text("solid cube\nfacet normal 0 0 1\n"), "not a readable PLY"),
    (_truncated, "not a readable PLY"),
    (lambda p: p.mkdir(), "is a folder"),
    (lambda p: None, "no such file"),
])
def test_malformed_files_are_one_line_input_errors(tmp_path, make, expected):
    path = tmp_path / "avatar.ply"
    make(path)
    with pytest.raises(InputError, match=expected.replace("*", r"\*")) as err:
        load_ply(path)
    assert err.value.source == str(path)
    assert "\n" not in str(err.value)


@pytest.mark.parametrize("field, value, expected", [
    ("scale_1", np.nan, "'scale_1' is not finite"),
    ("f_rest_4", np.inf, "'f_rest_4' is not finite"),
    ("x", -np.inf, "'x' is not finite"),
    ("scale_2", 200.0, "'scale_\\*' is out of float32 range"),  # exp(200) overflows float32
    ("scale_0", -200.0, "'scale_\\*' is out of float32 range"),  # exp(-200) is 0 in float32
])
def test_non_finite_values_are_refused_naming_the_property(tmp_path, field, value, expected):
    rows = _raw_rows(n=5)
    rows[field][3] = value
    with pytest.raises(InputError, match=expected):
        load_ply(_write(tmp_path / "a.ply", rows))


def test_values_beyond_float32_are_refused(tmp_path):
    rows = _raw_rows(n=3, dtype="<f8")
    rows["f_dc_1"][1] = 1e300
    with pytest.raises(InputError, match="'f_dc_1' is not finite in float32"):
        load_ply(_write(tmp_path / "a.ply", rows))


def test_a_zero_length_quaternion_is_refused(tmp_path):
    rows = _raw_rows(n=5)
    for name in ("rot_0", "rot_1", "rot_2", "rot_3"):
        rows[name][2] = 0.0
    with pytest.raises(InputError, match="'rot_0..3' is a zero-length quaternion in row 2"):
        load_ply(_write(tmp_path / "a.ply", rows))


def test_a_list_property_is_refused(tmp_path):
    rows = _raw_rows(n=2, drop=("x",))
    listed = np.empty(2, dtype=[(n, rows.dtype[n]) for n in rows.dtype.names] + [("x", "O")])
    for name in rows.dtype.names:
        listed[name] = rows[name]
    listed["x"] = [np.zeros(2, "f4"), np.zeros(2, "f4")]
    with pytest.raises(InputError, match="'x' is not a numeric scalar"):
        load_ply(_write(tmp_path / "a.ply", listed))


@pytest.mark.parametrize("change, expected", [
    (lambda g: Gaussians(g.means[:0], g.quats[:0], g.scales[:0], g.opacities[:0], g.sh[:0]), "no Gaussians"),
    (lambda g: g.opacities.__setitem__(0, 1.5), "opacities must lie in"),
    (lambda g: g.scales.__setitem__((1, 2), 0.0), "scales must be > 0"),
    (lambda g: g.quats.__setitem__(1, 0.0), "zero-length quaternion"),
    (lambda g: g.means.__setitem__((0, 1), np.nan), "means has non-finite"),
])
def test_save_refuses_what_load_could_not_read_back(tmp_path, change, expected):
    g = _gaussians(1)
    g = change(g) or g
    with pytest.raises(InputError, match=expected):
        save_ply(tmp_path / "a.ply", g)
    assert not (tmp_path / "a.ply").exists()


def test_save_replaces_atomically_and_refuses_a_missing_folder(tmp_path):
    save_ply(tmp_path / "a.ply", _gaussians(0, n=3))
    save_ply(tmp_path / "a.ply", _gaussians(2, n=4))
    assert load_ply(tmp_path / "a.ply").count == 4
    assert [p.name for p in tmp_path.iterdir()] == ["a.ply"]  # no temporary left behind
    with pytest.raises(InputError, match="output folder does not exist"):
        save_ply(tmp_path / "missing" / "a.ply", _gaussians(0))
