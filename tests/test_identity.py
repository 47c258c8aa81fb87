"""Identity travels with results (issue 45, rule 5; ``docs/identity.md``).

A crosstalk file records the panel it was measured for: ``encode``/``render --compensate`` with
the profile of another panel is refused in one line, and ``--force`` accepts it and says so in
the output's provenance.  Crosstalk patterns drawn from the fit of a virtual panel are
photographed by ``capture --camera sim`` on that virtual panel, which it names; a seed that
contradicts it, or a profile that names none, is refused.  A singular compensation without
regularisation is one error line.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from lenticalib.calib.patterns.calibration_patterns import design_patterns
from lenticalib.core.identity import profile_identity, virtual_panel_record
from lenticalib.core.files.imageio import write_image
from lenticalib.core.pattern_sets import write_patterns
from lenticalib.core.profile import PanelProfile, load_profile, make_provenance, save_profile
from lenticalib.sim.capture import TRUTH_NAME, write_simulation_record, write_truth
from lenticalib.sim.scene import random_scene

from .cli_support import one_error_line, refused, run_main

PANEL = {"views": 8, "slant": 0.19, "period": 7.4, "offset": 1.5, "reference_view": 4.0, "width": 96, "height": 54,
         "subpixel_order": "RGB"}
OTHER = {**PANEL, "period": 7.9}  # another panel (or another fit) of the same size and view count


def _mixing(row) -> list[list[float]]:
    n = len(row)
    return [[row[(j - i) % n] for j in range(n)] for i in range(n)]


def _crosstalk_file(path, row, profile=None):
    document = {"format": "lenticalib.crosstalk", "format_version": 1, "views": len(row), "matrix": _mixing(row)}
    if profile is not None:
        document["profile"] = profile
    path.write_text(json.dumps(document))
    return path


@pytest.fixture
def encode_files(tmp_path):
    for name, constants in (("panel", PANEL), ("other", OTHER)):
        (tmp_path / f"{name}.json").write_text(json.dumps(constants))
    views = tmp_path / "views"
    views.mkdir()
    rng = np.random.default_rng(1)
    for i in range(8):
        write_image(views / f"v{i}.png", rng.integers(40, 200, (27, 48, 3), dtype=np.uint8))
    crosstalk = _crosstalk_file(tmp_path / "crosstalk.json", [0.6, 0.2, 0, 0, 0, 0, 0, 0.2], PANEL)
    return tmp_path, views, crosstalk


def test_encode_refuses_a_compensation_of_another_panel_and_force_says_so(encode_files):
    tmp_path, views, crosstalk = encode_files
    encode = ["encode", "--views-dir", views, "--compensate", crosstalk]
    line = refused(*encode, "--profile", tmp_path / "other.json", "-o", tmp_path / "a.png", source=crosstalk)
    panel, other = (profile_identity(load_profile(tmp_path / f"{n}.json")) for n in ("panel", "other"))
    assert f"was measured for panel {panel}, the profile is panel {other}" in line and "--force" in line, line
    assert not (tmp_path / "a.png").exists()

    code, out, err = run_main(*encode, "--profile", tmp_path / "other.json", "-o", tmp_path / "a.png", "--force",
                              "--json")
    assert code == 0, err
    record = json.loads(out)["provenance"]
    assert record["profile_id"] == other
    assert record["compensation"] == {"crosstalk_file": str(crosstalk), "made_for": panel, "used_with": other,
                                      "match": False, "forced": True}
    assert f"{crosstalk} was made for panel {panel}, used with panel {other} as forced" in err  # and a warning

    code, out, err = run_main(*encode, "--profile", tmp_path / "panel.json", "-o", tmp_path / "b.png", "--json")
    assert code == 0 and not err, err
    assert json.loads(out)["provenance"]["compensation"]["forced"] is False


def test_render_refuses_a_compensation_of_another_panel_before_the_avatar(encode_files):
    tmp_path, _, crosstalk = encode_files
    line = refused("render", tmp_path / "no-avatar.ply", "--profile", tmp_path / "other.json", "--compensate",
                   crosstalk, "-o", tmp_path / "frame.png", source=crosstalk)
    assert "was measured for panel" in line


def test_render_with_force_warns_that_the_compensation_is_of_another_panel(encode_files):
    from lenticalib.render.avatar.gaussians import Gaussians
    from lenticalib.render.avatar.ply import save_ply

    tmp_path, _, crosstalk = encode_files
    rng = np.random.default_rng(2)
    n = 40
    save_ply(tmp_path / "blob.ply", Gaussians(
        means=rng.normal(0.0, 0.3, (n, 3)).astype(np.float32), quats=np.tile([1.0, 0, 0, 0], (n, 1)).astype(np.float32),
        scales=np.full((n, 3), 0.1, np.float32), opacities=np.full(n, 0.9, np.float32),
        sh=rng.normal(0.0, 0.5, (n, 1, 3)).astype(np.float32)))
    code, _, err = run_main("render", tmp_path / "blob.ply", "--profile", tmp_path / "other.json", "--compensate",
                            crosstalk, "--force", "--view-size", "48x27", "-o", tmp_path / "frame.png")
    assert code == 0, err
    assert f"{crosstalk} was made for panel" in err and "as forced" in err


def test_an_edited_crosstalk_identity_is_refused(encode_files):
    tmp_path, views, crosstalk = encode_files
    document = json.loads(crosstalk.read_text())
    document["profile_id"] = profile_identity(PanelProfile(**OTHER))  # says another panel than its constants
    crosstalk.write_text(json.dumps(document))
    line = refused("encode", "--views-dir", views, "--compensate", crosstalk, "--profile", tmp_path / "panel.json",
                   "-o", tmp_path / "a.png", source=crosstalk)
    assert "an edited file" in line


def test_a_singular_compensation_without_regularisation_is_one_error_line(encode_files):
    tmp_path, views, _ = encode_files
    singular = _crosstalk_file(tmp_path / "singular.json", [0.5, 0.5, 0, 0, 0, 0, 0, 0])  # M v = 0 for (1,-1,1,...)
    line = refused("encode", "--views-dir", views, "--profile", tmp_path / "panel.json", "--compensate", singular,
                   "--regularisation", "0", "-o", tmp_path / "a.png", source="--regularisation")
    assert "singular" in line and "use a positive regularisation" in line
    assert not (tmp_path / "a.png").exists()
    code, _, err = run_main("encode", "--views-dir", views, "--profile", tmp_path / "panel.json", "--compensate",
                            singular, "-o", tmp_path / "a.png")  # the default regularisation inverts it
    assert code == 0 and not err, err


# --- capture --camera sim photographs the virtual panel of the folder's own fit ----------------------

SEED, W, H, VIEWS = 3, 640, 360, 8


@pytest.fixture
def fitted_on_seed_3(tmp_path):
    """A calibration folder photographed by ``--camera sim:3`` as far as its records go (its
    ``simulation.json`` and ``truth.json``; the photos are not needed here) and a profile fitted from
    it: the truth a little off, with the provenance ``lenticalib fit`` writes for such a folder."""
    cal = tmp_path / "cal"
    patterns = design_patterns(W, H, VIEWS)
    write_patterns(cal, patterns)
    scene = random_scene(SEED, width=W, height=H, resolution=(1200, 900), subsamples=1)
    _, constants = write_truth(cal, scene, patterns)
    write_simulation_record(cal, scene, patterns, "complete", [], {"file": TRUTH_NAME, **constants})
    truth = load_profile(cal / TRUTH_NAME)
    fitted = truth.replace(period=truth.period * 1.0004, offset=truth.offset + 0.01,
                           provenance=make_provenance("fit", virtual_panel=virtual_panel_record(cal)))
    save_profile(fitted, tmp_path / "profile.json")
    return tmp_path, truth


def test_capture_sim_photographs_the_virtual_panel_the_profile_was_fitted_on(fitted_on_seed_3):
    tmp_path, truth = fitted_on_seed_3
    xt = tmp_path / "xt"
    assert run_main("crosstalk", "patterns", "--profile", tmp_path / "profile.json", "-o", xt)[0] == 0
    capture = ["capture", xt, "--display", "none", "--resolution", "1200x900", "--subsamples", "1"]
    line = refused(*capture, "--camera", "sim:1", source=xt / "patterns.json")
    assert "virtual panel seed 3; sim:1 would photograph another panel" in line
    assert not (xt / "captures").exists()
    line = refused(*capture, "--camera", "sim", "--layout", "RGB", source=xt / "patterns.json")  # seed 3's is BGR
    assert "seed 3 now draws a virtual panel of truth" in line

    code, out, err = run_main(*capture, "--camera", "sim")
    assert code == 0, err
    named = [row for row in out.splitlines() if "virtual panel: seed" in row]
    assert len(named) == 1 and named[0].startswith("camera: virtual panel: seed 3 (the panel the patterns' profile "
                                                   "was fitted on"), out
    assert f"period {truth.period:.2f}" in named[0] and profile_identity(truth) in named[0]
    assert profile_identity(load_profile(xt / TRUTH_NAME)) == profile_identity(truth)  # the same panel photographed


def test_fit_refuses_a_moved_right_set_of_another_virtual_panel(tmp_path):
    """``fit cal --moved-right cal2``: the two sets must show the same panel; photos that the
    virtual camera took of two different panels (seeds 3 and 4) are refused before any fit."""
    patterns = design_patterns(W, H, VIEWS)
    grey = np.full((900, 1200, 3), 90, np.uint8)
    for name, seed in (("cal", 3), ("cal2", 4)):
        folder = tmp_path / name
        write_patterns(folder, patterns)
        (folder / "captures").mkdir()
        for pattern in patterns.patterns:
            write_image(folder / "captures" / f"{pattern.name}.png", grey)
        scene = random_scene(seed, width=W, height=H, resolution=(1200, 900), subsamples=1)
        _, constants = write_truth(folder, scene, patterns)
        write_simulation_record(folder, scene, patterns, "complete", [], {"file": TRUTH_NAME, **constants})
    line = refused("fit", tmp_path / "cal", "--moved-right", tmp_path / "cal2", "-o", tmp_path / "p.json",
                   source=tmp_path / "cal2")
    assert "holds photos of virtual panel seed 4" in line and "another panel" in line


def test_capture_sim_refuses_a_profile_that_names_no_virtual_panel(fitted_on_seed_3):
    tmp_path, truth = fitted_on_seed_3
    save_profile(truth.replace(provenance=None), tmp_path / "plain.json")  # a real panel's, as far as it says
    xt = tmp_path / "xt"
    assert run_main("crosstalk", "patterns", "--profile", tmp_path / "plain.json", "-o", xt)[0] == 0
    code, out, err = run_main("capture", xt, "--camera", "sim", "--display", "none", "--resolution", "1200x900")
    assert code == 2, (out, err)
    assert "cannot tell which panel to photograph" in one_error_line(err, xt / "patterns.json")


def test_capture_sim_resumes_a_calibration_folder_on_its_own_virtual_panel(tmp_path):
    """``capture cal --camera sim`` (no seed) in a folder the virtual camera photographed with seed 3
    names and photographs panel 3 again, not the default seed 1."""
    cal = tmp_path / "cal"
    patterns = design_patterns(W, H, VIEWS)
    write_patterns(cal, patterns)
    scene = random_scene(SEED, width=W, height=H, resolution=(1200, 900), subsamples=1)
    _, constants = write_truth(cal, scene, patterns)
    write_simulation_record(cal, scene, patterns, "in progress", [], {"file": TRUTH_NAME, **constants})
    from lenticalib.calib.capture.cameras import make_camera

    camera = make_camera("sim", folder=cal, resolution=(1200, 900), subsamples=1)
    camera.open()
    assert camera.seed == SEED and camera.settings()[0].startswith(
        "virtual panel: seed 3 (the panel of this folder's earlier photos")
    assert make_camera("sim:5", folder=cal, resolution=(1200, 900)).seed == 5  # a seed given is a seed given
