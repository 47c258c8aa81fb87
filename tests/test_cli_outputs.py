"""patterns, simulate and fit: options and output paths refused in one line before the work, and
all-or-nothing results (a failed run leaves nothing partial and earlier results intact).

The long work is replaced by a function that fails the test when reached, so every refusal is
shown to come before it.  (The fit's report, summary and figures are tested in test_calib.py,
with the fit of the bundled set.)
"""

import json
from pathlib import Path

import pytest

import lenticalib.calib.routing.fit as fit_module
import lenticalib.core.pattern_sets as pattern_sets_module
import lenticalib.sim.capture as capture_module
from lenticalib.calib.patterns.calibration_patterns import design_patterns
from lenticalib.core.errors import InputError
from lenticalib.core.pattern_sets import write_patterns
from lenticalib.sim.scene import random_scene

from .cli_support import refused
from .outputs_support import read_only  # noqa: F401 -- pytest fixture

FIXTURE = Path(__file__).resolve().parent.parent / "fixtures" / "capture-demo"


def _tree(folder: Path) -> dict:
    return {str(p.relative_to(folder)): (None if p.is_dir() else p.read_bytes()) for p in sorted(folder.rglob("*"))}


@pytest.fixture
def no_work(monkeypatch):
    """Make the long work of patterns, simulate and fit fail the test if it is reached."""
    def reached(*args, **kwargs):
        pytest.fail("the long work started before the options and outputs were checked")

    monkeypatch.setattr(fit_module, "fit_capture_set", reached)
    monkeypatch.setattr(pattern_sets_module, "write_patterns", reached)
    monkeypatch.setattr(capture_module, "simulate_capture_set", reached)


# ---------------------------------------------------------------------------------------------
# refusals before the work
# ---------------------------------------------------------------------------------------------

def test_patterns_refuses_options_and_outputs_before_work(tmp_path, no_work, read_only):
    (tmp_path / "file").write_text("not a folder")
    ro = read_only(tmp_path / "ro")
    cases = [
        (["-o", tmp_path / "file"], tmp_path / "file"),
        (["-o", ro / "pat"], ro),
        (["-o", tmp_path / "missing" / "pat"], tmp_path / "missing"),
        (["--views", 0, "-o", tmp_path / "p"], "--views"),
        (["--views", 1, "-o", tmp_path / "p"], "--views"),
        (["--views", 255, "-o", tmp_path / "p"], "--views"),
        (["--width", 0, "-o", tmp_path / "p"], "--width"),
        (["--width", -3840, "-o", tmp_path / "p"], "--width"),
        (["--height", 100000, "-o", tmp_path / "p"], "--height"),
    ]
    for argv, source in cases:
        refused("patterns", *argv, source=source)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["file", "ro"]
    assert list(ro.iterdir()) == []


def test_fit_refuses_options_and_outputs_before_the_fit(tmp_path, no_work, read_only):
    existing = tmp_path / "existing"
    existing.mkdir()
    (tmp_path / "file").write_text("x")
    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / "thesis.tex").write_text("keep me")
    ro = read_only(tmp_path / "ro")
    out = tmp_path / "p.json"
    cases = [
        (["-o", existing], existing),  # today: a whole fit, then a wrong hint and existing-report/ left
        (["-o", tmp_path / "missing" / "p.json"], tmp_path / "missing"),
        (["-o", ro / "p.json"], ro),
        (["-o", out, "--report", ro / "rep"], ro),
        (["-o", out, "--report", tmp_path / "file"], tmp_path / "file"),
        (["-o", out, "--report", tmp_path / "missing" / "rep"], tmp_path / "missing"),
        (["-o", out, "--report", mine], mine),  # not a report: never replaced
        (["-o", out, "--report", out], out),
        (["-o", out, "--views", 0], "--views"),  # today: silently ignored
        (["-o", out, "--views", 1], "--views"),
        (["-o", out, "--views", 255], "--views"),
    ]
    for argv, source in cases:
        refused("fit", FIXTURE, *argv, source=source)
    (tmp_path / "p-report").write_text("a file where the default report folder goes")
    line = refused("fit", FIXTURE, "-o", out, source=tmp_path / "p-report")
    assert "--report" in line
    assert sorted(p.name for p in tmp_path.iterdir()) == ["existing", "file", "mine", "p-report", "ro"]
    assert list(existing.iterdir()) == [] and _tree(mine) == {"thesis.tex": b"keep me"}


@pytest.fixture(scope="module")
def small_patterns(tmp_path_factory):
    """Patterns of a 640x360, 8-view panel (written once; copy before writing into it)."""
    directory = tmp_path_factory.mktemp("patterns") / "set"
    write_patterns(directory, design_patterns(640, 360, 8))
    return directory


def _copy(source: Path, destination: Path) -> Path:
    import shutil

    shutil.copytree(source, destination)
    return destination


def test_simulate_refuses_options_and_outputs_before_work(tmp_path, small_patterns, no_work, read_only):
    directory = _copy(small_patterns, tmp_path / "set")
    small = random_scene(9, width=640, height=360, resolution=(600, 400))
    (tmp_path / "small-scene.json").write_text(json.dumps(small.to_dict()))
    cases = [
        # today: simulated, then refused by the fit naming x1-0.jpg
        (["--resolution", "600x400"], "--resolution"),
        (["--resolution", "0x0"], "--resolution"),
        (["--resolution", "30000x3000"], "--resolution"),
        (["--scene", tmp_path / "small-scene.json"], tmp_path / "small-scene.json"),
        (["--seed", -1], "--seed"),
        (["--seed", 2 ** 64], "--seed"),
        (["--subsamples", 0], "--subsamples"),
        (["--jpeg-quality", 0], "--jpeg-quality"),
    ]
    for argv, source in cases:
        line = refused("simulate", directory, *argv, source=source)
        if "600x400" in argv:
            assert "1 megapixel" in line, line
    (directory / "captures").write_text("a file where the photos go")
    refused("simulate", directory, "--seed", 1, "--resolution", "1250x800", source=directory / "captures")
    (directory / "captures").unlink()
    ro = read_only(_copy(small_patterns, tmp_path / "ro"))
    refused("simulate", ro, "--seed", 1, "--resolution", "1250x800", source=ro)
    assert sorted(p.name for p in directory.iterdir()) == sorted(p.name for p in small_patterns.iterdir())


# ---------------------------------------------------------------------------------------------
# a run that fails half way leaves nothing of its own and the earlier results intact
# ---------------------------------------------------------------------------------------------

def _failing_after(monkeypatch, module, name, calls):
    """Make ``module.name`` fail like a full disk after ``calls`` successful calls."""
    real = getattr(module, name)
    count = []

    def wrapper(*args, **kwargs):
        if len(count) >= calls:
            raise InputError("cannot write output: No space left on device", source=str(args[0]),
                             hint="check free space and permissions")
        count.append(1)
        return real(*args, **kwargs)

    monkeypatch.setattr(module, name, wrapper)


@pytest.mark.parametrize("earlier", [False, True], ids=["fresh", "over-an-earlier-set"])
def test_patterns_failing_half_way_leaves_nothing(tmp_path, cli, monkeypatch, earlier):
    folder = tmp_path / "pat"
    if earlier:
        write_patterns(folder, design_patterns(640, 360, 8))
    before = _tree(tmp_path)
    _failing_after(monkeypatch, pattern_sets_module, "write_image", 5)  # as write_patterns calls it
    code, _, err = cli("patterns", "--width", 512, "--height", 256, "--views", 16, "-o", folder)
    assert code == 2 and len(err.strip().splitlines()) == 1 and "No space left" in err, err
    assert _tree(tmp_path) == before  # no half set, no mix of two sets, nothing hidden left


@pytest.mark.parametrize("earlier", [False, True], ids=["fresh", "over-an-earlier-simulation"])
def test_simulate_failing_half_way_leaves_nothing(tmp_path, small_patterns, earlier):
    directory = _copy(small_patterns, tmp_path / "set")
    if earlier:  # stands for an earlier simulation of the folder
        (directory / "captures").mkdir()
        for name in design_patterns(640, 360, 8).names:
            (directory / "captures" / f"{name}.jpg").write_bytes(f"earlier {name}".encode())
        (directory / "simulation.json").write_text('{"status": "complete"}\n')
        (directory / "truth.json").write_text('{"earlier": true}\n')
    broken = directory / "x1-0.png"  # the fourth pattern: three photos are taken before it
    broken.write_bytes(b"not a PNG any more")
    before = _tree(tmp_path)
    line = refused("simulate", directory, "--seed", 2, "--resolution", "1250x800", "--subsamples", 1, source=broken)
    assert "readable" in line, line
    assert _tree(tmp_path) == before  # today: a half set of new photos (and simulation.json "in progress")
