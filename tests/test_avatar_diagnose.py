"""The LentiAvatar side-view diagnostics (``lenticalib avatar diagnose``): meshes, the mesh mask,
the seven metrics with known answers, the rig's mesh posed like its Gaussians, bad input.

Known answers: an opaque sphere of Gaussians with its exact mesh (nothing outside the support,
smear only at the rim); faint Gaussians outside the dilated mask whose alpha mass is computed
from their projected footprints (the renderer's EWA covariance, its 0.3 px^2 low-pass and its
1/255 alpha floor); a view saturated only on its alpha boundary; mirror symmetry of the -25 and
+25 degree views of a mirror-symmetric avatar.  Small views (320 x 180), fixed seeds.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from lenticalib.core.errors import InputError  # noqa: E402
from lenticalib.render.avatar.demo_avatar_shapes import frame_quats  # noqa: E402
from lenticalib.render.diagnose.avatars import DiagnoseOptions, diagnose_avatars, diagnose_cameras, mesh_box  # noqa: E402
from lenticalib.render.avatar.gaussians import SH_C0, Gaussians  # noqa: E402
from lenticalib.render.avatar.mesh import check_mesh_fits, load_mesh_file  # noqa: E402
from lenticalib.render.diagnose.mesh_raster import mesh_masks  # noqa: E402
from lenticalib.render.avatar.ply import save_ply  # noqa: E402
from lenticalib.render.renderers.cpu_project import ALPHA_MIN  # noqa: E402
from lenticalib.render.renderers.common import EPS2D  # noqa: E402
from lenticalib.render.diagnose.side_metrics import (DILATION_PX, Crop, alpha_boundary, crop_rule, dilate,  # noqa: E402
                                            view_metrics)

R = 0.1  # sphere radius, metres
SMALL = DiagnoseOptions(n_views=5, view_size=(320, 180))


# ------------------------------------------------------------------ avatars with known answers

def fibonacci(n):
    i = np.arange(n) + 0.5
    phi = np.arccos(1 - 2 * i / n)
    th = math.pi * (1 + 5 ** 0.5) * i
    return np.stack([np.cos(th) * np.sin(phi), np.cos(phi), np.sin(th) * np.sin(phi)], 1)


def sphere_gaussians(n=6000, colour=(0.8, 0.5, 0.4)):
    """Flat opaque Gaussians tiling a sphere of radius R about the origin (G = n)."""
    d = fibonacci(n)
    spacing = math.sqrt(4 * math.pi * R * R / n)
    t = np.cross(d, [0.0, 1.0, 1e-3])
    t /= np.linalg.norm(t, axis=1, keepdims=True)
    scales = np.tile([0.8 * spacing, 0.8 * spacing, 0.05 * spacing], (n, 1))
    sh = np.repeat(((np.array(colour) - 0.5) / SH_C0)[None, None, :], n, 0)
    return Gaussians(means=(R * d).astype(np.float32), quats=frame_quats(d, t).astype(np.float32),
                     scales=scales.astype(np.float32), opacities=np.full(n, 0.99, np.float32), sh=sh.astype(np.float32))


def faint_ring(radius, count, sigma, opacity, spread_deg=40.0):
    """``count`` faint isotropic Gaussians on two arcs of a circle of ``radius`` in the plane z = 0
    (facing the front camera), within ``spread_deg`` of the horizontal on either side."""
    a = np.radians(np.linspace(-spread_deg, spread_deg, count // 2))
    a = np.concatenate([a, math.pi - a])
    means = np.stack([radius * np.cos(a), radius * np.sin(a), np.zeros(len(a))], 1)
    count = len(a)
    return Gaussians(means=means.astype(np.float32), quats=np.tile([1.0, 0, 0, 0], (count, 1)).astype(np.float32),
                     scales=np.full((count, 3), sigma, np.float32), opacities=np.full(count, opacity, np.float32),
                     sh=np.zeros((count, 1, 3), np.float32))


def join(*parts: Gaussians) -> Gaussians:
    return Gaussians(**{f: np.concatenate([getattr(p, f) for p in parts]) for f in
                        ("means", "quats", "scales", "opacities", "sh")})


def uv_sphere(radius=R, nu=48, nv=96):
    th = np.linspace(0, math.pi, nu + 1)
    ph = np.linspace(0, 2 * math.pi, nv, endpoint=False)
    T, P = np.meshgrid(th, ph, indexing="ij")
    v = radius * np.stack([np.sin(T) * np.sin(P), np.cos(T), np.sin(T) * np.cos(P)], -1).reshape(-1, 3)
    i, j = np.meshgrid(np.arange(nu), np.arange(nv), indexing="ij")
    a, b = i * nv + j, i * nv + (j + 1) % nv
    tris = np.concatenate([np.stack([a, a + nv, b], -1).reshape(-1, 3), np.stack([b, a + nv, b + nv], -1).reshape(-1, 3)])
    return v, tris


def write_obj(path, vertices, triangles):
    lines = [f"v {x:.9g} {y:.9g} {z:.9g}" for x, y, z in vertices]
    lines += [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in triangles]
    path.write_text("\n".join(lines) + "\n")
    return path


@pytest.fixture(scope="module")
def sphere_files(tmp_path_factory):
    folder = tmp_path_factory.mktemp("sphere")
    save_ply(folder / "sphere.ply", sphere_gaussians())
    write_obj(folder / "sphere.obj", *uv_sphere())
    return folder


# ------------------------------------------------------------------ metrics with known answers

def test_opaque_sphere_with_its_mesh_has_nothing_outside_and_smear_only_at_the_rim(sphere_files):
    r = diagnose_avatars([sphere_files / "sphere.ply"], mesh=sphere_files / "sphere.obj", options=SMALL)
    for view in r["views"]:
        assert view["O_alpha"] < 1e-3 and view["G_m"] < 1e-3 and view["G_d"] < 1e-4
        assert view["S_alpha"] > 0
    # the smear lies at the rim: none of it more than 3 px inside the silhouette
    from lenticalib.render.renderers import render

    g = sphere_gaussians()
    arc, _ = diagnose_cameras(mesh_box(*uv_sphere()), SMALL)
    rgba = render(g, arc.viewmats, arc.K, arc.width, arc.height)
    alpha = rgba[..., 3]
    masks = mesh_masks(*uv_sphere(), arc.viewmats, arc.K, arc.width, arc.height)
    for a, m in zip(alpha, masks):
        import cv2

        interior = cv2.erode(m.astype(np.uint8), np.ones((7, 7), np.uint8)).astype(bool)
        smear = 4 * a * (1 - a)
        assert smear[interior].max() < 0.02
        assert smear[~interior].sum() > 20 * smear[interior].sum()


def footprint_mass(g: Gaussians, viewmat, K) -> float:
    """The alpha mass (sum over pixels) of isotropic, non-overlapping Gaussians in one view: each
    o 2 pi sqrt(det S) (1 - 1/(255 o)), with S = sigma^2 J J^T + EPS2D I its projected covariance
    (px^2) and the alpha floor 1/255 cutting the footprint at q = 2 ln(255 o)."""
    total = 0.0
    for mean, sigma, o in zip(g.means.astype(np.float64), g.scales[:, 0].astype(np.float64), g.opacities):
        x, y, z = viewmat[:3, :3] @ mean + viewmat[:3, 3]
        fx, fy = K[0, 0], K[1, 1]
        J = np.array([[fx / z, 0, -fx * x / z ** 2], [0, fy / z, -fy * y / z ** 2]])
        S = sigma ** 2 * J @ J.T + EPS2D * np.eye(2)
        total += o * 2 * math.pi * math.sqrt(np.linalg.det(S)) * (1 - ALPHA_MIN / o)
    return total


def test_faint_gaussians_outside_the_dilated_mask_give_their_analytic_alpha_mass(tmp_path, sphere_files):
    sphere = sphere_gaussians()
    ring = faint_ring(1.3 * R, 24, 0.0025, 0.45)
    save_ply(tmp_path / "shell.ply", join(sphere, ring))
    options = DiagnoseOptions(n_views=3, view_size=(640, 360))
    alone = diagnose_avatars([sphere_files / "sphere.ply"], mesh=sphere_files / "sphere.obj", options=options)
    r = diagnose_avatars([tmp_path / "shell.ply"], mesh=sphere_files / "sphere.obj", options=options)
    arc, _ = diagnose_cameras(mesh_box(*uv_sphere()), options)
    from lenticalib.render.renderers import render

    sphere_mass = render(sphere, arc.viewmats, arc.K, arc.width, arc.height)[..., 3].sum(axis=(1, 2))
    for k, view in enumerate(r["views"]):
        shell = footprint_mass(ring, arc.viewmats[k], arc.K[k])
        expected = (alone["views"][k]["O_alpha"] * sphere_mass[k] + shell) / (sphere_mass[k] + shell)
        assert view["O_alpha"] == pytest.approx(expected, rel=0.05), (k, view["O_alpha"], expected)
        assert expected > 0.01  # the shell is not lost in the sphere's own share


def test_colour_saturated_only_on_the_alpha_boundary_gives_the_first_term_of_F_c():
    H, W = 120, 160
    yy, xx = np.mgrid[0:H, 0:W]
    disc = (xx - 80) ** 2 + (yy - 60) ** 2 <= 40 ** 2
    alpha = disc.astype(np.float64)
    colour = np.where(disc[..., None], 0.6, 0.0) * np.ones(3)
    boundary = alpha_boundary(alpha)
    colour[boundary] = [0.9, 0.1, 0.1]   # saturation 8/9 on B only
    crop = Crop(10, 5, 150, 115)
    m = view_metrics(colour, alpha, disc, crop)
    assert m["F_c"] == pytest.approx(0.45 * 8 / 9, abs=1e-6)
    assert m["O_alpha"] == 0 and m["S_alpha"] == 0 and m["S_n"] == 0
    # saturate one pixel inside instead: the boundary term drops out, nothing else changes F_c
    colour[boundary] = 0.6
    colour[60, 80] = [0.9, 0.1, 0.1]
    assert view_metrics(colour, alpha, disc, crop)["F_c"] == 0.0


def test_mirror_symmetric_avatar_has_equal_metrics_at_minus_and_plus_25_degrees(tmp_path):
    rng = np.random.default_rng(7)
    half = faint_ring(1.3 * R, 12, 0.0025, 0.3)
    half.means = half.means[half.means[:, 0] > 0]
    n = len(half.means)
    back = rng.uniform([0.02, -0.12, -0.15], [0.12, -0.05, -0.1], (20, 3))   # ghosts behind, on the +x side
    side = Gaussians(means=np.concatenate([half.means, back]).astype(np.float32),
                     quats=np.tile([1.0, 0, 0, 0], (n + 20, 1)).astype(np.float32),
                     scales=np.full((n + 20, 3), 0.004, np.float32),
                     opacities=rng.uniform(0.1, 0.6, n + 20).astype(np.float32),
                     sh=np.repeat(((rng.uniform(0.1, 0.9, (n + 20, 3)) - 0.5) / SH_C0)[:, None, :], 1, 1).astype(np.float32))
    mirrored = Gaussians(means=side.means * np.array([-1, 1, 1], np.float32), quats=side.quats, scales=side.scales,
                         opacities=side.opacities, sh=side.sh)
    save_ply(tmp_path / "sym.ply", join(sphere_gaussians(), side, mirrored))
    write_obj(tmp_path / "sphere.obj", *uv_sphere())
    r = diagnose_avatars([tmp_path / "sym.ply"], mesh=tmp_path / "sphere.obj", options=SMALL)
    left, right = r["side"]["views"]
    assert (left["yaw_deg"], right["yaw_deg"]) == (-25.0, 25.0)
    assert left["O_alpha"] > 0.005  # the ghosts are seen
    for m in ("O_alpha", "G_m", "G_d", "S_n", "S_alpha", "F_c", "E_c"):
        assert left[m] == pytest.approx(right[m], rel=0.02, abs=1e-6), m


# ------------------------------------------------------------------ mesh, mask, crop

def test_mesh_mask_marks_the_pixel_centres_inside_the_projected_triangles():
    # a square 0.2 m wide 1 m in front of a camera with f = 100 px: 20 px wide, centred on (49.5, 39.5)
    K = np.array([[[100.0, 0, 49.5], [0, 100.0, 39.5], [0, 0, 1]]])
    view = np.eye(4)[None]
    v = np.array([[-0.1, -0.1, 1], [0.1, -0.1, 1], [0.1, 0.1, 1], [-0.1, 0.1, 1]])
    mask = mesh_masks(v, np.array([[0, 1, 2], [0, 2, 3]]), view, K, 100, 80)[0]
    ys, xs = np.nonzero(mask)
    assert (xs.min(), xs.max(), ys.min(), ys.max()) == (40, 59, 30, 49)   # centres 39.5 +- 10
    assert mask.sum() == 400
    # a triangle reaching behind the camera is clipped at the near plane: it covers the wedge above
    # its front edge (row 29.5), widening by a pixel a row (corners 505 px out at 45 degrees, where the
    # plane z = 0.01 cuts its sides); projected unclipped, its third corner
    # (0, 0, -1) would land on the image centre (49.5, 39.5) and fill rows below the edge instead
    behind = np.array([[-0.1, -0.1, 1], [0.1, -0.1, 1], [0.0, 0.0, -1]])
    m2 = mesh_masks(behind, np.array([[0, 1, 2]]), view, K, 100, 80)[0]
    assert m2[29, 40:60].all() and m2[0, 11:89].all() and not m2[0, :9].any() and not m2[30:].any()


def test_crop_rule_and_dilation():
    masks = np.zeros((2, 100, 200), bool)
    masks[0, 40:60, 50:70] = True
    masks[1, 45:65, 120:150] = True
    crop = crop_rule(masks)
    grow = max(math.ceil(0.25 * 100), DILATION_PX + 2)
    assert (crop.x0, crop.x1, crop.y0, crop.y1) == (50 - grow, 150 + grow, max(40 - grow, 0), 65 + grow)
    one = np.zeros((41, 41), bool)
    one[20, 20] = True
    d = dilate(one)
    assert d.sum() == sum(1 for y in range(-9, 10) for x in range(-9, 10) if x * x + y * y <= 81)


def test_mesh_files_obj_quads_and_negative_indices_and_ply(tmp_path):
    (tmp_path / "q.obj").write_text("v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvt 0 0\nf 1/1 2/1 3/1 4/1\nf -4 -2 -1\n")
    m = load_mesh_file(tmp_path / "q.obj")
    assert m.triangles.tolist() == [[0, 1, 2], [0, 2, 3], [0, 2, 3]]
    import plyfile

    vert = np.array([(0, 0, 0), (1, 0, 0), (0, 1, 0)], dtype=[("x", "f4"), ("y", "f4"), ("z", "f4")])
    face = np.array([([0, 1, 2],)], dtype=[("vertex_indices", "i4", (3,))])
    plyfile.PlyData([plyfile.PlyElement.describe(vert, "vertex"), plyfile.PlyElement.describe(face, "face")]).write(
        str(tmp_path / "t.ply"))
    assert load_mesh_file(tmp_path / "t.ply").triangles.tolist() == [[0, 1, 2]]


def test_a_mesh_must_fit_the_avatars_box():
    box = (np.array([-0.1, -0.2, -0.1]), np.array([0.1, 0.15, 0.12]))
    check_mesh_fits(box, (box[0] * 1.1, box[1] * 0.95), "m.obj")
    for other in ((box[0] * 1000, box[1] * 1000), (box[0] + 0.3, box[1] + 0.3)):
        with pytest.raises(InputError, match="does not fit"):
            check_mesh_fits(other, box, "m.obj")


# ------------------------------------------------------------------ the rig's mesh

def test_rig_mesh_is_posed_exactly_like_the_gaussians(tmp_path):
    from lenticalib.render.avatar.demo_avatar import demo_avatar_arrays
    from lenticalib.render.avatar.rig_file import load_rig, rig_from_arrays, save_rig

    arrays = demo_avatar_arrays(seed=3, count=3000)
    arrays.pop("part_names")
    # a mesh whose vertices are the Gaussians' centres, with their weights and blendshapes
    G = len(arrays["means"])
    arrays.update(mesh_vertices=arrays["means"], mesh_triangles=np.arange(G - G % 3).reshape(-1, 3),
                  mesh_skin_weights=arrays["skin_weights"], mesh_blend_index=arrays["blend_index"],
                  mesh_blend_shape=arrays["blend_shape"], mesh_blend_pos=arrays["blend_pos"])
    save_rig(tmp_path / "r.npz", rig_from_arrays(arrays))
    rig = load_rig(tmp_path / "r.npz")
    rng = np.random.default_rng(0)
    c = np.zeros(rig.control_dim, np.float32)
    c[:10] = rng.uniform(0, 1, 10)
    for group, scale in (("jaw", 0.2), ("neck", 0.2), ("head", 0.3), ("translation", 0.01), ("eyes", 0.2)):
        s = rig.layout.slice(group)
        c[s] = rng.uniform(-scale, scale, s.stop - s.start)
    posed = rig.pose_mesh(c).numpy()
    assert np.abs(posed - rig.deform(c).means.numpy()).max() < 1e-6
    assert np.abs(posed - arrays["means"]).max() > 0.01   # it moved


def test_demo_mesh_lies_on_the_demo_gaussians_surfaces():
    from scipy.spatial import cKDTree

    from lenticalib.render.avatar.demo_avatar import demo_avatar_arrays

    a = demo_avatar_arrays(seed=0, count=20000)
    skin = a["part_names"] == "skin"
    tree = cKDTree(a["mesh_vertices"])
    d, _ = tree.query(a["means"][skin])
    assert np.percentile(d, 99) < 0.003   # every skin Gaussian within a grid cell of the mesh
    # and the mesh does not stray from the avatar: where the mask is, the avatar is opaque
    from lenticalib.render.renderers import render
    from lenticalib.render.avatar.rig_file import rig_from_arrays

    rig = rig_from_arrays({k: v for k, v in a.items() if k != "part_names"})
    vertices = rig.pose_mesh(rig.neutral_controls()).numpy()
    triangles = rig.mesh.triangles
    arc, _ = diagnose_cameras(mesh_box(vertices, triangles), SMALL)
    alpha = render(rig.canonical.to_numpy(), arc.viewmats, arc.K, arc.width, arc.height)[..., 3]
    masks = mesh_masks(vertices, triangles, arc.viewmats, arc.K, arc.width, arc.height)
    assert (masks & (alpha < 0.5)).sum() < 0.01 * masks.sum()
    # the hair (outside the mesh, as on FLAME) is the rest: 16 % here; a missing part (the neck, the
    # collar, the ears) would be more than 20 %
    assert (masks & (alpha > 0.5)).sum() > 0.8 * (alpha > 0.5).sum()


# ------------------------------------------------------------------ the command

def test_diagnose_command_table_json_and_report(cli, tmp_path, sphere_files):
    code, out, err = cli("avatar", "diagnose", sphere_files / "sphere.ply", "--mesh", sphere_files / "sphere.obj",
                         "--views", 5, "--view-size", "320x180", "--report", tmp_path / "rep")
    assert code == 0, err
    assert "-25.0 deg" in out and "+25.0 deg" in out and "worst view" in out
    files = sorted(p.name for p in (tmp_path / "rep").iterdir())
    assert files == ["sphere-metrics.png", "sphere-sides.png", "sphere.json"]
    from lenticalib.core.figures import read_figure_record

    record = read_figure_record(tmp_path / "rep" / "sphere-metrics.png")
    assert record["title"].startswith("Side-view diagnostics") and all(a["xlabel"] for a in record["axes"][:7])
    doc = json.loads((tmp_path / "rep" / "sphere.json").read_text())
    assert doc["format"] == "lenticalib.avatar-diagnostics" and doc["provenance"]["inputs"]
    code, out, err = cli("avatar", "diagnose", sphere_files / "sphere.ply", "--mesh", sphere_files / "sphere.obj",
                         "--views", 4, "--view-size", "320x180", "--json")
    assert code == 0, err
    result = json.loads(out)
    assert len(result["views"]) == 4 and set(result["views"][0]) == {"view", "yaw_deg", "O_alpha", "G_m", "G_d",
                                                                     "S_n", "S_alpha", "F_c", "E_c"}
    assert result["crop"] and result["mask_source"].startswith("mesh file")
    assert [v["yaw_deg"] for v in result["side"]["views"]] == [-25.0, 25.0]   # rendered besides the arc


def test_several_avatars_one_row_each_with_best_marked(cli, tmp_path, sphere_files):
    save_ply(tmp_path / "ghost.ply", join(sphere_gaussians(), faint_ring(1.3 * R, 24, 0.0025, 0.3)))
    code, out, err = cli("avatar", "diagnose", sphere_files / "sphere.ply", tmp_path / "ghost.ply", "--mesh",
                         sphere_files / "sphere.obj", "--views", 3, "--view-size", "320x180")
    assert code == 0, err
    rows = {line.split()[0]: line for line in out.splitlines() if line.startswith(("sphere.ply", "ghost.ply"))}
    o_sphere, o_ghost = (rows[n].split()[1] for n in ("sphere.ply", "ghost.ply"))
    assert o_sphere.endswith("*") and o_ghost.endswith("+")


def test_bad_input_is_one_line_before_rendering(cli, tmp_path, sphere_files):
    v, t = uv_sphere()
    cases = {
        "another avatar's mesh": (write_obj(tmp_path / "big.obj", v * 1000, t), "does not fit"),
        "no triangles": (tmp_path / "points.obj", "no triangles"),
    }
    (tmp_path / "points.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\n")
    for what, (mesh, message) in cases.items():
        code, out, err = cli("avatar", "diagnose", sphere_files / "sphere.ply", "--mesh", mesh, "--views", 3)
        assert code == 2 and out == "", what
        assert len(err.strip().splitlines()) == 1 and message in err and str(mesh) in err, (what, err)
    code, out, err = cli("avatar", "diagnose", sphere_files / "sphere.ply", "--views", 3)
    assert code == 2 and len(err.strip().splitlines()) == 1 and "carries no mesh" in err and "--mesh" in err
    code, out, err = cli("avatar", "diagnose", sphere_files / "sphere.ply", "--mesh", sphere_files / "sphere.obj",
                         "--controls", "demo")
    assert code == 2 and "static avatar" in err and "--controls" in err


def test_a_rig_is_diagnosed_in_the_pose_its_controls_give(cli, tmp_path):
    from lenticalib.render.avatar.demo_avatar import make_demo_avatar
    from lenticalib.render.avatar.rig_file import save_rig

    save_rig(tmp_path / "demo.npz", make_demo_avatar(seed=1, count=4000))
    args = ("avatar", "diagnose", tmp_path / "demo.npz", "--views", 3, "--view-size", "320x180", "--json")
    code, out, err = cli(*args)
    assert code == 0, err
    rest = json.loads(out)
    assert rest["controls"] is None and "canonical pose" in rest["mask_source"]
    code, out, err = cli(*args, "--controls", "demo", "--frame", 45)
    assert code == 0, err
    demo = json.loads(out)
    assert demo["controls"] == {"source": "demo", "frame": 45, "t": 1.5} and "the controls" in demo["mask_source"]
    # a pose far from the canonical one: head turned 0.6 rad, moved 5 cm sideways; the mesh moves with
    # it, so the outside-support share stays that of the hair (a still mesh would leave the head outside)
    from lenticalib.render.avatar.rig import DEFAULT_LAYOUT

    pose = np.zeros((2, DEFAULT_LAYOUT.dim), np.float32)
    pose[:, DEFAULT_LAYOUT.slice("head").start + 1] = 0.6
    pose[:, DEFAULT_LAYOUT.slice("translation").start] = 0.05
    np.savez(tmp_path / "c.npz", t=np.array([0.0, 1.0]), controls=pose)
    code, out, err = cli(*args, "--controls", tmp_path / "c.npz", "--frame", 1)
    assert code == 0, err
    turned = json.loads(out)
    assert turned["controls"]["source"] == str(tmp_path / "c.npz")
    assert turned["side"]["mean"]["O_alpha"] < 1.5 * rest["side"]["mean"]["O_alpha"] + 0.01
    code, out, err = cli(*args, "--controls", tmp_path / "c.npz", "--frame", 2)
    assert code == 2 and "--frame" in err and "past the 2 samples" in err
