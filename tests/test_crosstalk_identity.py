"""Crosstalk photos that do not follow the profile's routing (issue 45, rule 5): refused in one line,
measured with ``--force`` (and the file says so), a right set measured without a warning.

The sets are small (a 1280 x 720 panel photographed at 1500 x 1000, as in test_crosstalk.py, whose
right set this file shares through the session's ``capture_set``); the limits and the sets they were
measured on: docs/crosstalk.md, "Photos that do not follow the profile".
"""

from __future__ import annotations

import json

import pytest

from lenticalib.calib.crosstalk.checks import ROUTING_LIMITS
from lenticalib.calib.crosstalk.measure import measure_crosstalk
from lenticalib.calib.patterns.crosstalk_patterns import design_crosstalk_patterns
from lenticalib.core.errors import CaptureError
from lenticalib.sim.scene import random_scene

from .cli_support import refused, run_main

VIEWS = 32


def _scene(seed: int):
    return random_scene(seed, width=1280, height=720, resolution=(1500, 1000), subsamples=2, distance=620.0)


@pytest.fixture(scope="module")
def panel():
    """The panel photographed (test_crosstalk.py's) and the profile fitted to it (a fit's small errors)."""
    scene = _scene(31)
    truth = scene.truth_profile(VIEWS)
    return scene, truth.replace(offset=truth.offset + 0.05 * truth.period / VIEWS, period=truth.period * (1 + 2e-6))


@pytest.fixture(scope="module")
def right_set(capture_set, panel):
    scene, profile = panel
    return capture_set(scene, design_crosstalk_patterns(profile), raw=True)


@pytest.fixture(scope="module")
def other_panel_set(capture_set, panel):
    """The issue's case: crosstalk patterns drawn from the profile of another virtual panel (seed 1:
    another period, the opposite slant), photographed on this one."""
    scene, _ = panel
    return capture_set(scene, design_crosstalk_patterns(_scene(1).truth_profile(VIEWS)), raw=True)


def test_photos_of_another_panel_are_refused_in_one_line_and_measured_with_force(other_panel_set, tmp_path):
    out = tmp_path / "crosstalk.json"
    line = refused("crosstalk", "measure", other_panel_set, "-o", out, "--photos", "linear", source=other_panel_set)
    assert "do not follow the routing of the profile" in line and "--force" in line, line
    assert not out.exists()
    code, stdout, stderr = run_main("crosstalk", "measure", other_panel_set, "-o", out, "--photos", "linear", "--force")
    assert code == 0, stderr
    assert "lenticalib: warning: measured anyway (forced): the photos may not follow the routing" in stderr
    document = json.loads(out.read_text())
    assert document["provenance"]["forced"].startswith("measured with force (--force) although the photos do not "
                                                       "follow the routing")
    check = document["diagnostics"]["routing_check"]
    assert check["verdict"] == "refuse" and check["forced"] and check["reasons"]
    assert any(w.startswith("measured anyway (forced)") for w in document["warnings"])
    assert document["diagnostics"]["cone_residual_relative"] > ROUTING_LIMITS["cone_residual_relative"][1]


@pytest.mark.slow
def test_a_right_set_is_measured_without_a_warning(right_set, tmp_path):
    out = tmp_path / "crosstalk.json"
    code, stdout, stderr = run_main("crosstalk", "measure", right_set, "-o", out, "--photos", "linear")
    assert code == 0, stderr
    assert "warning" not in stderr, stderr
    document = json.loads(out.read_text())
    assert document["warnings"] == [] and "forced" not in document["provenance"]
    diagnostics = document["diagnostics"]
    check = diagnostics["routing_check"]
    assert (check["verdict"], check["reasons"], check["forced"]) == ("ok", [], False)
    for key, (warn, _) in ROUTING_LIMITS.items():  # the band check's quick fit and the measurement's own
        assert abs(check["judged"][key]) < warn / 2 and abs(diagnostics[key]) < warn / 2, (key, check)


@pytest.mark.slow
def test_a_profile_whose_period_and_slant_are_not_the_panel_s_is_refused_as_a_set_before_the_measurement(
        capture_set, panel, monkeypatch):
    """A period 0.1 % off and a slant 0.002 off: the cone fit follows both (its residual is that of a
    right set), but the bands drift across the panel, and from top to bottom, from where the profile
    drew them.  Refused as a set by the band check's quick fit, before the measurement's own work
    (no glare fitted), not by a photo (which would send the user to retake a right photo)."""
    import lenticalib.calib.crosstalk.measure as measure

    scene, profile = panel
    wrong = profile.replace(period=profile.period * 1.001, slant=profile.slant + 0.002)
    folder = capture_set(scene, design_crosstalk_patterns(wrong), raw=True)

    def measured(*args, **kwargs):
        raise AssertionError("the measurement's own work began")

    monkeypatch.setattr(measure.photometry, "fit_glare", measured)
    with pytest.raises(CaptureError) as refusal:
        measure_crosstalk(folder, photos="linear")
    assert refusal.value.source == str(folder)
    text = str(refusal.value)
    assert "\n" not in text and "a period not the panel's" in text and "a slant not the panel's" in text, text
