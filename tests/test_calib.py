"""Calibration: the test patterns, the fit of the bundled capture set and of a fresh simulated one,
the ``fit`` CLI end to end, every failure mode of a capture set, and the untrustworthy gate.

The bundled set ``fixtures/capture-demo`` is fitted once per session (through the CLI, which
also gives the end-to-end test its output).  Copies of the set never include
``simulation.json``: the fit must work from ``patterns.json`` and the photos alone.
"""

import contextlib
import hashlib
import json
import math
import shutil
import types
from pathlib import Path

import cv2
import numpy as np
import pytest

import lenticalib.calib.routing.fit as fit_module
import lenticalib.cli.shared.progress as progress_module
from lenticalib.calib.routing.compare import compare_profiles
from lenticalib.calib.patterns.calibration_patterns import design_patterns, read_manifest
from lenticalib.core.errors import InputError
from lenticalib.core.pattern_sets import write_patterns
from lenticalib.core.profile import load_profile

from .cli_support import one_error_line, run_main

FIXTURE = Path(__file__).resolve().parent.parent / "fixtures" / "capture-demo"
PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
REPORT_FILES = ("panel.png", "view-map.png", "residual.png", "summary.json")

# accuracy every fit of a good capture set must reach (views, over every subpixel of the panel)
MAX_RMS, MAX_WORST, MAX_CENTRING = 0.05, 0.15, 0.25
MAX_SIGMAS = 3.0


# ---------------------------------------------------------------------------------------------
# helpers
# ---------------------------------------------------------------------------------------------

def _copy_capture_set(destination: Path) -> Path:
    """patterns.json + captures/ + truth.json of the bundled set (never simulation.json)."""
    destination.mkdir(parents=True)
    shutil.copy2(FIXTURE / "patterns.json", destination / "patterns.json")
    shutil.copy2(FIXTURE / "truth.json", destination / "truth.json")
    shutil.copytree(FIXTURE / "captures", destination / "captures")
    return destination


def _circular(d: float, period: float) -> float:
    return (d + period / 2) % period - period / 2


def _check_accuracy(fitted, truth):
    diff = compare_profiles(fitted, truth)
    assert diff.rms <= MAX_RMS, diff
    assert diff.worst <= MAX_WORST, diff
    assert abs(diff.centring) <= MAX_CENTRING, diff
    assert diff.order_match, (fitted.subpixel_order, truth.subpixel_order)
    return diff


def _check_constants_within_uncertainty(fitted, truth):
    unc = fitted.uncertainty
    assert unc is not None
    for key in ("period", "slant", "offset"):
        sigma = unc[key]
        assert math.isfinite(sigma) and sigma > 0, (key, sigma)
        d = getattr(fitted, key) - getattr(truth, key)
        if key == "offset":
            d = _circular(d, truth.period)
        assert abs(d) <= MAX_SIGMAS * sigma, (f"{key}: fitted {getattr(fitted, key)!r}, true "
                                              f"{getattr(truth, key)!r}: off by {d:.3g} = "
                                              f"{abs(d) / sigma:.2f} sigma (sigma {sigma:.3g})")


def _srgb_encode(linear):
    """IEC 61966-2-1, written out here independently of lenticalib."""
    linear = np.clip(linear, 0.0, 1.0)
    return np.where(linear <= 0.0031308, 12.92 * linear, 1.055 * linear ** (1 / 2.4) - 0.055)


def _expected_pattern(entry: dict, width: int, height: int, frame: int, frame_level: float) -> np.ndarray:
    """RGB float (height, width, 3) in 0..255: 0.5 + 0.45 cos(2 pi (c + 0.5) / T + theta), sRGB
    encoded; c = 3 x + RGB slot of the channel for axis x, the row for axis y; unlit channels 0;
    the outer ``frame`` pixels on every side all channels at ``frame_level`` (linear)."""
    theta = 2 * math.pi * entry["step"] / entry["steps"]
    out = np.zeros((height, width, 3))
    for ci, channel in enumerate("RGB"):
        if channel not in entry["channels"]:
            continue
        if entry["axis"] == "x":
            coordinate = (3 * np.arange(width) + ci)[None, :]
        else:
            coordinate = np.arange(height)[:, None]
        linear = 0.5 + 0.45 * np.cos(2 * math.pi * (coordinate + 0.5) / entry["period"] + theta)
        out[:, :, ci] = 255.0 * _srgb_encode(linear)
    level = 255.0 * _srgb_encode(np.float64(frame_level))
    out[:frame] = out[-frame:] = level
    out[:, :frame] = out[:, -frame:] = level
    return out


def _read_png_rgb(path: Path) -> np.ndarray:
    image = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    assert image is not None, path
    assert image.dtype == np.uint8 and image.ndim == 3 and image.shape[2] == 3, (path, image.dtype, image.shape)
    return image[:, :, ::-1]


def _check_pngs(directory: Path, names=None):
    """Every (or the named) pattern PNG in ``directory`` decodes to the formula within 1 LSB."""
    manifest = json.loads((directory / "patterns.json").read_text())
    width, height = manifest["width"], manifest["height"]
    checked = 0
    for entry in manifest["patterns"]:
        if names is not None and entry["name"] not in names:
            continue
        image = _read_png_rgb(directory / entry["file"])
        assert image.shape == (height, width, 3), entry["file"]
        expected = _expected_pattern(entry, width, height, manifest["frame_pixels"], manifest["frame_level"])
        error = np.abs(image.astype(np.float64) - expected)
        assert error.max() <= 1.0, (entry["name"], float(error.max()))
        checked += 1
    return checked


def _write_jpeg(path: Path, image: np.ndarray) -> None:
    assert cv2.imwrite(str(path), image, [cv2.IMWRITE_JPEG_QUALITY, 92]), path


def _read_bgr(path: Path) -> np.ndarray:
    image = cv2.imread(str(path), cv2.IMREAD_COLOR)
    assert image is not None, path
    return image


class _RecordingBar:
    """Stands in for the CLI's progress bar: its total (given when opened, or set before the first
    update: a total set later fails the test) and every update."""

    bars: list = []

    def __init__(self, total, desc):
        self.total, self.desc, self.updates = total, desc, []
        _RecordingBar.bars.append(self)

    def update(self, message=None):
        self.updates.append(message)

    def set_total(self, total):
        assert not self.updates, "the total came after the first update"
        self.total = total


@contextlib.contextmanager
def _recording_progress_bar(total, desc):
    yield _RecordingBar(total, desc)


def _fit_cli_recording(argv):
    """Run ``lenticalib fit ...`` in-process, returning (code, stdout, stderr, FitResult, progress bar)."""
    results = []
    real = fit_module.fit_capture_set

    def recording(*args, **kwargs):
        result = real(*args, **kwargs)
        results.append(result)
        return result

    _RecordingBar.bars = []
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(fit_module, "fit_capture_set", recording)
        mp.setattr(progress_module, "progress_bar", _recording_progress_bar)
        code, out, err = run_main(*argv)
    assert len(results) == 1, (code, err)
    assert len(_RecordingBar.bars) == 1
    return code, out, err, results[0], _RecordingBar.bars[0]


# ---------------------------------------------------------------------------------------------
# session fixtures: the bundled set fitted once, a 1920x1080 pattern set, a fresh simulated set
# ---------------------------------------------------------------------------------------------

@pytest.fixture(scope="session")
def demo_fit(tmp_path_factory):
    """The bundled capture set, copied and fitted once through ``lenticalib fit DIR -o OUT/profile.json``."""
    root = tmp_path_factory.mktemp("demo")
    directory = _copy_capture_set(root / "capture-demo")
    out = root / "out"
    out.mkdir()
    profile_path = out / "profile.json"
    code, stdout, stderr, result, bar = _fit_cli_recording(["fit", directory, "-o", profile_path])
    return types.SimpleNamespace(directory=directory, out=out, profile_path=profile_path, code=code,
                                 stdout=stdout, stderr=stderr, result=result, progress=bar,
                                 truth=load_profile(directory / "truth.json"))


@pytest.fixture(scope="session")
def patterns_1080(tmp_path_factory):
    """The pattern PNGs and manifest of a 1920x1080, 32-view panel."""
    directory = tmp_path_factory.mktemp("patterns-1080") / "set"
    write_patterns(directory, design_patterns(1920, 1080, 32))
    return directory


@pytest.fixture(scope="session")
def sim_fit(tmp_path_factory, capture_set):
    """A fresh simulated capture set (BGR, negative slant, small camera) of a 1920x1080, 32-view
    panel and its fit."""
    from lenticalib.sim.scene import random_scene

    # one ray per sensor pixel: the fit reads fringe phases over the whole panel, which the 3x3
    # rays of the default only anti-alias (the same checks, a third of the simulation's time)
    scene = random_scene(7, width=1920, height=1080, resolution=(1500, 1000), period=22.5, slant=-0.3,
                         order="BGR", jpeg_quality=85, subsamples=1)
    directory = capture_set(scene)
    # the fit sees what a user has: the manifest and the photos (no simulation.json, no truth)
    fit_dir = tmp_path_factory.mktemp("sim-fit") / "set"
    fit_dir.mkdir()
    shutil.copy2(directory / "patterns.json", fit_dir / "patterns.json")
    shutil.copytree(directory / "captures", fit_dir / "captures")
    result = fit_module.fit_capture_set(fit_dir)
    return types.SimpleNamespace(directory=directory, result=result, truth=load_profile(directory / "truth.json"))


# ---------------------------------------------------------------------------------------------
# 1. patterns
# ---------------------------------------------------------------------------------------------

@pytest.mark.parametrize("width, height, views", [(3840, 2160, 32), (1920, 1080, 45), (640, 360, 8),
                                                  (64, 64, 2), (7680, 4320, 100)])
def test_pattern_set_design(width, height, views):
    ps = design_patterns(width, height, views)
    assert len(ps.patterns) <= 24
    assert len(set(ps.names)) == len(ps.names)
    sub = 3 * width
    expected = {"x0": ("x", 1.25 * sub, 3, "G"), "x1": ("x", sub / 12, 3, "G"),
                "x2": ("x", min(96.0, sub / 24), 3, "G"), "y0": ("y", 1.25 * height, 3, "G"),
                "y1": ("y", height / 16, 3, "G"), "f16": ("x", 16.0, 3, "G"), "f22": ("x", 22.0, 3, "G"),
                "order-r": ("x", 16.0, 1, "R"), "order-b": ("x", 16.0, 1, "B")}
    assert sorted({p.group for p in ps.patterns}) == sorted(expected)
    for group, (axis, period, steps, channels) in expected.items():
        members = ps.group(group)
        assert len(members) == steps, group
        for k, p in enumerate(members):
            assert (p.axis, p.channels, p.steps, p.step) == (axis, channels, steps, k), p
            assert p.period == pytest.approx(period, rel=1e-12), p
            assert p.file == f"{p.name}.png"
            assert p.theta == pytest.approx(2 * math.pi * k / steps)
    # the id changes with anything that changes the patterns
    assert ps.set_id == design_patterns(width, height, views).set_id
    assert ps.set_id != design_patterns(width, height + 2, views).set_id
    assert ps.set_id != design_patterns(width, height, views + 1).set_id


def test_pattern_design_rejects_bad_sizes():
    for args in ((63, 100, 8), (100, 10, 8), (640, 360, 1), (640, 360, 255)):
        with pytest.raises(InputError):
            design_patterns(*args)


def test_pattern_pngs_decode_to_the_formula(patterns_1080):
    manifest = json.loads((patterns_1080 / "patterns.json").read_text())
    groups = {}
    for entry in manifest["patterns"]:
        groups.setdefault(entry["group"], []).append(entry["name"])
    # the first and last step of every group (a few patterns of each)
    names = {n for members in groups.values() for n in (members[0], members[-1])}
    assert _check_pngs(patterns_1080, names) == len(names) == 16
    # the registration frame: 1/40 of the height (27 of 1080 rows) on every side, identical in every pattern
    f = manifest["frame_pixels"]
    assert f == 27
    inside = (slice(f, -f), slice(f, -f))
    # inside it the x-patterns of the green group light only the middle slot (G); order-r only R, order-b only B
    f16 = _read_png_rgb(patterns_1080 / "f16-0.png")
    assert f16[inside][:, :, 0].max() == 0 and f16[inside][:, :, 2].max() == 0 and f16[:, :, 1].max() > 200
    assert _read_png_rgb(patterns_1080 / "order-r.png")[inside][:, :, 1:].max() == 0
    assert _read_png_rgb(patterns_1080 / "order-b.png")[inside][:, :, :2].max() == 0
    ring = np.ones((1080, 1920), bool)
    ring[inside] = False
    frames = {_read_png_rgb(patterns_1080 / e["file"])[ring].tobytes() for e in manifest["patterns"][::4]}
    assert len(frames) == 1
    # every PNG the manifest lists exists, and nothing else was written
    assert sorted(p.name for p in patterns_1080.iterdir()) == sorted(
        [e["file"] for e in manifest["patterns"]] + ["patterns.json"])


def test_read_manifest_round_trip(patterns_1080):
    ps = read_manifest(patterns_1080)
    assert ps == design_patterns(1920, 1080, 32)
    data = json.loads((patterns_1080 / "patterns.json").read_text())
    assert data == ps.to_dict()
    assert data["set_id"] == ps.set_id and (data["width"], data["height"], data["views"]) == (1920, 1080, 32)
    assert [e["name"] for e in data["patterns"]] == ps.names
    # the bundled fixture's manifest reads back to the pattern set it names
    demo = read_manifest(FIXTURE)
    assert demo.set_id == json.loads((FIXTURE / "patterns.json").read_text())["set_id"]
    assert (demo.width, demo.height, demo.views) == (3840, 2160, 32)


@pytest.mark.parametrize("edit", ["pattern period", "panel width", "set id", "pattern dropped"])
def test_edited_manifest_is_rejected(tmp_path, patterns_1080, edit):
    data = json.loads((patterns_1080 / "patterns.json").read_text())
    if edit == "pattern period":
        index = [e["name"] for e in data["patterns"]].index("f16-1")
        data["patterns"][index]["period"] = 17.0
    elif edit == "panel width":
        data["width"] = 1921
    elif edit == "set id":
        data["set_id"] = "0123456789abcdef"
    else:
        del data["patterns"][-1]
    directory = tmp_path / "edited"
    directory.mkdir()
    (directory / "patterns.json").write_text(json.dumps(data, indent=2))
    with pytest.raises(InputError) as info:
        read_manifest(directory)
    assert str(directory / "patterns.json") in str(info.value)


def test_patterns_cli_writes_pngs_and_manifest(tmp_path, cli):
    directory = tmp_path / "pat"
    code, out, err = cli("patterns", "--width", 640, "--height", 360, "--views", 8, "-o", directory)
    assert code == 0, err
    assert err == ""
    manifest = json.loads((directory / "patterns.json").read_text())
    assert (manifest["width"], manifest["height"], manifest["views"]) == (640, 360, 8)
    ps = read_manifest(directory)
    assert ps == design_patterns(640, 360, 8) and manifest["set_id"] == ps.set_id
    assert ps.set_id in out
    assert sorted(p.name for p in directory.iterdir()) == sorted([p.file for p in ps.patterns] + ["patterns.json"])
    assert _check_pngs(directory) == len(ps.patterns) <= 24
    # bad sizes end in one line, nothing written
    code, _, err = cli("patterns", "--width", 32, "--height", 360, "-o", tmp_path / "small")
    assert code == 2
    one_error_line(err)
    assert not (tmp_path / "small").exists()


# ---------------------------------------------------------------------------------------------
# 2. the fit of the bundled capture set
# ---------------------------------------------------------------------------------------------

def test_demo_fit_matches_the_truth(demo_fit):
    result, truth = demo_fit.result, demo_fit.truth
    assert result.trusted, result.problems
    assert result.problems == []
    _check_accuracy(result.profile, truth)
    p = result.profile
    assert (p.width, p.height, p.views, p.reference_view) == (truth.width, truth.height, truth.views,
                                                              truth.views / 2)
    assert p.subpixel_order == truth.subpixel_order == "RGB"
    q = result.quality
    assert q["block_residual_rms_views"] <= fit_module.MAX_BLOCK_RESIDUAL_RMS
    assert q["predicted_error_worst_views"] <= fit_module.MAX_PREDICTED_ERROR
    assert q["coherence"] >= fit_module.MIN_COHERENCE
    assert q["subpixel_order"]["margin"] >= fit_module.MIN_ORDER_MARGIN


def test_fit_progress_counts_to_its_total(demo_fit):
    """The fit's progress bar is given, before the first update, the number of updates the fit
    then makes: one per photo read, one per stage (it once stood at 100 % with a third of the fit
    to go)."""
    bar = demo_fit.progress
    patterns = read_manifest(demo_fit.directory)
    assert bar.total == len(bar.updates) == fit_module.progress_steps(patterns)
    reads = [u for u in bar.updates if u.startswith("reading ")]
    assert sorted(reads) == sorted(f"reading {n}.jpg" for n in patterns.names)  # every photo once
    assert [u for u in bar.updates if not u.startswith("reading ")] == list(fit_module.STAGES)


def test_demo_fit_constants_within_three_sigma(demo_fit):
    _check_constants_within_uncertainty(demo_fit.result.profile, demo_fit.truth)


def test_demo_fit_provenance_records_photos_and_pattern_set(demo_fit):
    directory = demo_fit.directory
    manifest = json.loads((directory / "patterns.json").read_text())
    for profile in (demo_fit.result.profile, load_profile(demo_fit.profile_path)):
        prov = profile.provenance
        assert prov["pattern_set"] == manifest["set_id"]
        inputs = {Path(e["path"]).resolve(): e.get("sha256") for e in prov["inputs"]}
        expected = [directory / "patterns.json"] + [directory / "captures" / f"{e['name']}.jpg"
                                                    for e in manifest["patterns"]]
        assert set(inputs) == {p.resolve() for p in expected}
        for path in expected:
            assert inputs[path.resolve()] == hashlib.sha256(path.read_bytes()).hexdigest(), path
        assert "simulation.json" not in json.dumps(prov)


# ---------------------------------------------------------------------------------------------
# 3. the fit CLI end to end
# ---------------------------------------------------------------------------------------------

def test_fit_cli_writes_profile_and_report(demo_fit, cli):
    assert demo_fit.code == 0, demo_fit.stderr
    assert demo_fit.stderr == ""
    assert f"wrote {demo_fit.profile_path}" in demo_fit.stdout
    profile = load_profile(demo_fit.profile_path)
    assert profile == demo_fit.result.profile
    assert profile.uncertainty == pytest.approx(demo_fit.result.profile.uncertainty)
    report = demo_fit.out / "profile-report"
    assert sorted(p.name for p in report.iterdir()) == sorted(REPORT_FILES)
    for name in REPORT_FILES[:3]:
        data = (report / name).read_bytes()
        assert data.startswith(PNG_SIGNATURE) and len(data) > 1000, name
    summary = json.loads((report / "summary.json").read_text())
    assert summary["trusted"] is True and summary["problems"] == []
    assert summary["profile"]["period"] == profile.period
    # nothing else next to the profile (no temporary files left)
    assert sorted(p.name for p in demo_fit.out.iterdir()) == ["profile-report", "profile.json"]

    code, out, err = cli("profile", "compare", demo_fit.profile_path, demo_fit.directory / "truth.json",
                         "--json")
    assert code == 0, err
    data = json.loads(out)
    diff = compare_profiles(profile, demo_fit.truth)
    for key in ("rms", "worst", "centring"):
        assert data[key] == pytest.approx(getattr(diff, key), abs=1e-12), key
    assert data["order_match"] is True
    assert data["rms"] <= MAX_RMS and data["worst"] <= MAX_WORST and abs(data["centring"]) <= MAX_CENTRING


def _png_size(path: Path) -> tuple[int, int]:
    data = path.read_bytes()
    assert data.startswith(PNG_SIGNATURE) and data[12:16] == b"IHDR", path
    return int.from_bytes(data[16:20], "big"), int.from_bytes(data[20:24], "big")


def test_report_figures_are_readable_sizes(demo_fit):
    from lenticalib.calib.routing.report import FIGURE_SIZES, REPORT_FILES as FILES

    report = demo_fit.out / "profile-report"
    assert sorted(FILES) == sorted(REPORT_FILES)
    for name, size in FIGURE_SIZES.items():
        assert _png_size(report / name) == size, name
        assert size[0] >= 1600, name
        # a figure, not a blank canvas: many distinct colours
        image = cv2.imread(str(report / name))
        assert len(np.unique(image.reshape(-1, 3), axis=0)) > 500, name


def _stated_rms(record) -> list[str]:
    """Every "RMS <number>" a figure's titles, labels and legends state."""
    import re

    texts = [record["title"]] + [t for ax in record["axes"] for t in (ax["title"], ax["xlabel"], ax["ylabel"],
                                                                     *ax["texts"], *ax["legend"])]
    return re.findall(r"RMS (\d+\.\d+)", " ".join(texts))


def test_report_figures_state_the_summary_residual(demo_fit):
    """view-map.png and residual.png show the residual the summary reports (issue 19: the view map said
    0.427 views RMS, a second definition, beside a headline of 0.037)."""
    from lenticalib.core.figures import read_figure_record

    report = demo_fit.out / "profile-report"
    quality = json.loads((report / "summary.json").read_text())["quality"]
    view_map = read_figure_record(report / "view-map.png")
    for key in ("block_residual_rms_views", "block_residual_worst_views", "pixel_residual_rms_views"):
        assert view_map["numbers"][key] == quality[key], key
    assert read_figure_record(report / "residual.png")["numbers"]["block_residual_rms_views"] == \
        quality["block_residual_rms_views"]
    for name in ("view-map.png", "residual.png"):
        stated = _stated_rms(read_figure_record(report / name))
        assert f"{quality['block_residual_rms_views']:.3f}" in stated, name
        # no RMS the summary does not hold
        assert set(stated) <= {f"{quality[k]:.3f}" for k in ("block_residual_rms_views",
                                                              "pixel_residual_rms_views")}, (name, stated)
    # the bottom panel, the headline, is the summary's block map: its weighted RMS is the stated one
    block = demo_fit.result.maps["block_residual_map"]
    assert np.nanmax(np.abs(block)) == pytest.approx(quality["block_residual_worst_views"], rel=1e-9)


def test_view_map_crop_resolves_subpixels_and_its_samples_lie_on_the_fit(demo_fit):
    """The crop is drawn at a zoom where one subpixel is several screen pixels wide, and the measured
    samples in it agree with the fitted w of the subpixel they lie on (no aliased checkerboard)."""
    from lenticalib.calib.routing.model import wrap
    from lenticalib.core.figures import read_figure_record
    from lenticalib.core.routing import view_coordinate

    numbers = read_figure_record(demo_fit.out / "profile-report" / "view-map.png")["numbers"]
    assert numbers["subpixel_width_figure_pixels"] >= 5.0
    x0, y0, cw, ch = numbers["crop_pixels"]
    samples, profile = demo_fit.result.maps["samples"], demo_fit.result.profile
    n = profile.views
    inside = (samples.x >= 3 * x0) & (samples.x < 3 * (x0 + cw)) & (samples.y >= y0) & (samples.y < y0 + ch)
    assert numbers["crop_samples"] == int(inside.sum()) >= 20
    xs, ys = np.floor(samples.x[inside]).astype(int), np.floor(samples.y[inside]).astype(int)
    w = view_coordinate(profile, ys)[np.arange(ys.size), xs]  # the profile's w of each sample's subpixel
    # the subpixel's w is at its left edge, the sample anywhere in it: a subpixel spans N / period views
    measured = samples.psi[inside] * n + n / 2
    diff = np.abs(wrap((measured - w) / n)) * n
    assert np.median(diff) < n / profile.period, np.median(diff)


def test_every_fit_report_figure_has_a_title_and_axes_with_units(demo_fit):
    from lenticalib.calib.routing.report import FIGURE_SIZES
    from lenticalib.core.figures import read_figure_record

    for name in FIGURE_SIZES:
        record = read_figure_record(demo_fit.out / "profile-report" / name)
        assert record["title"], name
        for ax in record["axes"]:
            labels = [label for label in (ax["xlabel"], ax["ylabel"]) if label]
            assert labels, (name, ax)  # a plot or a colour bar
            assert all("(" in label and label.rstrip().endswith(")") for label in labels), (name, labels)


def _fit_returning(monkeypatch, result):
    """``lenticalib fit`` with the (slow) fit replaced by an earlier result."""
    monkeypatch.setattr(fit_module, "fit_capture_set", lambda *args, **kwargs: result)


def test_summary_json_is_what_fit_json_prints(demo_fit, tmp_path, cli, monkeypatch):
    _fit_returning(monkeypatch, demo_fit.result)
    code, out, err = cli("fit", demo_fit.directory, "-o", tmp_path / "p.json", "--json")
    assert code == 0, err
    text = (tmp_path / "p-report" / "summary.json").read_text()
    assert json.loads(out) == json.loads(text)
    assert text.count('"quality"') == 1  # once, not also inside the profile's provenance
    summary = json.loads(text)
    assert summary["output"] == str(tmp_path / "p.json") and summary["report"] == str(tmp_path / "p-report")
    assert summary["quality"]["block_residual_rms_views"] == demo_fit.result.quality["block_residual_rms_views"]
    assert summary["profile"]["period"] == load_profile(tmp_path / "p.json").period
    # the report of the session's plain run says the same
    plain = json.loads((demo_fit.out / "profile-report" / "summary.json").read_text())
    assert plain["quality"] == summary["quality"] and plain["output"] == str(demo_fit.profile_path)


@pytest.mark.parametrize("earlier", [False, True], ids=["fresh", "over-earlier-results"])
def test_fit_failing_in_the_report_leaves_nothing(demo_fit, tmp_path, cli, monkeypatch, earlier):
    import lenticalib.calib.routing.report as report_module

    _fit_returning(monkeypatch, demo_fit.result)
    out = tmp_path / "out"
    out.mkdir()
    if earlier:
        _old_profile(out / "profile.json")
        shutil.copytree(demo_fit.out / "profile-report", out / "profile-report")
    before = {str(p.relative_to(out)): p.read_bytes() if p.is_file() else None for p in sorted(out.rglob("*"))}

    def full_disk(fig, result):
        raise InputError("cannot write output: No space left on device", source="residual.png")

    monkeypatch.setattr(report_module, "_residual_figure", full_disk)  # after two figures were written
    code, _, err = cli("fit", demo_fit.directory, "-o", out / "profile.json")
    assert code == 2, err
    assert "No space left" in one_error_line(err)
    after = {str(p.relative_to(out)): p.read_bytes() if p.is_file() else None for p in sorted(out.rglob("*"))}
    assert after == before  # no profile, no half report, nothing hidden left; earlier results intact


# ---------------------------------------------------------------------------------------------
# 4. a fresh simulated capture set: BGR, negative slant, small camera
# ---------------------------------------------------------------------------------------------

@pytest.mark.slow
def test_simulated_bgr_set_fits_to_the_truth(sim_fit):
    result, truth = sim_fit.result, sim_fit.truth
    assert truth.subpixel_order == "BGR" and truth.slant == pytest.approx(-0.3)
    assert truth.period == pytest.approx(22.5)
    assert result.trusted, result.problems
    assert result.profile.subpixel_order == "BGR"
    _check_accuracy(result.profile, truth)
    _check_constants_within_uncertainty(result.profile, truth)
    assert result.profile.provenance["pattern_set"] == read_manifest(sim_fit.directory).set_id


# ---------------------------------------------------------------------------------------------
# 5. failure modes: one error line naming the photo (or the folder), exit 2, no profile written
# ---------------------------------------------------------------------------------------------

def _missing_photo(d):
    (d / "captures" / "y1-2.jpg").unlink()
    return d / "captures", ["y1-2"]


def _extra_photo(d):
    shutil.copy2(d / "captures" / "x0-0.jpg", d / "captures" / "extra.jpg")
    return d / "captures" / "extra.jpg", []


def _misnamed_photo(d):
    (d / "captures" / "x1-0.jpg").rename(d / "captures" / "x1_0.jpg")
    return d / "captures" / "x1_0.jpg", []


def _same_group_wrong_pattern(d):
    shutil.copy2(d / "captures" / "x1-2.jpg", d / "captures" / "x1-1.jpg")
    # x1-1.jpg and x1-2.jpg are now the same photo: either may be named
    return [d / "captures" / "x1-1.jpg", d / "captures" / "x1-2.jpg"], []


def _y_photo_for_x2(d):
    shutil.copy2(d / "captures" / "y1-1.jpg", d / "captures" / "x2-1.jpg")
    return d / "captures" / "x2-1.jpg", []


def _grey_frames(d):
    for path in sorted((d / "captures").iterdir()):
        _write_jpeg(path, np.full_like(_read_bgr(path), 128))
    return d / "captures", []


def _overexposed(d):
    path = d / "captures" / "y1-1.jpg"
    _write_jpeg(path, np.clip(_read_bgr(path).astype(np.float32) * 4.0, 0, 255).astype(np.uint8))
    return path, ["overexposed"]


def _black(d):
    path = d / "captures" / "f22-0.jpg"
    _write_jpeg(path, np.zeros_like(_read_bgr(path)))
    return path, []


def _another_pattern_set(d):
    (d / "patterns.json").write_text(json.dumps(design_patterns(1920, 1080, 32).to_dict(), indent=2) + "\n")
    return [d / "captures", d / "patterns.json"], []


def _resized(name):
    def mutate(d):
        path = d / "captures" / f"{name}.jpg"
        _write_jpeg(path, cv2.resize(_read_bgr(path), (1500, 1000), interpolation=cv2.INTER_AREA))
        return path, ["1500x1000"]
    return mutate


def _too_small_set(d):
    """Every photo below captures.MIN_PHOTO_PIXELS: named by the set's first photo (x0-0)."""
    for path in sorted((d / "captures").iterdir()):
        _write_jpeg(path, cv2.resize(_read_bgr(path), (1000, 667), interpolation=cv2.INTER_AREA))
    return d / "captures" / "x0-0.jpg", ["1000x667", "megapixel"]


def _one_small_photo(d):
    path = d / "captures" / "y1-1.jpg"
    _write_jpeg(path, cv2.resize(_read_bgr(path), (900, 600), interpolation=cv2.INTER_AREA))
    return path, ["900x600", "megapixel"]


def _notes_file(d):
    (d / "captures" / "notes.txt").write_text("exposure 1/60 s, ISO 100\n")
    return d / "captures" / "notes.txt", []


def _corrupt_jpeg(d):
    path = d / "captures" / "y0-2.jpg"
    path.write_bytes(np.random.default_rng(5).integers(0, 256, 40_000, dtype=np.uint8).tobytes())
    return path, []


def _no_captures_folder(d):
    shutil.rmtree(d / "captures")
    return d / "captures", []


def _no_manifest(d):
    (d / "patterns.json").unlink()
    return d / "patterns.json", []


FAILURES = {
    "missing-photo": (_missing_photo, False),
    "extra-photo": (_extra_photo, True),
    "misnamed-photo": (_misnamed_photo, False),
    "wrong-pattern-x1-2-as-x1-1": (_same_group_wrong_pattern, True),
    "y-photo-as-x2-1": (_y_photo_for_x2, False),
    "panel-not-found-grey-frames": (_grey_frames, True),
    "overexposed": (_overexposed, False),
    "black-photo": (_black, True),
    "another-pattern-set": (_another_pattern_set, False),
    "different-size-x0-0": (_resized("x0-0"), True),
    "different-size-x1-1": (_resized("x1-1"), False),
    "too-small-set": (_too_small_set, True),
    "one-small-photo-y1-1": (_one_small_photo, False),
    "non-photo-file": (_notes_file, True),
    "corrupt-jpeg": (_corrupt_jpeg, False),
    "no-captures-folder": (_no_captures_folder, True),
    "no-manifest": (_no_manifest, False),
}
SLOW_FAILURES = {"another-pattern-set", "y-photo-as-x2-1"}  # the two slowest refusals (several seconds each)


def _old_profile(path: Path) -> bytes:
    """A valid profile at the -o path before the run; returns its bytes."""
    shutil.copy2(FIXTURE / "truth.json", path)
    return path.read_bytes()


def _listing(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.iterdir() if not p.name.endswith("-report"))


def _check_nothing_written(out: Path, profile_path: Path, old: bytes | None, before: list[str]):
    if old is None:
        assert not profile_path.exists(), "a profile was written"
    else:
        assert profile_path.read_bytes() == old, "the existing profile was changed"
    assert _listing(out) == before  # no temporary file left behind either


@pytest.mark.parametrize("case", [pytest.param(c, marks=pytest.mark.slow) if c in SLOW_FAILURES else c for c in FAILURES])
def test_fit_failure_mode(case, tmp_path, cli):
    mutate, existing = FAILURES[case]
    directory = _copy_capture_set(tmp_path / "set")
    named, fragments = mutate(directory)
    out = tmp_path / "out"
    out.mkdir()
    profile_path = out / "profile.json"
    old = _old_profile(profile_path) if existing else None
    before = _listing(out)
    code, _, err = cli("fit", directory, "-o", profile_path)
    assert code == 2, (code, err)
    line = one_error_line(err)
    sources = named if isinstance(named, list) else [named]
    # the message starts with the file or folder at fault: "lenticalib: error: SOURCE: ..."
    assert any(line.startswith(f"lenticalib: error: {s}: ") for s in sources), (
        f"expected the message to name {' or '.join(map(str, sources))}: {line}")
    for fragment in fragments:
        assert fragment in line, line
    _check_nothing_written(out, profile_path, old, before)


def _blur(names, sigma):
    def mutate(d):
        for name in names(d):
            path = d / "captures" / f"{name}.jpg"
            _write_jpeg(path, cv2.GaussianBlur(_read_bgr(path), (0, 0), sigma))
        return d
    return mutate


@pytest.mark.parametrize("case, mutate, culprit", [
    ("one-fine-photo", _blur(lambda d: ["f16-1"], 30.0), "f16-1.jpg"),
    ("every-photo", _blur(lambda d: [p.stem for p in (d / "captures").iterdir()], 30.0), None),
], ids=["f16-1", "every-photo"])
@pytest.mark.slow
def test_blurred_photos_never_give_a_silent_profile(case, mutate, culprit, tmp_path, cli):
    """A heavily blurred photo ends in an error (exit 2) or an untrusted fit (exit 3), no profile."""
    directory = _copy_capture_set(tmp_path / "set")
    mutate(directory)
    out = tmp_path / "out"
    out.mkdir()
    profile_path = out / "profile.json"
    old = _old_profile(profile_path) if case == "every-photo" else None
    before = _listing(out)
    code, _, err = cli("fit", directory, "-o", profile_path)
    if code == 0 and profile_path.exists() and profile_path.read_bytes() != old:
        diff = compare_profiles(load_profile(profile_path), load_profile(directory / "truth.json"))
        pytest.fail(f"blurred photos ({case}) were accepted: exit 0, profile written ({diff})")
    assert code in (2, 3), (code, err)
    line = one_error_line(err)
    if code == 2:
        source = directory / "captures" / culprit if culprit else directory / "captures"
        assert line.startswith(f"lenticalib: error: {source}: "), line
    else:
        assert "--force" in line and "not trustworthy" in line, line
    _check_nothing_written(out, profile_path, old, before)


# ---------------------------------------------------------------------------------------------
# 6. the untrustworthy gate and --force
# ---------------------------------------------------------------------------------------------

@pytest.mark.slow
def test_untrustworthy_fit_needs_force(demo_fit, tmp_path, cli, monkeypatch):
    """The gate trips on the real fit (its limit lowered); ``--force`` is then judged on that same
    untrusted result, handed to the second run instead of fitting the set again."""
    monkeypatch.setattr(fit_module, "MAX_PREDICTED_ERROR", 1e-9)
    real, results = fit_module.fit_capture_set, []

    def fitted_once(*args, **kwargs):
        results.append(results[0] if results else real(*args, **kwargs))
        return results[-1]

    monkeypatch.setattr(fit_module, "fit_capture_set", fitted_once)
    out = tmp_path / "out"
    out.mkdir()
    profile_path = out / "profile.json"
    code, _, err = cli("fit", demo_fit.directory, "-o", profile_path)
    assert code == 3, (code, err)
    line = one_error_line(err)
    assert "--force" in line and "not trustworthy" in line, line
    assert f"report in {out / 'profile-report'}" in line, line  # kept, and the user is told where
    assert not profile_path.exists()
    summary = json.loads((out / "profile-report" / "summary.json").read_text())
    assert summary["trusted"] is False and summary["output"] is None

    code, _, err = cli("fit", demo_fit.directory, "-o", profile_path, "--force")
    assert code == 0, err
    assert len(results) == 2 and results[0].trusted is False
    assert "not trustworthy" in err and "lenticalib: error" not in err
    profile = load_profile(profile_path)
    assert profile == demo_fit.result.profile  # the same fit, only the gate differs


@pytest.mark.slow
def test_very_noisy_photos_are_never_blamed_on_camera_motion(capture_set):
    """High-ISO noise alone (250 e- full well, 14 e- read noise) must not trip a capture check: the
    single-fringe coordinates are smoothed before unwrapping and the motion check has a confidence.
    The fit runs to the end and judges itself; it may call itself untrusted, never the camera moved."""
    from lenticalib.sim.scene import random_scene

    scene = random_scene(12, width=1920, height=1080, resolution=(1400, 934), subsamples=1,
                         full_well=250.0, read_noise=14.0)
    result = fit_module.fit_capture_set(capture_set(scene, views=32))
    assert not any("moved" in w for w in result.warnings)
    assert result.profile.subpixel_order == scene.optics.subpixel_order
