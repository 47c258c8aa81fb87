"""Virtual cameras for the avatar renderer (lenticalib.render.cameras.view_cameras, .camera_models).

The expected numbers are recomputed here from the arc equation of the LentiAvatar paper
(c = c0 + 0.08 h e_up, o(theta) = c + r [sin theta e_side + cos theta e_forward]) and the
documented default radius; projections are checked against OpenCV's cv2.projectPoints.
"""

from __future__ import annotations

import json
import math

import cv2
import numpy as np
import pytest

from lenticalib.core.errors import InputError
from lenticalib.render.cameras.models import CAMERA_MODELS, arc_cameras, make_cameras, shear_cameras
from lenticalib.render.cameras.view_cameras import ViewCameras, camera_side, order_for_direction
from lenticalib.render.avatar.gaussians import Gaussians

LO = np.array([-0.09, -0.12, -0.10])
HI = np.array([0.09, 0.14, 0.11])
W, H = 960, 540


def _expected_arc(n, yaw_range=50.0, fov=20.0, radius=None):
    """c, r, yaws (degrees) and camera centres for the box LO..HI, up=+y, forward=+z."""
    h = HI[1] - LO[1]
    c = (LO + HI) / 2 + np.array([0.0, 0.08 * h, 0.0])
    r = radius if radius is not None else (h / 0.8) / (2 * math.tan(math.radians(fov) / 2)) + (HI[2] - LO[2]) / 2
    yaws = [0.0] if n == 1 else [-yaw_range / 2 + yaw_range * i / (n - 1) for i in range(n)]
    centres = [c + r * np.array([math.sin(math.radians(t)), 0.0, math.cos(math.radians(t))]) for t in yaws]
    return c, r, np.array(yaws), np.array(centres)


@pytest.mark.parametrize("n, yaw_range, fov, radius",
                         [(32, 50.0, 20.0, None), (5, 90.0, 35.0, 2.5), (1, 50.0, 20.0, None)])
def test_arc_matches_the_equation(n, yaw_range, fov, radius):
    cams = arc_cameras(LO, HI, n, yaw_range_deg=yaw_range, fov_deg=fov, radius=radius)
    c, r, yaws, centres = _expected_arc(n, yaw_range, fov, radius)
    assert cams.model == "arc" and cams.n_views == n and (cams.width, cams.height) == (W, H)
    np.testing.assert_allclose(cams.params["c"], c, atol=1e-12)
    assert cams.params["r"] == pytest.approx(r, rel=1e-12)
    np.testing.assert_allclose(cams.yaw_deg, yaws, atol=1e-12)
    cam_to_world = np.linalg.inv(cams.viewmats)
    np.testing.assert_allclose(cam_to_world[:, :3, 3], centres, atol=1e-12)
    for i in range(n):
        axis = cam_to_world[i, :3, 2]  # the camera's +z in world terms
        np.testing.assert_allclose(axis, (c - centres[i]) / np.linalg.norm(c - centres[i]), atol=1e-12)
        np.testing.assert_allclose(cam_to_world[i, :3, 1], [0.0, -1.0, 0.0], atol=1e-12)  # image y = -up
    f = H / (2 * math.tan(math.radians(fov) / 2))
    np.testing.assert_allclose(cams.K, np.broadcast_to([[f, 0, (W - 1) / 2], [0, f, (H - 1) / 2], [0, 0, 1]],
                                                       (n, 3, 3)), rtol=1e-12)


def test_arc_in_a_rotated_frame_looks_at_c_with_image_y_down():
    up, forward = np.array([0.0, 0.0, 1.0]), np.array([1.0, 0.0, 0.0])  # z up, facing +x: e_side = +y
    cams = arc_cameras(LO, HI, 7, up=up, forward=forward, view_size=(64, 48))
    c = np.asarray(cams.params["c"])
    h = HI[2] - LO[2]
    np.testing.assert_allclose(c, (LO + HI) / 2 + 0.08 * h * up, atol=1e-12)
    cam_to_world = np.linalg.inv(cams.viewmats)
    for i in range(7):
        o = cam_to_world[i, :3, 3]
        np.testing.assert_allclose(cam_to_world[i, :3, 2], (c - o) / np.linalg.norm(c - o), atol=1e-12)
        np.testing.assert_allclose(cam_to_world[i, :3, 1], -up, atol=1e-12)
    assert cams.centres[0, 1] < c[1] < cams.centres[-1, 1]  # view 0 on the viewer's left (-e_side)
    np.testing.assert_allclose(cams.K[0, :2, 2], [31.5, 23.5])


def test_overrides_centre_and_height_and_gaussians_input():
    rng = np.random.default_rng(7)
    means = rng.uniform(LO, HI, (500, 3)).astype(np.float32)
    g = Gaussians(means, np.tile([1, 0, 0, 0], (500, 1)).astype(np.float32), np.full((500, 3), 0.01, np.float32),
                  np.full(500, 0.5, np.float32), np.zeros((500, 1, 3), np.float32))
    lo, hi = np.percentile(means.astype(np.float64), (1, 99), axis=0)  # an avatar is framed on its robust box
    cams = make_cameras("arc", g, 9)
    np.testing.assert_allclose(cams.params["c0"], (lo + hi) / 2, atol=1e-12)
    assert cams.params["h"] == pytest.approx(hi[1] - lo[1], rel=1e-12)
    cams = make_cameras("arc", (LO, HI), 9, centre=(1.0, 2.0, 3.0), height=0.5, radius=2.0)
    np.testing.assert_allclose(cams.params["c"], [1.0, 2.0 + 0.08 * 0.5, 3.0], atol=1e-12)
    np.testing.assert_allclose(cams.centres[4], [1.0, 2.04, 5.0], atol=1e-12)


def test_cameras_json_round_trip(tmp_path):
    cams = arc_cameras(LO, HI, 6, view_size=(320, 180))
    path = tmp_path / "cameras.json"
    cams.write_json(path)
    data = json.loads(path.read_text())
    assert data["format"] == "lenticalib.cameras" and data["format_version"] == 1
    assert data["model"] == "arc" and (data["width"], data["height"]) == (320, 180) and data["view_direction"] == 1
    assert {"c0", "h", "c", "r", "Y", "N", "up", "forward", "fov"} <= set(data["params"])
    assert data["params"]["N"] == 6 and data["params"]["Y"] == 50.0 and data["params"]["fov"] == 20.0
    assert data["params"]["up"] == [0.0, 1.0, 0.0] and data["params"]["forward"] == [0.0, 0.0, 1.0]
    assert [v["index"] for v in data["views"]] == list(range(6))
    for i, view in enumerate(data["views"]):
        assert set(view) == {"index", "yaw_deg", "K", "world_to_camera"}
        assert view["yaw_deg"] == cams.yaw_deg[i]
        assert np.array_equal(view["K"], cams.K[i]) and np.array_equal(view["world_to_camera"], cams.viewmats[i])
    back = ViewCameras.from_json(path)
    for name in ("K", "viewmats", "yaw_deg"):
        assert np.array_equal(getattr(back, name), getattr(cams, name))
    assert (back.width, back.height, back.model, back.params, back.view_direction) == \
        (cams.width, cams.height, cams.model, cams.params, cams.view_direction)
    order_for_direction(cams, -1).write_json(path)
    assert ViewCameras.from_json(path).view_direction == -1


@pytest.mark.parametrize("text", ["{not json", '{"format": "other"}',
                                  '{"format": "lenticalib.cameras", "format_version": 1, "views": []}'])
def test_from_json_refuses_other_files(tmp_path, text):
    path = tmp_path / "cameras.json"
    path.write_text(text)
    with pytest.raises(InputError) as err:
        ViewCameras.from_json(path)
    assert err.value.source == str(path)


def test_projection_agrees_with_opencv():
    cams = arc_cameras(LO, HI, 4, view_size=(200, 100))
    points = np.random.default_rng(3).uniform(LO, HI, (50, 3))
    uv, depth = cams.project(points)
    for i in range(4):
        rvec, _ = cv2.Rodrigues(cams.viewmats[i, :3, :3])
        ref, _ = cv2.projectPoints(points, rvec, cams.viewmats[i, :3, 3], cams.K[i], None)
        np.testing.assert_allclose(uv[i], ref[:, 0], atol=1e-9)
        np.testing.assert_allclose(depth[i], (points @ cams.viewmats[i, :3, :3].T + cams.viewmats[i, :3, 3])[:, 2])
    behind = cams.centres[0] - 2 * (np.asarray(cams.params["c"]) - cams.centres[0])
    assert np.isnan(cams.project([behind])[0][0, 0]).all()


def test_arc_projection_centre_up_and_right():
    cams = arc_cameras(LO, HI, 9)
    c = np.asarray(cams.params["c"])
    uv, depth = cams.project([c, c + [0.0, 0.05, 0.0], c + [0.02, 0.0, 0.0]])
    np.testing.assert_allclose(uv[:, 0], np.broadcast_to([(W - 1) / 2, (H - 1) / 2], (9, 2)), atol=1e-9)
    np.testing.assert_allclose(depth[:, 0], cams.params["r"], rtol=1e-12)
    assert (uv[:, 1, 1] < (H - 1) / 2).all()      # above c: smaller y
    assert uv[4, 2, 0] > (W - 1) / 2               # front camera: +x (viewer's right) is image right


def test_shear_focal_plane_and_parallax():
    n = 8
    cams = shear_cameras(LO, HI, n)
    c, r = np.asarray(cams.params["c"]), cams.params["r"]
    _, _, yaws, _ = _expected_arc(n)
    np.testing.assert_allclose(cams.yaw_deg, yaws, atol=1e-12)
    x = r * np.tan(np.radians(yaws))
    np.testing.assert_allclose(cams.centres, c + np.stack([x, np.zeros(n), np.full(n, r)], 1), atol=1e-12)
    np.testing.assert_allclose(cams.viewmats[:, :3, :3], np.broadcast_to(np.diag([1.0, -1.0, -1.0]), (n, 3, 3)))
    f = H / (2 * math.tan(math.radians(20.0) / 2))
    np.testing.assert_allclose(cams.K[:, 0, 2], (W - 1) / 2 + f * x / r, rtol=1e-12)
    on_plane = [c, c + [0.03, -0.04, 0.0]]
    uv, _ = cams.project(on_plane)
    np.testing.assert_allclose(uv[:, 0], np.broadcast_to([(W - 1) / 2, (H - 1) / 2], (n, 2)), atol=1e-9)
    np.testing.assert_allclose(uv[:, 1], np.broadcast_to(uv[0, 1], (n, 2)), atol=1e-9)  # same pixel everywhere
    off = cams.project([c + [0.0, 0.0, 0.05], c - [0.0, 0.0, 0.05]])[0][:, :, 0] - (W - 1) / 2
    assert off[0, 0] > 0 > off[-1, 0] and off[0, 1] < 0 < off[-1, 1]  # opposite parallax, ends of the rig
    assert np.all(np.diff(off[:, 0]) < 0)


@pytest.mark.parametrize("model", sorted(CAMERA_MODELS))
def test_left_right_and_order_for_direction(model):
    cams = make_cameras(model, (LO, HI), 6)
    c = np.asarray(cams.params["c"])
    assert cams.centres[0, 0] < c[0] < cams.centres[-1, 0]  # view 0 at -x, view N-1 at +x
    assert camera_side(cams.yaw_deg[0]) == "left" and camera_side(cams.yaw_deg[-1]) == "right"
    assert camera_side(0.0) == "centre" and cams.view_direction == 1
    assert order_for_direction(cams, 1) is cams
    rev = order_for_direction(cams, -1)
    assert rev.view_direction == -1 and camera_side(rev.yaw_deg[0]) == "right"
    for name in ("K", "viewmats", "yaw_deg"):
        assert np.array_equal(getattr(rev, name), getattr(cams, name)[::-1])
    assert order_for_direction(rev, -1) is rev
    back = order_for_direction(rev, 1)
    assert np.array_equal(back.viewmats, cams.viewmats) and back.view_direction == 1
    with pytest.raises(InputError) as err:
        order_for_direction(cams, 0)
    assert err.value.source == "view_direction"


@pytest.mark.parametrize("options, source", [
    ({"view_size": (960, 0)}, "view_size"), ({"view_size": (960.5, 540)}, "view_size"),
    ({"view_size": 960}, "view_size"), ({"view_size": (True, 540)}, "view_size"),
    ({"fov_deg": 1.0}, "fov_deg"), ({"fov_deg": 120.0}, "fov_deg"), ({"fov_deg": float("nan")}, "fov_deg"),
    ({"fov_deg": "wide"}, "fov_deg"), ({"radius": 0.0}, "radius"), ({"radius": -1.0}, "radius"),
    ({"yaw_range_deg": 0.0}, "yaw_range_deg"), ({"yaw_range_deg": 180.0}, "yaw_range_deg"),
    ({"n_views": 0}, "n_views"), ({"n_views": 255}, "n_views"), ({"n_views": 4.0}, "n_views"),
    ({"up": (0, 0, 0)}, "up"), ({"forward": (0, 2, 0)}, "forward"), ({"height": 0.0}, "height"),
    ({"centre": (1, 2)}, "centre"),
])
@pytest.mark.parametrize("model", ["arc", "shear"])
def test_bad_options_name_the_option(model, options, source):
    options = dict(options)
    n = options.pop("n_views", 8)
    with pytest.raises(InputError) as err:
        make_cameras(model, (LO, HI), n, **options)
    assert err.value.source == source and "\n" not in str(err.value)


def test_unknown_model_and_bad_inputs():
    with pytest.raises(InputError) as err:
        make_cameras("fisheye", (LO, HI), 8)
    assert err.value.source == "model" and "arc" in str(err.value)
    for bbox in [(HI, LO), (LO, HI[:2]), 3.0]:
        with pytest.raises(InputError) as err:
            make_cameras("arc", bbox, 8)
        assert err.value.source == "bbox"
    flat = (np.array([0.0, 0.1, 0.0]), np.array([1.0, 0.1, 1.0]))  # no extent along up
    with pytest.raises(InputError, match="radius"):
        make_cameras("arc", flat, 8)
    assert make_cameras("arc", flat, 8, radius=1.0).params["r"] == 1.0
    with pytest.raises(InputError) as err:
        arc_cameras(LO, HI, 4).project(np.zeros((3, 2)))
    assert err.value.source == "points_world"
