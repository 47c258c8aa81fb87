"""Crosstalk: patterns, the virtual panel's true M, the measurement against it, check, and the CLI."""

from __future__ import annotations

import json
import shutil

import numpy as np
import pytest

from lenticalib.calib.crosstalk.patterns import BAND_PATTERNS, design_crosstalk_patterns, lit_subpixels
from lenticalib.calib.patterns import design_patterns, read_manifest, read_pattern_folder, write_patterns
from lenticalib.cli import main
from lenticalib.errors import CaptureError, InputError
from lenticalib.render.routing import view_coordinate
from lenticalib.sim.scene import random_scene

VIEWS = 32


@pytest.fixture(scope="module")
def scene():
    return random_scene(31, width=1280, height=720, resolution=(1500, 1000), subsamples=2, distance=620.0)


@pytest.fixture(scope="module")
def profile(scene):
    truth = scene.truth_profile(VIEWS)
    # a fitted profile is never exact: 0.05 view of centring error and a slight period error
    return truth.replace(offset=truth.offset + 0.05 * truth.period / VIEWS, period=truth.period * (1 + 2e-6))


@pytest.fixture(scope="module")
def measured_set(tmp_path_factory, scene, profile):
    """A crosstalk capture set of the virtual panel (photographed once per test session) and its measurement."""
    from lenticalib.calib.crosstalk.measure import measure_crosstalk
    from lenticalib.sim.capture import simulate_capture_set

    folder = tmp_path_factory.mktemp("xt") / "set"
    write_patterns(folder, design_crosstalk_patterns(profile))
    simulate_capture_set(folder, scene, raw=True)  # 16-bit linear, as from a raw converter
    return folder, measure_crosstalk(folder, profile, photos="linear")


def test_band_patterns_light_one_view_wide_bands_that_sweep_across_the_panel(profile):
    pattern_set = design_crosstalk_patterns(profile)
    rows = np.arange(0, profile.height, 97)
    w = view_coordinate(profile, rows)
    xs = np.arange(profile.subpixels_per_row)
    for pattern in pattern_set.bands[:3]:
        lit = lit_subpixels(pattern_set, pattern, rows)
        centre = VIEWS / 2 + pattern.shift + VIEWS * (xs + 0.5) / (3 * pattern_set.sweep)
        d = np.mod(w - centre[None, :] + VIEWS / 2, VIEWS) - VIEWS / 2
        assert np.array_equal(lit, (d >= -0.5) & (d < 0.5))
        assert abs(lit.mean() - 1 / VIEWS) < 0.002  # one view in N
    halves = [lit_subpixels(pattern_set, p, rows) for p in pattern_set.group("half")]
    assert not np.any(halves[0] & halves[1]) and np.all(halves[0] | halves[1])
    assert len(pattern_set.bands) == BAND_PATTERNS and len(pattern_set.patterns) <= 14


def test_rendered_pattern_has_the_frame_and_full_white_bands(profile):
    from lenticalib.calib.patterns import frame_width

    pattern_set = design_crosstalk_patterns(profile)
    raster = pattern_set.render(pattern_set.bands[0])
    f = frame_width(profile.height)
    assert raster.shape == (profile.height, profile.width, 3)
    assert len(np.unique(raster[:f])) == 1 and raster[:f].max() > 0
    inside = raster[f:-f, f:-f]
    assert set(np.unique(inside)) == {0, 255}
    white = pattern_set.render(pattern_set.group("white")[0])
    assert white[f:-f, f:-f].min() == 255


def test_pattern_folder_round_trip_and_dispatch(tmp_path, profile):
    folder = tmp_path / "xt"
    write_patterns(folder, design_crosstalk_patterns(profile))
    again = read_pattern_folder(folder)
    assert again.set_id == design_crosstalk_patterns(profile).set_id
    with pytest.raises(InputError, match="crosstalk patterns, not calibration"):
        read_manifest(folder)
    data = json.loads((folder / "patterns.json").read_text())
    data["sweep_pixels"] = 100.0
    (folder / "patterns.json").write_text(json.dumps(data))
    with pytest.raises(InputError, match="did not draw"):
        read_pattern_folder(folder)


def test_true_matrix_is_a_circulant_mixing_matrix_matching_the_view_cone(scene, profile):
    from lenticalib.sim.crosstalk_truth import true_mixing_matrix, true_view_cone

    m = true_mixing_matrix(scene.optics, scene.eye, profile)
    assert m.shape == (VIEWS, VIEWS)
    assert np.allclose(m.sum(axis=1), 1.0)
    assert np.allclose(m, np.roll(np.roll(m, 1, axis=0), 1, axis=1))
    assert m[0, 0] == m.max() and abs(m[0, 1] - m[0, -1]) < 0.01  # own view brightest, symmetric neighbours
    cone = true_view_cone(scene.optics, scene.eye, profile, np.array([0.0, 1.0]))
    # the cone is the light of one view over white's: the matrix row is the same up to normalisation
    assert cone[1] / cone[0] == pytest.approx(m[0, 1] / m[0, 0], abs=0.01)


def test_measured_matrix_matches_the_truth_within_its_uncertainty(measured_set):
    folder, m = measured_set
    truth = np.asarray(json.loads((folder / "crosstalk-truth.json").read_text())["matrix"])
    sigma = m.row_sigma[(np.arange(VIEWS)[None, :] - np.arange(VIEWS)[:, None]) % VIEWS]
    err = m.matrix - truth
    assert np.abs(err).max() < 0.015
    assert abs(err[0, 0]) < 0.012
    assert np.all(np.abs(err) <= 3 * sigma + 1e-6)
    assert np.allclose(m.matrix.sum(axis=1), 1.0)
    assert np.isfinite(m.regions).all() and m.regions.max() - m.regions.min() < 0.2


def test_jpeg_photos_carry_their_unknown_tone_curve_in_the_uncertainty(tmp_path, scene, profile):
    """Camera JPEGs are decoded as sRGB; this camera's curve is 8 % off (power 0.925), and the reported
    sigma must cover what that does."""
    from lenticalib.calib.crosstalk.measure import measure_crosstalk
    from lenticalib.sim.capture import simulate_capture_set

    assert abs(scene.camera.tone_gamma - 1) > 0.05
    folder = tmp_path / "jpeg"
    write_patterns(folder, design_crosstalk_patterns(profile))
    simulate_capture_set(folder, scene)
    m = measure_crosstalk(folder, profile)
    truth = np.asarray(json.loads((folder / "crosstalk-truth.json").read_text())["matrix"])
    sigma = m.row_sigma[(np.arange(VIEWS)[None, :] - np.arange(VIEWS)[:, None]) % VIEWS]
    err = m.matrix - truth
    assert np.all(np.abs(err) <= 3 * sigma + 1e-6)
    assert abs(err[0, 0]) < 0.05


def test_measure_cli_writes_the_document_and_report_and_check_judges_it(measured_set, tmp_path, capsys):
    folder, _ = measured_set
    out, report = tmp_path / "crosstalk.json", tmp_path / "report"
    assert main(["crosstalk", "measure", str(folder), "-o", str(out), "--report", str(report), "--photos", "linear",
                 "--eye-separation-mm", "64", "--distance", "620", "--cone-angle", "40"]) == 0
    data = json.loads(out.read_text())
    assert len(data["matrix"]) == VIEWS and all(len(r) == VIEWS for r in data["matrix"])
    assert {"own_view_share", "adjacent_crosstalk", "non_adjacent_crosstalk", "eye_pair_crosstalk"} <= set(data["figures"])
    assert data["provenance"]["inputs"] and data["eye_separation_note"].startswith("64 mm")
    assert sorted(p.name for p in report.iterdir()) == ["compensation.png", "matrix.png", "photos.png", "uniformity.png",
                                                         "view-cone.png"]
    prediction = data["compensation_prediction"]
    assert prediction["mean_rms_with"] < prediction["mean_rms_without"]
    capsys.readouterr()
    adjacent = data["figures"]["adjacent_crosstalk"]["value"]
    assert main(["crosstalk", "check", str(out), "--max-adjacent", str(adjacent + 0.01)]) == 0
    assert capsys.readouterr().out.startswith("PASS")
    assert main(["crosstalk", "check", str(out), "--max-adjacent", f"{100 * (adjacent - 0.01):.3f}%",
                 "--max-eye-pair", "0"]) == 1
    lines = capsys.readouterr().out.strip().splitlines()
    assert len(lines) == 2 and all(line.startswith("FAIL") for line in lines)


def _copy_set(folder, tmp_path):
    target = tmp_path / "copy"
    shutil.copytree(folder, target)
    return target


def test_photo_of_another_pattern_is_named(measured_set, tmp_path, profile):
    from lenticalib.calib.crosstalk.measure import measure_crosstalk

    folder = _copy_set(measured_set[0], tmp_path)
    captures = folder / "captures"
    shutil.copy(captures / "band-05.png", captures / "band-02.png")
    with pytest.raises(CaptureError, match="shows the same pattern as band-02.png") as err:
        measure_crosstalk(folder, profile, photos="linear")
    assert "band-05.png" in str(err.value)
    shutil.copy(measured_set[0] / "captures" / "band-02.png", captures / "band-02.png")
    shutil.copy(captures / "half-0.png", captures / "band-07.png")
    with pytest.raises(CaptureError, match="does not show pattern band-07") as err:
        measure_crosstalk(folder, profile, photos="linear")
    assert "band-07.png" in str(err.value)


def test_bad_inputs_end_in_one_line(measured_set, tmp_path, capsys, profile):
    from lenticalib.profile import save_profile

    folder = _copy_set(measured_set[0], tmp_path)
    (folder / "captures" / "white.png").unlink()
    assert main(["crosstalk", "measure", str(folder), "-o", str(tmp_path / "x.json")]) == 2
    assert "white" in capsys.readouterr().err
    calibration = tmp_path / "cal"
    write_patterns(calibration, design_patterns(640, 360, VIEWS))
    assert main(["crosstalk", "measure", str(calibration), "-o", str(tmp_path / "x.json")]) == 2
    assert "calibration patterns" in capsys.readouterr().err
    other = tmp_path / "other.json"
    save_profile(profile.replace(offset=profile.offset + 1.0), other)
    assert main(["crosstalk", "measure", str(measured_set[0]), "--profile", str(other), "-o", str(tmp_path / "x.json")]) == 2
    assert "not the profile the crosstalk patterns were drawn from" in capsys.readouterr().err
    assert not (tmp_path / "x.json").exists()
    assert main(["crosstalk", "measure", str(measured_set[0]), "-o", str(tmp_path / "x.json"),
                 "--eye-separation", "40"]) == 2
    assert "--eye-separation" in capsys.readouterr().err
    assert main(["fit", str(measured_set[0]), "-o", str(tmp_path / "p.json")]) == 2
    assert "crosstalk patterns" in capsys.readouterr().err


def test_crosstalk_file_for_another_view_count_is_refused(tmp_path, capsys):
    from lenticalib.calib.crosstalk.result import read_crosstalk

    bad = tmp_path / "crosstalk.json"
    row = np.zeros(8)
    row[0], row[1], row[-1] = 0.6, 0.2, 0.2
    matrix = row[(np.arange(8)[None, :] - np.arange(8)[:, None]) % 8]
    bad.write_text(json.dumps({"format": "lenticalib.crosstalk", "format_version": 1, "views": 8,
                               "matrix": matrix.tolist()}))
    assert read_crosstalk(bad, views=8)["views"] == 8
    with pytest.raises(InputError, match="is for 8 views, the profile has 32"):
        read_crosstalk(bad, views=32)
    bad.write_text(json.dumps({"format": "lenticalib.crosstalk", "format_version": 1, "views": 8,
                               "matrix": (matrix * 2).tolist()}))
    with pytest.raises(InputError, match="rows must be shares"):
        read_crosstalk(bad)
    assert main(["crosstalk", "check", str(tmp_path / "missing.json"), "--max-adjacent", "0.1"]) == 2
    assert "missing.json" in capsys.readouterr().err


def test_glare_is_measured_outside_the_panel_and_removed():
    import cv2

    from lenticalib.calib.crosstalk.photometry import fit_glare, remove_glare

    h, w = 300, 400
    direct = np.zeros((h, w), np.float32)
    direct[80:220, 100:300] = 1.0
    sigma = 0.05 * w
    seen = (0.97 * direct + 0.03 * cv2.GaussianBlur(direct, (0, 0), sigma, borderType=cv2.BORDER_CONSTANT)).astype(np.float32)
    outside = np.ones((h, w), bool)
    outside[70:230, 90:310] = False
    glare = fit_glare(seen, outside)
    assert glare.fraction == pytest.approx(0.03, rel=0.1) and glare.sigma == pytest.approx(sigma, rel=0.01)
    cleaned = remove_glare(seen, glare)
    assert np.abs(cleaned - direct)[100:200, 120:280].max() < 0.003


def test_cone_fit_recovers_a_known_profile_and_sweep_from_synthetic_ratios():
    from lenticalib.calib.crosstalk import cone

    n, k = 32, 10
    rng = np.random.default_rng(4)
    rows, cols = np.mgrid[0:200, 0:300]
    rows, cols = rows.ravel(), cols.ravel()
    delta = 0.11 * cols + 0.01 * rows + 1e-4 * (cols - 150) ** 2 - 7.3  # views: a sweep through a perspective

    def profile(t):
        t = np.mod(t + n / 2, n) - n / 2
        return 0.002 + 0.45 * np.exp(-0.5 * (t / 0.7) ** 2)

    shifts = np.arange(k) * n / k
    gains = 1 + 0.03 * np.sin(np.arange(k))
    ratios = gains[None, :] * profile(delta[:, None] + shifts[None, :]) + rng.normal(0, 0.01, (rows.size, k))
    fit = cone.fit_cone(ratios, rows, cols, shifts, n, (200, 300))
    assert np.allclose(fit.gains / fit.gains.mean(), gains / gains.mean(), atol=0.01)
    assert np.abs(fit.delta(rows, cols) - delta).max() < 0.05
    grid, values, counts = cone.profile_for(fit, ratios, rows, cols, shifts)
    row = cone.values_at_integers(grid, values, counts, n)
    truth = profile(np.arange(n) - n * (np.arange(n) >= n / 2)) * gains.mean()
    assert np.abs(row - truth).max() < 0.006
