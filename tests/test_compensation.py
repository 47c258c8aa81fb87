"""Crosstalk pre-compensation: the circulant solve, the bounded problem, the kernels, and where it is used."""

from __future__ import annotations

import json

import numpy as np
import pytest

from lenticalib.core.errors import InputError
from lenticalib.core.files.imageio import read_image, write_image
from lenticalib.render.compose.compensation import Compensator, circulant_row, compensation_study

from .cli_support import one_error_line

N = 16


def _matrix(n=N, own=0.5, adjacent=0.2, second=0.04):
    row = np.full(n, 0.002)
    row[0], row[1], row[-1], row[2], row[-2] = own, adjacent, adjacent, second, second
    row /= row.sum()
    return row[(np.arange(n)[None, :] - np.arange(n)[:, None]) % n]


def _views(n=N, p=4000, seed=0):
    rng = np.random.default_rng(seed)
    base = rng.uniform(0.2, 0.8, (1, p))
    return np.clip(base + 0.1 * np.sin(2 * np.pi * np.arange(n)[:, None] * 2 / n + rng.uniform(0, 6, (1, p))),
                   0, 1).astype(np.float32)


def test_circulant_row_and_the_unconstrained_solve_inverts_the_mixing():
    m = _matrix()
    assert np.allclose(circulant_row(m), m[0])
    c = Compensator.from_matrix(m, regularisation=1e-6, iterations=0)
    solve = np.zeros(N)
    for o, w in zip(c.solve_offsets, c.solve_weights):
        solve[o % N] += w
    c_matrix = solve[(np.arange(N)[None, :] - np.arange(N)[:, None]) % N]
    assert np.allclose(m @ c_matrix, np.eye(N), atol=0.03)  # taps below TAP_FLOOR are dropped


def test_seen_views_match_the_intended_ones_where_no_clipping_is_needed():
    m = _matrix()
    views = np.full((N, 100), 0.5, np.float32) + 0.05 * np.sin(np.arange(N))[:, None].astype(np.float32)
    c = Compensator.from_matrix(m, regularisation=1e-6, iterations=0)
    sent = c.apply_linear(views)
    assert sent.min() > 0 and sent.max() < 1
    assert np.abs(c.seen(sent, m) - views).max() < 2e-3
    assert np.abs(c.seen(views, m) - views).max() > 0.01  # without it the views are visibly mixed


def test_projected_gradient_steps_lower_the_bounded_objective_and_stay_in_range():
    m = _matrix()
    views = _views()

    def objective(c, e):
        t = c.target(views)
        return np.sum((c.seen(e, m) - t) ** 2) + c.regularisation * np.sum((e - t) ** 2)

    values = []
    for iterations in (0, 1, 4):
        c = Compensator.from_matrix(m, iterations=iterations, black_lift=0.03)
        e = c.apply_linear(views)
        assert e.min() >= 0 and e.max() <= 1
        values.append(objective(c, e))
    assert values[0] > values[1] > values[2]


def test_uint8_kernel_matches_the_float_one_and_torch_matches_numba():
    torch = pytest.importorskip("torch")
    m = _matrix()
    rng = np.random.default_rng(3)
    views = rng.integers(0, 256, (N, 6, 7, 3), dtype=np.uint8)
    c = Compensator.from_matrix(m, black_lift=0.02)
    decoded = np.where(views / 255 <= 0.04045, views / 255 / 12.92, ((views / 255 + 0.055) / 1.055) ** 2.4)
    linear = c.apply_linear(decoded.reshape(N, -1).astype(np.float32))
    encoded = np.where(linear <= 0.0031308, 12.92 * linear, 1.055 * np.maximum(linear, 0) ** (1 / 2.4) - 0.055)
    out = c.apply(views).reshape(N, -1).astype(int)
    assert np.abs(out - np.rint(encoded * 255)).max() <= 1
    on_torch = c.apply_torch(torch.from_numpy(decoded.reshape(N, -1).astype(np.float32))).numpy()
    assert np.abs(on_torch - linear).max() < 1e-5


def test_compensation_brings_the_seen_views_closer_and_cuts_the_residual_crosstalk():
    m = _matrix()
    measured = _matrix(own=0.51, adjacent=0.195)  # a measurement is never exact
    study = compensation_study(Compensator.from_matrix(measured, black_lift=0.03), m, _views())
    assert study["mean_rms_with"] < 0.5 * study["mean_rms_without"]
    assert study["residual_crosstalk_with"] < 0.5 * study["residual_crosstalk_without"]


def test_bad_matrices_and_knobs_are_refused():
    with pytest.raises(InputError, match="N x N"):
        Compensator.from_matrix(np.ones((3, 4)))
    with pytest.raises(InputError, match="black lift"):
        Compensator.from_matrix(_matrix(), black_lift=0.7)
    with pytest.raises(InputError, match="expected 16 uint8 views"):
        Compensator.from_matrix(_matrix()).apply(np.zeros((8, 2, 2, 3), np.uint8))


def _crosstalk_file(path, n):
    m = _matrix(n)
    path.write_text(json.dumps({"format": "lenticalib.crosstalk", "format_version": 1, "views": n,
                                "matrix": m.tolist()}))
    return path


def test_encode_compensate_changes_the_raster_and_refuses_a_file_for_another_panel(tmp_path, cli):
    profile = {"views": 8, "slant": 0.19, "period": 7.4, "offset": 1.5, "reference_view": 4,
               "width": 96, "height": 54, "subpixel_order": "RGB"}
    (tmp_path / "p.json").write_text(json.dumps(profile))
    folder = tmp_path / "views"
    folder.mkdir()
    rng = np.random.default_rng(1)
    for i in range(8):
        write_image(folder / f"v{i}.png", rng.integers(40, 200, (27, 48, 3), dtype=np.uint8))
    encode = ["encode", "--profile", tmp_path / "p.json", "--views-dir", folder]
    code, _, err = cli(*encode, "-o", tmp_path / "a.png")
    assert code == 0, err
    good = _crosstalk_file(tmp_path / "x8.json", 8)
    code, out, err = cli(*encode, "-o", tmp_path / "b.png", "--compensate", good, "--black-lift", "0.02")
    assert code == 0, err
    assert "pre-compensation" in out
    assert not np.array_equal(read_image(tmp_path / "a.png"), read_image(tmp_path / "b.png"))
    bad = _crosstalk_file(tmp_path / "x16.json", 16)
    code, _, err = cli(*encode, "-o", tmp_path / "c.png", "--compensate", bad)
    assert code == 2
    assert "x16.json" in err and "is for 16 views, the profile has 8" in err and len(err.strip().splitlines()) == 1
    code, _, err = cli(*encode, "-o", tmp_path / "c.png", "--black-lift", "0.1")
    assert code == 2
    assert "--black-lift: is only used with --compensate" in one_error_line(err)
    assert not (tmp_path / "c.png").exists()
