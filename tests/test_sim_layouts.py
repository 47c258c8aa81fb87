"""The virtual panel with subpixel layouts: truth vs ray tracing, the renderer's physics, scene JSON, CLI."""

import json

import numpy as np
import pytest

from lenticalib.core.errors import InputError
from lenticalib.core.profile import load_profile
from lenticalib.core.routing import view_coordinate
from lenticalib.sim import Scene, random_scene, view_coordinate_truth
from lenticalib.sim.layouts import NAMED_LAYOUTS, resolve_layout
from lenticalib.sim.panel_light import render_radiance

from .cli_support import one_error_line

N = 32


def _circular(d, n=N):
    return (np.asarray(d) + n / 2) % n - n / 2


def _true_centres(layout, slant, xs, ys):
    """Channel centres straight from the layout's definition: pixel (x, y), channel c at
    (x + 0.5 + dx, y + 0.5 + dy) pixels, as raster coordinates (subpixels, rows)."""
    cells = np.asarray(layout.cells)  # (cells, 3, 2)
    cell = layout.cell_of(xs // 3, ys)
    d = cells[cell, xs % 3]
    return 3.0 * (xs // 3 + 0.5 + d[..., 0]), ys + 0.5 + d[..., 1]


# 1. The truth profile of a cell panel routes every slot by its true position -------------------------
@pytest.mark.parametrize("name", sorted(NAMED_LAYOUTS))
@pytest.mark.parametrize("slant", [0.27, -0.19])
def test_cell_truth_profile_matches_ray_traced_view_coordinate_at_true_centres(name, slant):
    layout = NAMED_LAYOUTS[name]
    scene = random_scene(4, width=640, height=360, resolution=(640, 480), slant=slant, layout=layout)
    profile = scene.truth_profile(N)
    assert profile.subpixel_layout == layout and profile.subpixel_order == "RGB"
    rows = np.r_[np.arange(0, 360, 7), 359]
    cols = np.r_[np.arange(0, 3 * 640, 5), 3 * 640 - 1]
    w = view_coordinate(profile, rows)[:, cols]
    X, Y = _true_centres(layout, scene.optics.slant, cols[None, :], rows[:, None])
    w_star = view_coordinate_truth(scene.optics, scene.eye, X, Y, N)
    assert np.abs(_circular(w - w_star)).max() < 1e-6
    # and the layout matters: the stripe routing of the same constants is off by views
    stripe = view_coordinate(profile.replace(subpixel_layout=None), rows)[:, cols]
    assert np.abs(_circular(stripe - w_star)).max() > 0.5


def test_a_layout_leaves_every_other_draw_of_the_seed_alone():
    plain = random_scene(8, order="RGB")
    cells = random_scene(8, layout=NAMED_LAYOUTS["lkg-columns"])
    assert cells.camera == plain.camera
    assert {k: v for k, v in cells.optics.to_dict().items() if k != "subpixel_layout"} == plain.optics.to_dict()
    with pytest.raises(InputError, match="order BGR"):
        random_scene(8, order="BGR", layout=NAMED_LAYOUTS["lkg-columns"])


# 2. The renderer puts each channel's light where the layout says ----------------------------------
def _band_raster(profile, lo, hi):
    v = np.mod(view_coordinate(profile), profile.views)
    lit = ((v >= lo) & (v < hi)).astype(np.uint8) * 255
    raster = np.zeros((profile.height, profile.width, 3), np.uint8)
    for channel, position in enumerate(profile.rho):
        raster[:, :, channel] = lit[:, position::3]
    return raster


@pytest.mark.parametrize("name, slant", [("lkg-columns", -0.23), ("lkg-checker", 0.3)])
def test_cell_panel_band_of_the_truth_is_centred_on_the_camera(name, slant):
    """A one-view band of the cell truth profile swept across the views: the camera sees it
    brightest, symmetrically, at N/2; the same band routed as a stripe panel is smeared and off."""
    scene = random_scene(21, width=1280, height=720, resolution=(400, 300), slant=slant, layout=NAMED_LAYOUTS[name])
    scene = Scene(scene.optics, scene.camera.clean(), scene.seed)
    cam, o = scene.camera, scene.optics
    px, py = np.meshgrid(np.arange(cam.width, dtype=float), np.arange(cam.height, dtype=float))
    lx, ly = cam.lens_plane_points(px, py)
    inside = (np.abs(lx) < 0.4 * o.panel_size[0]) & (np.abs(ly) < 0.4 * o.panel_size[1])
    shifts = np.arange(-2.0, 2.01, 0.5)
    truth = scene.truth_profile(N)

    def sweep(profile):
        light = np.array([render_radiance(_band_raster(profile, N / 2 + d - 0.5, N / 2 + d + 0.5), scene)
                          .sum(axis=2)[inside].mean() for d in shifts])
        above = light - light.min()
        return light, (above * shifts).sum() / above.sum()

    light, centroid = sweep(truth)
    assert shifts[light.argmax()] == 0.0 and abs(centroid) < 0.05
    np.testing.assert_allclose(light, light[::-1], rtol=0.03)
    stripe_light, _ = sweep(truth.replace(subpixel_layout=None))
    assert stripe_light.max() < 0.85 * light.max()  # the stripe routing mixes neighbouring views


# 3. Scene JSON ----------------------------------------------------------------------------------------
def test_scene_json_carries_the_layout_and_a_stripe_scene_reads_as_before():
    stripe = random_scene(5, width=640, height=360, resolution=(320, 240))
    assert "subpixel_layout" not in stripe.to_dict()["optics"]
    scene = random_scene(5, width=640, height=360, resolution=(320, 240), layout=NAMED_LAYOUTS["lkg-checker"])
    data = json.loads(json.dumps(scene.to_dict()))
    assert data["optics"]["subpixel_layout"]["pattern"] == [[0, 1], [1, 0]]
    assert Scene.from_dict(data) == scene
    data["optics"]["subpixel_layout"]["cells"][1]["G"] = [0.1]
    with pytest.raises(InputError, match="subpixel_layout.cells\\[1\\].G"):
        Scene.from_dict(data, source="scene.json")


def test_layout_names_and_files(tmp_path):
    assert resolve_layout("BGR") == ("BGR", None)
    assert resolve_layout("lkg-columns") == ("RGB", NAMED_LAYOUTS["lkg-columns"])
    path = tmp_path / "layout.json"
    path.write_text(json.dumps(NAMED_LAYOUTS["lkg-rows4"].to_dict()))
    assert resolve_layout(str(path)) == ("RGB", NAMED_LAYOUTS["lkg-rows4"])
    path.write_text(json.dumps({"cells": [{"R": [0, 0], "G": [0, 0]}]}))
    with pytest.raises(InputError, match="layout.json"):
        resolve_layout(str(path))
    with pytest.raises(InputError, match="unknown layout"):
        resolve_layout("pentile")


# 4. CLI -----------------------------------------------------------------------------------------------
@pytest.fixture
def simulate_main(monkeypatch, cli):
    import lenticalib.cli as cli_module

    monkeypatch.setattr(cli_module, "_COMMANDS", {"simulate": cli_module._COMMANDS["simulate"]})
    return cli


def test_simulate_cli_layout_errors_are_one_line(tmp_path, simulate_main):
    from lenticalib.calib.patterns.calibration_patterns import design_patterns
    from lenticalib.core.pattern_sets import write_patterns

    write_patterns(tmp_path, design_patterns(64, 64, 8))
    code, _, err = simulate_main("simulate", tmp_path, "--layout", "lkg-columns", "--order", "BGR")
    assert code == 2 and "--layout" in one_error_line(err) and "--order" in err
    code, _, err = simulate_main("simulate", tmp_path, "--layout", "hexagons")
    assert code == 2 and "hexagons" in one_error_line(err, "--layout")
    assert not (tmp_path / "captures").exists()


@pytest.mark.slow
def test_simulate_cli_photographs_a_cell_panel(tmp_path, simulate_main):
    from lenticalib.calib.patterns.calibration_patterns import design_patterns
    from lenticalib.core.pattern_sets import write_patterns

    write_patterns(tmp_path, design_patterns(64, 64, 8))
    code, out, err = simulate_main("simulate", tmp_path, "--seed", "3", "--resolution", "1250x800",
                                   "--subsamples", "1", "--layout", "lkg-columns")
    assert code == 0, err
    assert "layout lkg-columns" in out
    truth = load_profile(tmp_path / "truth.json")
    assert truth.subpixel_layout == NAMED_LAYOUTS["lkg-columns"]
    record = json.loads((tmp_path / "simulation.json").read_text())
    assert record["truth"]["subpixel_layout"] == NAMED_LAYOUTS["lkg-columns"].to_dict()
    assert Scene.from_dict(record).optics.subpixel_layout == NAMED_LAYOUTS["lkg-columns"]


def test_the_sim_capture_camera_takes_a_layout(tmp_path):
    from lenticalib.calib.capture.cameras import make_camera
    from lenticalib.calib.patterns.calibration_patterns import design_patterns
    from lenticalib.core.pattern_sets import write_patterns

    from .cli_support import refused

    camera = make_camera("sim:3", layout="lkg-checker")
    assert (camera.order, camera.layout) == ("RGB", NAMED_LAYOUTS["lkg-checker"])
    assert make_camera("sim:3").layout is None
    with pytest.raises(InputError, match="unknown layout"):
        make_camera("sim:3", layout="pentile")
    write_patterns(tmp_path, design_patterns(64, 64, 8))
    assert "sim" in refused("capture", str(tmp_path), "--camera", "opencv:0", "--layout", "lkg-columns",
                            source="--layout")
