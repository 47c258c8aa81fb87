"""Profiles for any viewing distance: the physical block, retargeting, and the per-frame API.

Ground truth is the simulator's ray-traced view coordinate (``sim.optics``), never the
retargeting formula itself: a profile that is exact for one eye, carried to another eye, must
equal the ideal profile ray-traced for that eye.
"""

import json
import math

import numpy as np
import pytest

from lenticalib.core.errors import InputError, ProfileError
from lenticalib.core.physical import gap_from_view_cone, validate_physical, view_cone_deg
from lenticalib.core.profile import load_profile, profile_from_dict, save_profile
from lenticalib.core.retarget import Eye, Retargeter, retarget_profile, routing_difference
from lenticalib.sim.truth import routing_error, truth_profile
from lenticalib.sim.scene import random_scene


def _exact(optics, eye_world, views=32):
    """The ideal profile for ``eye_world`` (world mm, z < 0) with its physical block."""
    x, y, z = eye_world
    return truth_profile(optics, eye_world, views).replace(
        physical={"pixel_pitch_mm": optics.pixel_pitch, "gap_mm": optics.gap, "eye_mm": [x, y, -z]})


@pytest.mark.parametrize("seed", [1, 2, 3])
@pytest.mark.parametrize("target", [(0.0, 0.0, 900.0), (45.0, 12.0, 400.0), (-90.0, -30.0, 750.0)])
def test_retargeting_an_exact_profile_gives_the_ray_traced_truth(seed, target):
    optics = random_scene(seed, distance=600).optics
    source = _exact(optics, (12.0, -30.0, -600.0))
    moved = retarget_profile(source, target)
    eye = (target[0], target[1], -target[2])
    assert np.abs(routing_error(optics, eye, moved)).max() < 1e-6
    assert moved.physical["eye_mm"] == list(target)
    # and without retargeting the routing would be wrong by views
    assert np.abs(routing_error(optics, eye, source)).max() > 0.5


def test_retargeting_there_and_back_is_the_identity():
    optics = random_scene(4, distance=550).optics
    source = _exact(optics, (5.0, 8.0, -550.0))
    back = retarget_profile(retarget_profile(source, (70.0, -5.0, 850.0)), (5.0, 8.0, 550.0))
    assert back.period == pytest.approx(source.period, rel=1e-12)
    assert routing_difference(back, source) < 1e-9


def test_uncertainty_of_the_gap_and_eye_is_propagated():
    optics = random_scene(5, distance=600).optics
    source = _exact(optics, (0.0, 0.0, -600.0))
    physical = dict(source.physical, uncertainty={"gap_mm": 0.02 * optics.gap})
    source = source.replace(physical=physical, uncertainty={"period": 1e-5, "offset": 0.01})
    near = retarget_profile(source, (0.0, 0.0, 600.0))
    far = retarget_profile(source, (0.0, 0.0, 900.0))
    # at the calibration eye the gap does not matter; farther away its error grows in
    assert near.uncertainty["period"] == pytest.approx(1e-5, rel=1e-3)
    assert far.uncertainty["period"] > near.uncertainty["period"]
    # a 2 % gap error, retargeting 600 -> 900 mm, is this period error (first order)
    k = (1 + optics.gap / 900) / (1 + optics.gap / 600)
    dk = abs((1 + 1.02 * optics.gap / 900) / (1 + 1.02 * optics.gap / 600) - k)
    assert far.uncertainty["period"] == pytest.approx(math.hypot(1e-5 * k, dk * source.period), rel=0.05)
    # not knowing where the calibration camera was costs even at the nominal eye
    unsure = source.replace(physical=dict(physical, uncertainty={"eye_mm": [0.0, 0.0, 6.0]}))
    m600 = 1 + optics.gap / 600
    dk_eye = abs((m600 / (1 + optics.gap / 606)) - 1)
    assert retarget_profile(unsure, (0.0, 0.0, 600.0)).uncertainty["period"] == pytest.approx(
        math.hypot(1e-5, dk_eye * source.period), rel=0.05)


def test_the_retargeter_rebuilds_only_when_the_routing_changes():
    optics = random_scene(6, distance=600).optics
    tracker = Retargeter(_exact(optics, (0.0, 0.0, -600.0)))
    first = tracker.profile_for((0.0, 0.0, 650.0))
    assert tracker.profile_for((0.001, 0.0, 650.0)) is first  # far below 0.01 view
    moved = tracker.profile_for((20.0, 0.0, 650.0))  # more than a view zone's tenth
    assert moved is not first and routing_difference(moved, first) > 0.01


def test_the_avatar_pipeline_retargets_per_frame():
    from lenticalib.render.avatar.sources import Avatar
    from lenticalib.render.cameras.models import make_cameras
    from lenticalib.render.avatar.gaussians import Gaussians
    from lenticalib.render.pipeline.avatar_pipeline import AvatarPipeline

    optics = random_scene(8, width=384, height=216, distance=600).optics
    profile = _exact(optics, (0.0, 0.0, -600.0), views=8)
    rng = np.random.default_rng(0)
    gaussians = Gaussians(means=rng.uniform(-0.1, 0.1, (50, 3)).astype(np.float32),
                          scales=np.full((50, 3), 0.01, np.float32),
                          quats=np.tile(np.array([1, 0, 0, 0], np.float32), (50, 1)),
                          opacities=np.full(50, 0.8, np.float32),
                          sh=rng.uniform(0, 1, (50, 1, 3)).astype(np.float32))
    cameras = make_cameras("arc", gaussians, 8, view_size=(96, 54))
    pipeline = AvatarPipeline(Avatar("static", "test", static=gaussians), profile, cameras)
    before, _, _ = pipeline.frame(None)
    assert pipeline.set_eye((0.0, 0.0, 900.0)) is True
    after, views, _ = pipeline.frame(None)
    from lenticalib.render.encoders import encode

    expected = retarget_profile(profile, (0.0, 0.0, 900.0), record=False)
    assert np.array_equal(after, encode(views, expected))
    assert not np.array_equal(before, after)
    assert pipeline.set_eye((0.0, 0.0, 900.0001)) is False


@pytest.mark.parametrize("block, words", [
    ({"gap_mm": 1.0}, "physical.pixel_pitch_mm': is missing"),
    ({"pixel_pitch_mm": -0.2}, "physical.pixel_pitch_mm': -0.2 is outside"),
    ({"pixel_pitch_mm": 0.2, "gap": 1.0}, "unknown field 'physical.gap' (did you mean 'physical.gap_mm'?)"),
    ({"pixel_pitch_mm": 0.2, "eye_mm": [0, 0, -600]}, "the distance D must be > 0"),
    ({"pixel_pitch_mm": 0.2, "uncertainty": {"gap_mm": -1}}, "physical.uncertainty.gap_mm"),
    ("0.2 mm", "must be a JSON object"),
])
def test_a_bad_physical_block_is_refused_naming_the_field(block, words):
    data = json.loads(load_profile("fixtures/panel-4k-32.json").to_json())
    data["physical"] = block
    with pytest.raises(ProfileError) as info:
        profile_from_dict(data, "p.json")
    assert words in str(info.value) and "p.json" in str(info.value)


def test_the_physical_block_survives_save_and_load(tmp_path):
    block = {"pixel_pitch_mm": 0.18, "gap_mm": 1.4, "lens_pitch_mm": 0.98, "eye_mm": [1.0, -2.0, 600.0],
             "source": "fit", "uncertainty": {"gap_mm": 0.01, "eye_mm": [0.1, 0.1, 0.5]}}
    profile = load_profile("fixtures/panel-4k-32.json").replace(physical=validate_physical(block))
    save_profile(profile, tmp_path / "p.json")
    assert load_profile(tmp_path / "p.json").physical == block


def test_view_cone_and_gap_are_inverse():
    gap = gap_from_view_cone(0.9, 14.0, 40.0)
    assert view_cone_deg(0.9, 14.0, gap) == pytest.approx(40.0, rel=1e-12)


def test_eye_positions_are_checked():
    assert Eye.parse({"distance": 700}).distance == 700.0
    for bad in ((0, 0, 10), (0, 0), ("a", 0, 600), (0, float("nan"), 600)):
        with pytest.raises(InputError):
            Eye.parse(bad)


def test_profile_retarget_cli(tmp_path, cli):
    optics = random_scene(9, width=3840, height=2160, distance=620).optics
    source = _exact(optics, (10.0, 20.0, -620.0))
    save_profile(source, tmp_path / "p.json")
    code, out, err = cli("profile", "retarget", tmp_path / "p.json", "--distance", 850, "--lateral", -40,
                         "-o", tmp_path / "p850.json")
    assert code == 0, err
    assert "period" in out and "wrote" in out
    moved = load_profile(tmp_path / "p850.json")
    assert np.abs(routing_error(optics, (-40.0, 0.0, -850.0), moved)).max() < 1e-6
    assert moved.provenance["method"] == "retarget" and moved.provenance["to_eye_mm"] == [-40.0, 0.0, 850.0]


@pytest.mark.parametrize("case", ["no physical", "no gap", "bad distance", "missing output folder"])
def test_profile_retarget_refusals_are_one_line(tmp_path, cli, case):
    profile = load_profile("fixtures/panel-4k-32.json")
    if case == "no gap":
        profile = profile.replace(physical={"pixel_pitch_mm": 0.18, "design_distance_mm": 600.0})
    save_profile(profile, tmp_path / "p.json")
    distance = 5 if case == "bad distance" else 800
    output = tmp_path / ("nowhere/p2.json" if case == "missing output folder" else "p2.json")
    code, out, err = cli("profile", "retarget", tmp_path / "p.json", "--distance", distance, "-o", output)
    assert code == 2 and err.count("\n") == 1 and "Traceback" not in err
    words = {"no physical": "gap", "no gap": "gap", "bad distance": "--distance",
             "missing output folder": "does not exist"}[case]
    assert words in err
    assert not (tmp_path / "p2.json").exists()


def test_set_physical_from_a_data_sheet_then_retarget(tmp_path, cli):
    optics = random_scene(10, width=3840, height=2160, distance=600).optics
    truth = truth_profile(optics, (0.0, 0.0, -600.0), 32)
    save_profile(truth, tmp_path / "p.json")
    cone = view_cone_deg(optics.lens_pitch, math.degrees(optics.slant_angle), optics.gap)
    code, out, err = cli("profile", "set-physical", tmp_path / "p.json", "--pixel-pitch", optics.pixel_pitch,
                         "--lens-pitch", optics.lens_pitch, "--view-cone", cone, "--design-distance", 600)
    assert code == 0, err
    block = load_profile(tmp_path / "p.json").physical
    assert block["gap_mm"] == pytest.approx(optics.gap, rel=1e-9) and block["source"] == "data sheet"
    code, out, err = cli("profile", "retarget", tmp_path / "p.json", "--distance", 450, "-o",
                         tmp_path / "p450.json")
    assert code == 0, err
    moved = load_profile(tmp_path / "p450.json")
    assert np.abs(routing_error(optics, (0.0, 0.0, -450.0), moved)).max() < 1e-6
    code, out, err = cli("profile", "set-physical", tmp_path / "p.json", "--gap", -1)
    assert code == 2 and "physical.gap_mm" in err


@pytest.mark.parametrize("reversed_views", [False, True])
def test_retargeting_a_cell_layout_routes_every_channel_from_its_true_position(reversed_views, tmp_path):
    from lenticalib.core.layout import SubpixelLayout, pattern_for_mode
    from lenticalib.core.routing import view_coordinate
    from lenticalib.sim.truth import view_coordinate_truth

    optics = random_scene(6, distance=600).optics
    cells = (((-0.25, 0.31), (-0.25, -0.28), (0.25, 0.0)), ((0.25, 0.31), (0.25, -0.28), (-0.25, 0.0)))
    layout = SubpixelLayout(cells=cells, pattern=pattern_for_mode(1, 2, optics.height))  # checkerboard
    source = _exact(optics, (12.0, -30.0, -600.0)).replace(
        subpixel_order="RGB", subpixel_layout=layout, views_reversed=reversed_views, flip_image_x=True,
        flip_image_y=True)
    target = (-60.0, 20.0, 820.0)
    moved = retarget_profile(source, target)
    assert (moved.subpixel_layout, moved.views_reversed, moved.flip_image_x, moved.flip_image_y) == \
        (layout, reversed_views, True, True)
    save_profile(moved, tmp_path / "moved.json")
    assert load_profile(tmp_path / "moved.json").routing_key() == moved.routing_key()
    # ground truth: ray-traced w* at each channel's own centre (pixel centre + (dx, dy) pixels)
    n = moved.views
    ys = np.linspace(0, optics.height - 1, 23).astype(np.int64)
    xs = np.linspace(0, optics.width - 1, 57).astype(np.int64)
    yy, xx = np.meshgrid(ys, xs, indexing="ij")
    eye = (target[0], target[1], -target[2])

    def worst_error(profile):
        w = view_coordinate(profile, ys)
        worst = 0.0
        for c in range(3):
            offsets = np.array(cells)[layout.cell_of(xx, yy), c]  # (rows, cols, 2)
            truth = view_coordinate_truth(optics, eye, 3 * xx + 1.5 + 3 * offsets[..., 0],
                                          yy + 0.5 + offsets[..., 1], n)
            shown = n - truth if reversed_views else truth
            got = w[np.arange(ys.size)[:, None], 3 * xx + c]
            worst = max(worst, float(np.abs(np.mod(got - shown + n / 2, n) - n / 2).max()))
        return worst

    assert worst_error(moved) < 1e-6
    assert worst_error(source) > 0.5  # not retargeted, the routing is views off
    assert worst_error(moved.replace(subpixel_layout=None)) > 0.2  # read as a stripe, channels are off
