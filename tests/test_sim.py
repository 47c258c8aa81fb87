"""The virtual panel: truth profile vs ray-traced w*, renderer physics, determinism, CLI."""

import json

import numpy as np
import pytest

from lenticalib.core.errors import InputError
from lenticalib.core.profile import load_profile
from lenticalib.core.routing import view_coordinate
from lenticalib.sim import Scene, random_scene, view_coordinate_truth
from lenticalib.sim.photo import photograph, photograph_jpeg

from .cli_support import one_error_line

N = 32


def _circular(d, n=N):
    return (np.asarray(d) + n / 2) % n - n / 2


# 1. The truth profile's w at subpixel x_s equals the ray-traced w* at the subpixel's centre ----------
@pytest.mark.parametrize("seed, slant, order", [(0, 0.31, "RGB"), (1, -0.12, "RGB"), (2, 0.19, "BGR"),
                                               (3, -0.35, "BGR"), (4, None, None), (5, None, None)])
def test_truth_profile_matches_ray_traced_view_coordinate(seed, slant, order):
    scene = random_scene(seed, slant=slant, order=order, resolution=(640, 480))
    o = scene.optics
    profile = scene.truth_profile(N)
    assert profile.slant == pytest.approx(np.tan(o.slant_angle), abs=1e-15)
    assert profile.period == pytest.approx(3 * o.lens_pitch * (1 + o.gap / scene.camera.distance) / o.pixel_pitch)
    assert 0 <= profile.offset < profile.period and profile.reference_view == N / 2
    assert profile.subpixel_order == o.subpixel_order and (profile.width, profile.height) == (3840, 2160)
    rows = np.r_[np.arange(0, 2160, 61), 2159]
    cols = np.r_[np.arange(0, 3 * 3840, 37), 3 * 3840 - 1]
    w = view_coordinate(profile, rows)[:, cols]
    w_star = view_coordinate_truth(o, scene.eye, cols[None, :] + 0.5, rows[:, None] + 0.5, N)
    assert np.abs(_circular(w - w_star)).max() < 1e-6
    if slant is not None:  # requested routing constants come out exactly
        assert profile.slant == pytest.approx(slant, rel=1e-12)


def test_requested_period_is_exact_at_the_camera_distance():
    scene = random_scene(11, period=17.25, distance=612.0, resolution=(640, 480))
    assert scene.truth_profile(N).period == pytest.approx(17.25, rel=1e-12)
    assert 1.0 <= scene.optics.gap / scene.optics.lens_pitch_u <= 1.6  # kappa range


def test_a_blurred_point_swept_over_a_stretch_lights_an_aperture_as_the_exact_integral_says():
    """The kernel's coverage of a subpixel's open aperture by a Gaussian (sigma s) whose centre sweeps
    ``[-ext/2, ext/2]``, against a dense numerical average over the sweep."""
    from scipy.special import ndtr

    from lenticalib.sim.gaussian_cover import PHI_TABLE, coverage

    for lo, width, ext, s in [(-0.4, 0.8, 0.0, 0.2), (-0.4, 0.8, 1.05, 0.1), (0.3, 0.8, 0.7, 0.25),
                              (-2.5, 0.85, 1.0, 0.15), (12.0, 0.8, 1.0, 0.2), (-0.9, 0.8, 0.003, 0.3)]:
        centre = ext * ((np.arange(100_000) + 0.5) / 100_000 - 0.5)  # midpoints of the sweep
        expected = np.mean(ndtr((lo + width - centre) / s) - ndtr((lo - centre) / s))
        assert coverage(lo, width, ext, s, PHI_TABLE) == pytest.approx(expected, abs=1e-6)


def test_a_view_seen_through_a_coarse_camera_is_as_bright_as_through_a_fine_one(monkeypatch):
    """Rays several rows long (a camera far coarser than the panel: the crosstalk truth's eye) see a sharp
    view's core as rays shorter than a row do.  When the seen stretch's extent across the subpixels was
    folded into the blur as a Gaussian of equal variance, the coarse eye took the own view 1 % too
    bright and the neighbour 2 % too dim."""
    from lenticalib.sim import crosstalk_truth

    scene = random_scene(105, blur=(0.15, 0.15), slant=0.35, distance=500.0)
    profile = scene.truth_profile(N)
    cones = []
    for pixels in ((24, 16), (192, 128)):  # about 14 and 1.7 rows of the panel per ray
        monkeypatch.setattr(crosstalk_truth, "EYE_PIXELS", pixels)
        cones.append(crosstalk_truth.true_view_cone(scene.optics, scene.eye, profile, np.array([0.0, 1.0])))
    np.testing.assert_allclose(cones[0], cones[1], atol=0.0015)


# 3. Seen-point formula ----------------------------------------------------------------------------
def test_seen_point_of_any_ray_lies_at_the_centre_of_the_view_cone():
    scene = random_scene(7, resolution=(640, 480))
    o, eye = scene.optics, scene.eye
    rng = np.random.default_rng(0)
    k = rng.integers(-250, 250, 200)
    v = rng.uniform(-150, 150, 200)
    u_c = o.lens_centre(k)
    lx, ly = o.from_uv(u_c, v)  # on lens centre lines
    xp, yp = o.seen_point(eye, lx, ly)
    # the chief ray: E, the lens-centre point L and the seen point P are collinear
    ex, ey, ez = eye
    t = -ez / (o.gap - ez)
    np.testing.assert_allclose(ex + (xp - ex) * t, lx, atol=1e-9)
    np.testing.assert_allclose(ey + (yp - ey) * t, ly, atol=1e-9)
    w = view_coordinate_truth(o, eye, *o.world_to_raster(xp, yp), N)
    assert np.abs(_circular(w - N / 2)).max() < 1e-9
    # any other point of the same lens shows the same u, hence the same view
    du = rng.uniform(-0.49, 0.49, 200) * o.lens_pitch_u
    xq, yq = o.seen_point(eye, *o.from_uv(u_c + du, v))
    w = view_coordinate_truth(o, eye, *o.world_to_raster(xq, yq), N)
    assert np.abs(_circular(w - N / 2)).max() < 1e-9


def test_camera_rays_and_projection_are_inverse():
    cam = random_scene(8, resolution=(640, 480)).camera
    px, py = np.meshgrid(np.linspace(-0.5, 639.5, 17), np.linspace(-0.5, 479.5, 13))
    lx, ly = cam.lens_plane_points(px, py)
    back = cam.project(np.stack([lx.ravel(), ly.ravel(), np.zeros(lx.size)], 1))
    assert np.abs(back - np.stack([px.ravel(), py.ravel()], 1)).max() < 1e-6


# 2. Physical consistency of the renderer with the truth ----------------------------------------------
def _band_raster(profile, lo, hi):
    """Light (255) every subpixel whose true view frac(w/N) N lies in [lo, hi), else 0."""
    v = np.mod(view_coordinate(profile), profile.views)
    lit = ((v >= lo) & (v < hi)).astype(np.uint8) * 255
    raster = np.zeros((profile.height, profile.width, 3), np.uint8)
    for channel, position in enumerate(profile.rho):
        raster[:, :, channel] = lit[:, position::3]
    return raster


def _panel_brightness(scene, photo):
    """Mean brightness (sum of RGB) of the camera pixels that see the inner 80% of the panel."""
    cam, o = scene.camera, scene.optics
    px, py = np.meshgrid(np.arange(cam.width, dtype=float), np.arange(cam.height, dtype=float))
    lx, ly = cam.lens_plane_points(px, py)
    half_w, half_h = o.panel_size[0] / 2, o.panel_size[1] / 2
    inside = (np.abs(lx) < 0.8 * half_w) & (np.abs(ly) < 0.8 * half_h)
    assert inside.sum() > 0.08 * inside.size
    values = photo.astype(np.float64).sum(axis=2)[inside]
    return values.mean(), values.std()


@pytest.fixture(scope="module")
def small_scene():
    # A 1280 x 720 raster (big pixels, so the camera sees ~3 pixels per lens at 800 x 600)
    scene = random_scene(21, width=1280, height=720, resolution=(800, 600), slant=-0.23)
    return Scene(scene.optics, scene.camera.clean(), scene.seed)


def test_views_around_the_camera_look_bright_and_others_dark(small_scene):
    profile = small_scene.truth_profile(N)
    rng = np.random.default_rng(0)
    centred = photograph(_band_raster(profile, N / 2 - 2, N / 2 + 2), small_scene, rng)
    aside = photograph(_band_raster(profile, N / 2 + 6, N / 2 + 10), small_scene, rng)
    bright, spread = _panel_brightness(small_scene, centred)
    dark, _ = _panel_brightness(small_scene, aside)
    assert bright >= 5 * dark, (bright, dark)
    assert spread < 0.12 * bright, (bright, spread)  # uniformly bright over the panel
    assert bright > 300  # of 765: the camera sees the lit subpixels, not the black matrix

    # Move the camera right by 8 view zones: the bright band follows (higher views to the right).
    o, cam = small_scene.optics, small_scene.camera
    shift = 8 * o.view_zone_width(cam.distance, N)
    moved = small_scene.replace_camera(position=(cam.position[0] + shift, cam.position[1], cam.position[2]))
    moved_profile = moved.truth_profile(N)
    rows = np.arange(0, 720, 53)
    np.testing.assert_allclose(_circular(view_coordinate(moved_profile, rows) - view_coordinate(profile, rows)),
                               -8.0, atol=1e-9)
    now_bright, now_spread = _panel_brightness(moved, photograph(_band_raster(profile, N / 2 + 6, N / 2 + 10),
                                                                  moved, rng))
    now_dark, _ = _panel_brightness(moved, photograph(_band_raster(profile, N / 2 - 2, N / 2 + 2), moved, rng))
    assert now_bright >= 5 * now_dark, (now_bright, now_dark)
    assert now_spread < 0.12 * now_bright


def test_crosstalk_profile_is_centred_on_the_camera(small_scene):
    """A one-view band swept across the views: the camera sees it brightest, symmetrically, at N/2.

    A half-subpixel slip between the renderer and the truth would move the centroid by
    N / (2 Delta_r) ~ 0.75 views."""
    from lenticalib.sim.panel_light import render_radiance

    profile = small_scene.truth_profile(N)
    cam, o = small_scene.camera, small_scene.optics
    px, py = np.meshgrid(np.arange(cam.width, dtype=float), np.arange(cam.height, dtype=float))
    lx, ly = cam.lens_plane_points(px, py)
    inside = (np.abs(lx) < 0.4 * o.panel_size[0]) & (np.abs(ly) < 0.4 * o.panel_size[1])
    shifts = np.arange(-3.0, 3.01, 0.5)
    light = np.array([render_radiance(_band_raster(profile, N / 2 + d - 0.5, N / 2 + d + 0.5), small_scene)
                      .sum(axis=2)[inside].mean() for d in shifts])
    assert shifts[light.argmax()] == 0.0
    above = light - light.min()
    assert abs((above * shifts).sum() / above.sum()) < 0.05  # views
    np.testing.assert_allclose(light, light[::-1], rtol=0.03)  # symmetric crosstalk


# 4. Determinism and JSON --------------------------------------------------------------------------
def test_same_seed_gives_identical_photo_bytes_and_scene_json_round_trips():
    scene = random_scene(5, width=640, height=360, resolution=(320, 240))
    assert random_scene(5, width=640, height=360, resolution=(320, 240)) == scene
    raster = np.random.default_rng(1).integers(0, 256, (360, 640, 3), dtype=np.uint8)
    a = photograph_jpeg(raster, scene, np.random.default_rng([5, 1]))
    b = photograph_jpeg(raster, scene, np.random.default_rng([5, 1]))
    c = photograph_jpeg(raster, scene, np.random.default_rng([5, 2]))
    assert a == b and a != c and a[:2] == b"\xff\xd8"
    again = Scene.from_dict(json.loads(json.dumps(scene.to_dict())))
    assert again == scene and again.to_dict() == scene.to_dict()
    with pytest.raises(InputError, match="unknown camera field"):
        data = scene.to_dict()
        data["camera"]["zoom"] = 2
        Scene.from_dict(data)


def test_noise_free_settings_are_honoured():
    scene = random_scene(6, width=640, height=360, resolution=(320, 240))
    clean = Scene(scene.optics, scene.camera.clean(), scene.seed)
    raster = np.full((360, 640, 3), 128, np.uint8)
    a = photograph(raster, clean, np.random.default_rng(1))
    b = photograph(raster, clean, np.random.default_rng(2))
    np.testing.assert_array_equal(a, b)  # no noise, no JPEG
    assert a.shape == (240, 320, 3) and a.dtype == np.uint8


# 5. The CLI end to end ------------------------------------------------------------------------------
@pytest.fixture
def simulate_main(monkeypatch, cli):
    """The ``cli`` runner with ``simulate`` as the only command."""
    import lenticalib.cli as cli_module

    monkeypatch.setattr(cli_module, "_COMMANDS", {"simulate": cli_module._COMMANDS["simulate"]})
    return cli


@pytest.mark.slow
def test_simulate_cli_writes_captures_truth_and_scene(tmp_path, simulate_main):
    from lenticalib.calib.patterns.calibration_patterns import design_patterns
    from lenticalib.core.pattern_sets import write_patterns

    # a 640x360 panel (nothing here depends on its size; the scene is drawn for the set's size) and
    # the smallest camera the fit takes (captures.MIN_PHOTO_PIXELS), one ray per pixel for speed
    pattern_set = design_patterns(640, 360, 32)
    write_patterns(tmp_path, pattern_set)
    code, out, err = simulate_main("simulate", tmp_path, "--seed", "3", "--resolution", "1250x800", "--subsamples", "1",
                                   "--json")
    assert code == 0, err
    summary = json.loads(out)
    captures = sorted(p.name for p in (tmp_path / "captures").iterdir())
    assert captures == sorted(f"{name}.jpg" for name in pattern_set.names)  # photos only
    assert summary["photos"] == len(pattern_set.patterns)
    truth = load_profile(tmp_path / "truth.json")
    expected = random_scene(3, width=640, height=360, resolution=(1250, 800), subsamples=1).truth_profile(32)
    assert truth.routing_key() == expected.routing_key()
    assert truth.provenance["method"] == "simulation"
    record = json.loads((tmp_path / "simulation.json").read_text())
    assert record["status"] == "complete" and record["seed"] == 3 and record["lenticalib_version"]
    assert Scene.from_dict(record) == random_scene(3, width=640, height=360, resolution=(1250, 800), subsamples=1)
    from lenticalib.core.files.imageio import read_image

    assert read_image(tmp_path / "captures" / "f16-0.jpg").shape == (800, 1250, 3)

    # simulation.json holds everything needed to reproduce a photo byte for byte
    entry = record["captures"][5]
    raster = read_image(tmp_path / f"{entry['pattern']}.png")
    again = photograph_jpeg(raster, Scene.from_dict(record), np.random.default_rng(entry["noise_seed"]))
    assert again == (tmp_path / entry["file"]).read_bytes()

    # --scene reuses it; it fixes the scene, so --seed cannot come with it
    code, _, err = simulate_main("simulate", tmp_path, "--scene", tmp_path / "simulation.json", "--seed", "4")
    assert code == 2 and "--scene" in one_error_line(err)


@pytest.mark.slow
def test_simulate_cli_reuses_a_scene_file(tmp_path, simulate_main):
    from lenticalib.calib.patterns.calibration_patterns import design_patterns
    from lenticalib.core.pattern_sets import write_patterns

    write_patterns(tmp_path / "set", design_patterns(640, 360, 8))
    scene = random_scene(9, width=640, height=360, resolution=(1250, 800), subsamples=1)
    (tmp_path / "scene.json").write_text(json.dumps(scene.to_dict()))
    args = ["simulate", str(tmp_path / "set"), "--scene", str(tmp_path / "scene.json"), "--jpeg-quality", "90"]
    real = tmp_path / "set" / "captures" / "IMG_0001.jpg"  # someone's real photos: never touched
    real.parent.mkdir()
    real.write_bytes(b"photo")
    code, _, err = simulate_main(*args)
    assert code == 2 and "captures" in one_error_line(err)
    assert real.read_bytes() == b"photo" and not (tmp_path / "set" / "simulation.json").exists()
    real.unlink()
    code, out, err = simulate_main(*args)
    assert code == 0, err
    assert "truth" in out and "1250x800" in out
    record = json.loads((tmp_path / "set" / "simulation.json").read_text())
    assert Scene.from_dict(record) == scene.replace_camera(jpeg_quality=90)
    assert load_profile(tmp_path / "set" / "truth.json").routing_key() == scene.truth_profile(8).routing_key()
    # a scene for another panel size is refused, naming the manifest
    other = random_scene(9, width=1280, height=720, resolution=(1250, 800))
    (tmp_path / "other.json").write_text(json.dumps(other.to_dict()))
    code, _, err = simulate_main("simulate", tmp_path / "set", "--scene", tmp_path / "other.json")
    line = one_error_line(err)
    assert code == 2 and "patterns.json" in line and "640x360" in line


def test_simulate_cli_without_patterns_fails_with_one_line(tmp_path, simulate_main):
    code, out, err = simulate_main("simulate", tmp_path, "--seed", "1")
    assert code == 2 and out == ""
    assert err.count("\n") == 1 and "patterns.json" in err and "Traceback" not in err
    code, _, err = simulate_main("simulate", tmp_path, "--resolution", "big")
    assert code == 2 and "--resolution" in one_error_line(err)


def test_hard_conditions_add_phone_behaviour_and_leave_every_other_draw_alone():
    from lenticalib.sim.capture import photo_scene
    from lenticalib.sim.scene import random_scene

    standard, hard = random_scene(21), random_scene(21, conditions="hard")
    assert (standard.camera.tone_contrast, standard.camera.exposure_jitter, standard.camera.shake) == (0, 0, 0)
    assert photo_scene(standard, "x1-0")[0] is standard
    assert 0.1 <= hard.camera.tone_contrast <= 1.0
    assert (hard.camera.exposure_jitter, hard.camera.shake) == (0.04, 0.3)
    assert 500 <= hard.camera.full_well <= 2500 and 3 <= hard.camera.read_noise <= 10
    changed = {"tone_contrast", "exposure_jitter", "shake", "full_well", "read_noise"}
    s_cam, h_cam = standard.camera.to_dict(), hard.camera.to_dict()
    assert {k for k in s_cam if s_cam[k] != h_cam[k]} == changed
    assert standard.optics == hard.optics
    draws = [photo_scene(hard, f"f16-{k}")[1] for k in range(3)]
    assert draws == [photo_scene(hard, f"f16-{k}")[1] for k in range(3)]  # reproducible
    for d in draws:
        assert abs(d["exposure_factor"] - 1) <= 0.04 and (d["shift_x"] ** 2 + d["shift_y"] ** 2) ** 0.5 <= 0.3
    assert len({d["shift_x"] for d in draws}) == 3


def test_s_curve_tone_lut():
    from lenticalib.sim.photo import _tone_lut

    plain, strong = _tone_lut(1.0, 0.0), _tone_lut(1.0, 1.0)
    mid = np.searchsorted(plain, 0.5)
    assert abs(strong[mid] - 0.5) < 1e-3  # the S-curve keeps mid-grey
    quarter, three_q = np.searchsorted(plain, 0.25), np.searchsorted(plain, 0.75)
    assert strong[quarter] < plain[quarter] - 0.05 and strong[three_q] > plain[three_q] + 0.05
    assert np.all(np.diff(strong) >= 0)


def test_the_cameras_jpeg_chroma_is_half_or_full_resolution_as_set():
    """A red/blue checkerboard of single pixels keeps its colours through a 4:4:4 JPEG and loses
    most of them through a 4:2:0 one (its chroma averaged over 2 x 2 pixels); an unknown chroma is
    refused, naming the field."""
    import cv2

    from lenticalib.sim.camera import JPEG_CHROMA
    from lenticalib.sim.photo import encode_jpeg

    assert JPEG_CHROMA == ("4:2:0", "4:4:4")
    yy, xx = np.mgrid[0:64, 0:64]
    red = (yy + xx) % 2 == 0  # one-pixel checks: the chroma alternates pixel by pixel
    photo = np.where(red[..., None], np.array([200, 30, 30], np.uint8), np.array([30, 30, 200], np.uint8))
    spread = {}
    for chroma in JPEG_CHROMA:
        back = cv2.imdecode(np.frombuffer(encode_jpeg(photo, 95, chroma), np.uint8), cv2.IMREAD_COLOR)[:, :, ::-1]
        spread[chroma] = float(np.mean(np.abs(back[..., 0].astype(int) - back[..., 2].astype(int))))
    assert spread["4:4:4"] > 120 and spread["4:2:0"] < 60
    scene = random_scene(5, width=320, height=180, resolution=(160, 120), subsamples=1)
    assert scene.camera.jpeg_chroma == "4:2:0"
    with pytest.raises(InputError, match="jpeg_chroma"):
        scene.replace_camera(jpeg_chroma="4:2:2")


def test_the_cameras_demosaicing_is_edge_aware_or_bilinear_as_set():
    """Panel rows one in eight lit, 3 photo pixels apart, coloured as a lens sheet's subpixels are:
    the bilinear demosaicing keeps their light (within 0.5 %), the edge-aware one takes some off (the
    level photos' loss, lenticalib.calib.crosstalk.level_texture); an unknown kind is refused."""
    import dataclasses

    from lenticalib.sim.camera import DEMOSAICING
    from lenticalib.sim.photo import develop

    assert DEMOSAICING == ("edge-aware", "bilinear")
    scene = random_scene(5, width=320, height=180, resolution=(240, 240), subsamples=1)
    camera = dataclasses.replace(scene.camera.clean(), colour_matrix=(1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0),
                                 exposure=1.0, defocus_sigma=0.0, chromatic=(0.0, 0.0))
    yy, xx = np.mgrid[0:240, 0:240]
    rows = ((yy // 3) % 8 == 0).astype(np.float32)
    colour = np.stack([(xx // 2) % 3 == k for k in range(3)], axis=2).astype(np.float32)  # subpixel colours
    radiance = 0.6 * rows[..., None] * colour
    kept = {}
    for kind in DEMOSAICING:
        photo = develop(radiance, camera.replace(demosaicing=kind), np.random.default_rng(0), linear=True)
        kept[kind] = float(photo[8:-8, 8:-8].astype(np.float64).sum() / 65535.0 / radiance[8:-8, 8:-8].sum())
    assert abs(kept["bilinear"] - 1.0) < 0.005
    assert kept["edge-aware"] < kept["bilinear"] - 0.01
    assert scene.camera.demosaicing == "edge-aware"
    with pytest.raises(InputError, match="demosaicing"):
        scene.replace_camera(demosaicing="vng")
