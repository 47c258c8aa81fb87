"""Animated avatars: the rig file and deformer, drivers, control sources, the demo avatar.

Expected poses are recomputed here in numpy (Rodrigues rotations about the documented pivots),
independently of the torch deformer.  CPU only, fixed seeds; one 100k demo avatar per module.
"""

from __future__ import annotations

import io
import json
import socket
import time

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from lenticalib.core.errors import BackendUnavailableError, InputError  # noqa: E402
from lenticalib.render.controls.streams import (DEMO_JAW_RAD, DEMO_YAW_DEG, demo_controls,  # noqa: E402
                                               open_text_stream, open_udp)
from lenticalib.render.controls.files import ControlTrack, load_controls
from lenticalib.render.controls.sources import open_controls  # noqa: E402
from lenticalib.render.avatar.demo_avatar import DEMO_EXPRESSIONS, make_demo_avatar  # noqa: E402
from lenticalib.render.avatar.demo_avatar_parts import DEMO_BONES  # noqa: E402
from lenticalib.render.avatar.drivers import load_driver  # noqa: E402
from lenticalib.render.avatar.gaussians import SH_C0, Gaussians  # noqa: E402
from lenticalib.render.avatar.rig import DEFAULT_LAYOUT  # noqa: E402
from lenticalib.render.avatar.rig import envelope_arrays  # noqa: E402
from lenticalib.render.avatar.rig_file import load_rig, rig_from_arrays, save_rig  # noqa: E402

L = DEFAULT_LAYOUT
D = L.dim
JAW, NECK, HEAD, EYES, LIDS, TRANS = (L.slice(g).start for g in ("jaw", "neck", "head", "eyes", "eyelids",
                                                                 "translation"))


def rodrigues(v):
    v = np.asarray(v, dtype=np.float64)
    th = np.linalg.norm(v)
    if th < 1e-15:
        return np.eye(3)
    k = v / th
    K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + np.sin(th) * K + (1 - np.cos(th)) * K @ K


def qmat(q):
    q = np.asarray(q, dtype=np.float64)
    q = q / np.linalg.norm(q, axis=-1, keepdims=True)
    w, x, y, z = np.moveaxis(q, -1, 0)
    return np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y),
                     2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x),
                     2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
                    -1).reshape(q.shape[:-1] + (3, 3))


def one_line(exc_info) -> str:
    text = str(exc_info.value)
    assert "\n" not in text, text
    return text


def controls(**groups) -> torch.Tensor:
    c = torch.zeros(D)
    for name, values in groups.items():
        s = L.slice(name)
        c[s.start:s.start + len(values)] = torch.tensor(values, dtype=torch.float32)
    return c


# ------------------------------------------------------------------ a small synthetic rig

def small_arrays(G=40, K=4, seed=0):
    rng = np.random.default_rng(seed)
    q = rng.normal(size=(G, 4))
    weights = np.zeros((G, 5), np.float32)
    weights[0:10, 2] = 1.0          # jaw
    weights[10:20, 1] = 1.0         # head
    weights[20:25, 3] = 1.0         # eye_l
    weights[25:30, 2] = 0.5         # half jaw, half rest
    weights[30:40, 0] = 0.3         # neck and head
    weights[30:40, 1] = 0.7
    idx = np.r_[0:15, 10:25, 20:25]
    shape = np.r_[np.zeros(15), np.ones(15), np.full(5, 2)].astype(np.int32)
    names = list(L.default_names())
    return {
        **envelope_arrays(),
        "means": rng.uniform(-0.1, 0.1, (G, 3)).astype(np.float32), "quats": q.astype(np.float32),
        "log_scales": rng.uniform(-7, -5, (G, 3)).astype(np.float32),
        "opacity_logits": rng.uniform(-2, 4, G).astype(np.float32),
        "sh": rng.normal(0, 0.5, (G, K, 3)).astype(np.float32),
        "control_groups": np.array(L.names), "control_sizes": np.array([s for _, s in L.groups], np.int32),
        "control_dim": np.array(D, np.int32), "control_names": np.array(names),
        "blend_controls": np.array([0, 1, LIDS], np.int32), "blend_index": idx.astype(np.int32),
        "blend_shape": shape, "blend_pos": rng.normal(0, 0.003, (len(idx), 3)).astype(np.float32),
        "blend_rot": rng.normal(0, 0.05, (len(idx), 3)).astype(np.float32),
        "blend_color": rng.normal(0, 0.1, (len(idx), 3)).astype(np.float32),
        "bone_names": np.array(DEMO_BONES), "bone_parents": np.array([-1, 0, 1, 1, 1], np.int32),
        "bone_pivots": np.array([[0, -0.17, -0.02], [0, -0.06, -0.02], [0, 0, 0], [0.03, 0.03, 0.07],
                                 [-0.03, 0.03, 0.07]], np.float32),
        "bone_controls": np.array([NECK, -1, JAW, EYES, EYES + 3], np.int32), "skin_weights": weights,
        "pose_pivot": np.array([0, -0.05, -0.01], np.float32), "pose_controls": np.array([HEAD, TRANS], np.int32),
        "provenance": np.array(json.dumps({"made_by": "tests/test_rig.py"})),
    }


@pytest.fixture(scope="module")
def small():
    return rig_from_arrays(small_arrays(), source="small")


@pytest.fixture(scope="module")
def demo():
    return make_demo_avatar(seed=0, count=100_000)


def write_npz(path, arrays):
    np.savez(path, **arrays)
    return path


# ------------------------------------------------------------------ rig file

def test_round_trip(tmp_path, small):
    path = tmp_path / "rig.npz"
    save_rig(path, small)
    back = load_rig(path)
    a, b = small.to_arrays(), back.to_arrays()
    assert set(a) == set(b)
    for name in a:
        if a[name].dtype.kind == "f":
            np.testing.assert_allclose(a[name], b[name], atol=2e-5, err_msg=name)
        else:
            np.testing.assert_array_equal(a[name], b[name], err_msg=name)
    c = torch.from_numpy(np.random.default_rng(1).normal(0, 0.2, D).astype(np.float32))
    g1, g2 = small.deform(c), back.deform(c)
    for f in ("means", "quats", "scales", "opacities", "sh"):
        np.testing.assert_allclose(getattr(g1, f).numpy(), getattr(g2, f).numpy(), atol=1e-5, err_msg=f)
    assert back.provenance == {"made_by": "tests/test_rig.py"}


def test_a_saved_rig_carries_the_envelope_and_rigs_in_the_old_spelling_still_read(tmp_path, small):
    path = tmp_path / "rig.npz"
    save_rig(path, small)
    with np.load(path) as stored:
        assert str(stored["format"]) == "lenticalib.rig" and int(stored["format_version"]) == 1
        assert "version" not in stored.files
    old = small_arrays()
    del old["format_version"]
    old.update({"format": np.array("lenticalib-rig"), "version": np.array(1, np.int32)})  # before the envelope
    back = load_rig(write_npz(tmp_path / "old.npz", old))
    np.testing.assert_array_equal(back.to_arrays()["means"], small.to_arrays()["means"])
    del old["version"]
    no_version = write_npz(tmp_path / "no-version.npz", old)
    with pytest.raises(InputError) as exc:
        load_rig(no_version)
    assert one_line(exc).startswith(f"{no_version}: field 'format_version' is missing")


@pytest.mark.parametrize("rig_name", ["small", "demo"])
def test_zero_controls_give_the_canonical_gaussians(rig_name, request):
    rig = request.getfixturevalue(rig_name)
    g = rig.deform(rig.neutral_controls())
    can = rig.canonical
    np.testing.assert_allclose(g.means.numpy(), can.means.numpy(), atol=1e-6)
    np.testing.assert_allclose(np.abs((g.quats * can.quats).sum(-1).numpy()), 1.0, atol=1e-6)
    for f in ("scales", "opacities", "sh"):
        np.testing.assert_allclose(getattr(g, f).numpy(), getattr(can, f).numpy(), atol=1e-6)
    g.validate("deformed")


def test_jaw_opening_moves_only_jaw_skinned_gaussians_down_and_back(demo):
    jaw = DEMO_BONES.index("jaw")
    w = demo.skin_weights[:, jaw].numpy()
    x0 = demo.canonical.means.numpy()
    g = demo.deform(controls(jaw=[0.2, 0, 0]))
    moved = np.linalg.norm(g.means.numpy() - x0, axis=1)
    assert moved[w == 0].max() < 1e-6
    full = w == 1.0
    assert full.sum() > 1000
    pivot = demo.bone_pivots[jaw].numpy()
    expected = (x0[full] - pivot) @ rodrigues([0.2, 0, 0]).T + pivot
    np.testing.assert_allclose(g.means.numpy()[full], expected, atol=2e-6)
    chin = full & (x0[:, 2] > 0.05) & (x0[:, 1] < -0.06)
    d = g.means.numpy()[chin] - x0[chin]
    assert chin.sum() > 100 and (d[:, 1] < -0.005).all() and (d[:, 2] < 0).all()   # down and back


@pytest.mark.parametrize("rig_name", ["small", "demo"])
def test_head_pose_is_rigid_about_the_pivot(rig_name, request):
    rig = request.getfixturevalue(rig_name)
    rot, trans = [0.05, 0.3, -0.02], [0.01, -0.02, 0.03]
    g = rig.deform(controls(head=rot, translation=trans))
    R = rodrigues(rot)
    pivot = rig.pose_pivot.numpy()
    x0 = rig.canonical.means.numpy().astype(np.float64)
    np.testing.assert_allclose(g.means.numpy(), (x0 - pivot) @ R.T + pivot + trans, atol=2e-6)
    np.testing.assert_allclose(qmat(g.quats.numpy()), R @ qmat(rig.canonical.quats.numpy()), atol=2e-6)


def test_yaw_turns_the_face_towards_plus_x(demo):
    """A positive head yaw (about +y) turns the nose tip towards +x (the viewer's right)."""
    tip = int(np.argmax(demo.canonical.means[:, 2].numpy()))
    g = demo.deform(controls(head=[0, 0.35, 0]))
    assert g.means[tip, 0] > 0.03


def test_neck_and_eye_bones_follow_the_hierarchy(small):
    neck, gaze = [0.1, 0.0, 0.05], [0.0, 0.3, 0.0]
    g = small.deform(controls(neck=neck, eyes=gaze + [0, 0, 0]))
    x0 = small.canonical.means.numpy().astype(np.float64)
    pv = small.bone_pivots.numpy()
    Rn, Re = rodrigues(neck), rodrigues(gaze)
    # head-only Gaussians (10..19): rotated about the neck pivot (the head bone has no control)
    np.testing.assert_allclose(g.means.numpy()[10:20], (x0[10:20] - pv[0]) @ Rn.T + pv[0], atol=2e-6)
    # left-eye Gaussians (20..24, also blendshape-free at zero eyelids): eye rotation, then the neck
    in_eye = (x0[20:25] - pv[3]) @ Re.T + pv[3]
    np.testing.assert_allclose(g.means.numpy()[20:25], (in_eye - pv[0]) @ Rn.T + pv[0], atol=2e-6)
    np.testing.assert_allclose(qmat(g.quats.numpy()[20:25]), Rn @ Re @ qmat(small.canonical.quats.numpy()[20:25]),
                               atol=2e-6)


def test_half_weight_gaussians_get_the_half_rotation(small):
    """Weights 0.5 jaw / 0.5 rest: position halfway (linear blend), rotation the half angle (quaternion blend)."""
    g = small.deform(controls(jaw=[0.4, 0, 0]))
    x0 = small.canonical.means.numpy().astype(np.float64)[25:30]
    pivot = small.bone_pivots.numpy()[2]
    full = (x0 - pivot) @ rodrigues([0.4, 0, 0]).T + pivot
    np.testing.assert_allclose(g.means.numpy()[25:30], 0.5 * (x0 + full), atol=2e-6)
    np.testing.assert_allclose(qmat(g.quats.numpy()[25:30]),
                               rodrigues([0.2, 0, 0]) @ qmat(small.canonical.quats.numpy()[25:30]), atol=2e-6)


def test_blendshapes_are_linear(small, demo):
    for rig, (i, j) in ((small, (0, 1)), (demo, (0, 2))):
        base = rig.canonical
        ei, ej = torch.zeros(D), torch.zeros(D)
        ei[i], ej[j] = 1.0, 1.0
        di = rig.deform(ei).means - base.means
        dj = rig.deform(ej).means - base.means
        dij = rig.deform(0.7 * ei - 1.3 * ej).means - base.means
        np.testing.assert_allclose(dij.numpy(), (0.7 * di - 1.3 * dj).numpy(), atol=2e-6)
        assert di.abs().max() > 1e-3
        ci = rig.deform(ei).sh[:, 0] - base.sh[:, 0]
        cij = rig.deform(2.0 * ei).sh[:, 0] - base.sh[:, 0]
        np.testing.assert_allclose(cij.numpy(), 2 * ci.numpy(), atol=1e-5)
    # the small rig's shape 0 only touches Gaussians 0..14
    d = (small.deform(torch.eye(D)[0]).means - small.canonical.means).abs().sum(1).numpy()
    assert (d[15:] == 0).all() and (d[:15] > 0).all()


def test_blend_rotation_and_colour(small):
    """blend_rot pre-rotates frames by the summed axis-angle; blend_color adds to the DC coefficient."""
    arrays = small_arrays()
    g = small.deform(torch.eye(D)[0] * 0.5)
    n = 15
    rot = 0.5 * arrays["blend_rot"][:n]
    q0 = qmat(small.canonical.quats.numpy()[:10])  # 0..9: jaw-skinned, shape 0 only; the jaw is closed
    np.testing.assert_allclose(qmat(g.quats.numpy()[:10]), np.stack([rodrigues(r) for r in rot[:10]]) @ q0,
                               atol=2e-6)
    np.testing.assert_allclose(g.sh.numpy()[:10, 0], arrays["sh"][:10, 0] + 0.5 * arrays["blend_color"][:10],
                               atol=1e-6)


def test_degree1_sh_turns_with_the_gaussian(small):
    """After a rigid turn R, a Gaussian's colour seen from R d equals its canonical colour seen from d."""
    C1 = 0.4886025119029199
    rot = [0.2, -0.5, 0.1]
    g = small.deform(controls(head=rot))

    def colour(sh, d):  # 3DGS degree-1 basis: -C1 y, C1 z, -C1 x
        return SH_C0 * sh[:, 0] - C1 * d[1] * sh[:, 1] + C1 * d[2] * sh[:, 2] - C1 * d[0] * sh[:, 3]

    d = np.array([0.3, -0.4, 0.87])
    d /= np.linalg.norm(d)
    np.testing.assert_allclose(colour(g.sh.numpy(), rodrigues(rot) @ d), colour(small.canonical.sh.numpy(), d),
                               atol=1e-5)


def test_a_batch_is_the_frames_one_by_one(small):
    C = torch.from_numpy(np.random.default_rng(3).normal(0, 0.2, (4, D)).astype(np.float32))
    batch = small.deform(C)
    assert batch.means.shape == (4, small.count, 3) and batch.opacities.shape == (4, small.count)
    for t in range(4):
        one = small.deform(C[t])
        for f in ("means", "quats", "scales", "opacities", "sh"):
            np.testing.assert_allclose(getattr(batch, f)[t].numpy(), getattr(one, f).numpy(), atol=1e-6)


@pytest.mark.parametrize("shape", [(D - 1,), (D + 1,), (2, 3, D), ()])
def test_wrong_control_length_is_one_line(small, shape):
    with pytest.raises(InputError) as exc:
        small.deform(torch.zeros(shape))
    text = one_line(exc)
    assert text.startswith("controls:") and f"D = {D}" in text
    assert "expression 50, jaw 3, neck 3, head 3, eyes 6, eyelids 2, translation 3" in text


def _drop(name):
    def edit(a):
        del a[name]
    return edit


def _set(name, value):
    def edit(a):
        a[name] = value
    return edit


def _nan(a):
    a["means"] = a["means"].copy()
    a["means"][3, 1] = np.nan


@pytest.mark.parametrize("edit, words", [
    (_drop("skin_weights"), "'skin_weights' is missing"),
    (_drop("means"), "'means' is missing"),
    (_set("quats", np.ones((40, 3), np.float32)), "'quats' has shape (40, 3), expected (40, 4)"),
    (_set("format_version", np.array(2, np.int32)), "field 'format_version': unknown version 2"),
    (_set("format", np.array("something-else")), "field 'format': expected \"lenticalib.rig\", got 'something-else'"),
    (_nan, "'means' holds a non-finite value"),
    (_set("sh", np.zeros((40, 2, 3), np.float32)), "'sh' has shape (40, 2, 3)"),
    (_set("control_dim", np.array(71, np.int32)), "'control_dim' is 71"),
    (_set("blend_index", np.full(35, 40, np.int32)), "'blend_index' holds 40"),
    (_set("bone_parents", np.array([-1, 0, 3, 1, 1], np.int32)), "does not precede it"),
    (_set("skin_weights", np.full((40, 5), 0.5, np.float32)), "summing to at most 1"),
    (_set("pose_controls", np.array([HEAD, D - 1], np.int32)), "'pose_controls' holds"),
    (_set("quats", np.zeros((40, 4), np.float32)), "zero-length quaternion"),
])
def test_malformed_rig_files_are_one_line(tmp_path, edit, words):
    arrays = small_arrays()
    edit(arrays)
    path = write_npz(tmp_path / "bad.npz", arrays)
    with pytest.raises(InputError) as exc:
        load_rig(path)
    text = one_line(exc)
    assert text.startswith(str(path)) and words in text, text


def test_unreadable_rig_files_are_one_line(tmp_path):
    not_zip = tmp_path / "notes.npz"
    not_zip.write_text("hello")
    pickled = tmp_path / "pickled.npz"
    arrays = small_arrays()
    arrays["provenance"] = np.array([{"a": 1}], dtype=object)
    np.savez(pickled, **arrays)
    for path, words in ((not_zip, "not a readable .npz"), (pickled, "pickled"),
                        (tmp_path / "missing.npz", "no such rig file")):
        with pytest.raises(InputError) as exc:
            load_rig(path)
        assert words in one_line(exc) and str(path) in str(exc.value)
    with pytest.raises(InputError) as exc:
        save_rig(tmp_path / "no" / "such" / "rig.npz", rig_from_arrays(small_arrays()))
    assert "does not exist" in one_line(exc)


# ------------------------------------------------------------------ drivers

def test_the_builtin_driver_is_the_rigs_deform(small):
    drive = load_driver("rig", rig=small)
    c = controls(jaw=[0.2, 0, 0], head=[0, 0.1, 0])
    np.testing.assert_array_equal(drive(c, torch.device("cpu")).means.numpy(), small.deform(c).means.numpy())
    assert drive.control_dim == D and drive.layout == L
    with pytest.raises(InputError) as exc:
        drive(torch.zeros(3), "cpu")
    assert "expects (70,)" in one_line(exc)


def test_a_plugin_driver_loads_and_runs():
    for spec in ("tests.avatar_driver_plugin:drive", "tests.avatar_driver_plugin:Namespace.method"):
        drive = load_driver(spec)
        g = drive(torch.tensor([0.5, 0, 0, 0]), "cpu")
        assert isinstance(g, Gaussians) and float(g.means[0, 0]) == 0.5
    assert load_driver("tests.avatar_driver_plugin:drive").control_dim == 4
    with pytest.raises(InputError) as exc:
        load_driver("tests.avatar_driver_plugin:drive")(torch.zeros(5), "cpu")
    assert "expects (4,)" in one_line(exc)
    with pytest.raises(InputError) as exc:
        load_driver("tests.avatar_driver_plugin:bad_return")(torch.zeros(5), "cpu")
    assert "returned dict, expected Gaussians" in one_line(exc)


@pytest.mark.parametrize("spec, error, words", [
    ("nocolon", InputError, "unknown driver 'nocolon'"),
    ("tests.avatar_driver_plugin:", InputError, "bad driver"),
    (":drive", InputError, "bad driver"),
    ("tests.no_such_module_here:drive", BackendUnavailableError, "no module named 'tests.no_such_module_here'"),
    ("tests.avatar_driver_plugin:missing", InputError, "has no attribute 'missing'"),
    ("tests.avatar_driver_plugin:not_callable", InputError, "is a int, not callable"),
    ("tests.avatar_driver_broken:drive", BackendUnavailableError,
     "failed to import: RuntimeError: the FLAME model file is missing"),
    ("rig", InputError, "the built-in driver needs a rig"),
])
def test_bad_driver_specs_are_one_line(spec, error, words):
    with pytest.raises(error) as exc:
        load_driver(spec)
    assert words in one_line(exc), str(exc.value)


# ------------------------------------------------------------------ control files

def _track():
    rng = np.random.default_rng(5)
    t = np.array([0.0, 0.5, 1.0, 2.0])
    c = np.zeros((4, D), np.float32)
    c[:, JAW] = rng.uniform(0, 0.2, 4)
    c[:, HEAD + 1] = rng.uniform(-0.3, 0.3, 4)
    c[:, 3] = rng.uniform(0, 1, 4)
    return t, c


def test_control_files_parse_alike(tmp_path):
    t, c = _track()
    np.savez(tmp_path / "c.npz", t=t, controls=c)
    header = ["t", "jaw.0", "head.1", "expression.3"]
    rows = [",".join(header)] + [f"{ti},{ci[JAW]!r},{ci[HEAD + 1]!r},{ci[3]!r}" for ti, ci in zip(t, c.tolist())]
    (tmp_path / "c.csv").write_text("\n".join(rows) + "\n")
    lines = [json.dumps({"t": ti, "controls": ci}) for ti, ci in zip(t.tolist(), c.tolist())]
    (tmp_path / "c.jsonl").write_text("\n".join(lines) + "\n\n")
    grouped = [json.dumps({"t": ti, "jaw": [ci[JAW], 0, 0], "head": [0, ci[HEAD + 1], 0],
                           "expression": ci[:50]}) for ti, ci in zip(t.tolist(), c.tolist())]
    (tmp_path / "g.jsonl").write_text("\n".join(grouped) + "\n")
    for name in ("c.npz", "c.csv", "c.jsonl", "g.jsonl"):
        track = load_controls(tmp_path / name)
        np.testing.assert_allclose(track.t, t, err_msg=name)
        np.testing.assert_allclose(track.controls, c, atol=1e-7, err_msg=name)
    # the rig's component names work as CSV columns too
    (tmp_path / "n.csv").write_text("t,jaw.x,expression.smile\n0,0.1,0.5\n")
    track = load_controls(tmp_path / "n.csv", names=["expression.smile"] + [f"x{i}" for i in range(1, 50)]
                          + ["jaw.x"] + [f"y{i}" for i in range(20)])
    assert track.controls[0, 0] == 0.5 and track.controls[0, JAW] == pytest.approx(0.1)


def test_a_track_interpolates_and_loops():
    t, c = _track()
    track = ControlTrack(t, c, L)
    ts, v = track.at(0.25)
    assert ts == 0.25 and np.allclose(v, 0.5 * (c[0] + c[1]))
    _, v = track.at(2.0 + 0.25)            # loops over the 2 s duration
    assert np.allclose(v, 0.5 * (c[0] + c[1]))
    _, v = track.at(5.0, loop=False)       # holds the end
    assert np.allclose(v, c[-1])
    assert [tt for tt, _ in track] == list(t)


@pytest.mark.parametrize("name, text, words", [
    ("bad.csv", "t,jaw.0\n0,0.1\n1\n", "bad.csv:3: 1 fields, expected 2"),
    ("bad.csv", "t,jaw.0\n0,0.1\n1,abc\n", "bad.csv:3: column 'jaw.0' is 'abc'"),
    ("bad.csv", "t,jaw.0\n0,0.1\n1,nan\n", "bad.csv:3: column 'jaw.0' is nan"),
    ("bad.csv", "t,jwa.0\n0,0.1\n", "bad.csv:1: unknown control column 'jwa.0'"),
    ("bad.csv", "time,jaw.0\n0,0.1\n", "bad.csv:1: first column is 'time'"),
    ("bad.csv", "t,jaw.0\n1,0.1\n0.5,0.2\n", "bad.csv:3: time 0.5 s comes after 1 s"),
    ("bad.jsonl", '{"t": 0, "controls": [0, 0]}\n', "bad.jsonl:1: 'controls' has 2 values, expected 70"),
    ("bad.jsonl", '{"t": 0, "jaw": [0, 0, 0]}\n\n{"t": 1, "jaw": [0.1]}\n',
     "bad.jsonl:3: group 'jaw' has 1 values, expected 3"),
    ("bad.jsonl", '{"t": 0, "jaw": [0, 0, 0]}\n{"t": 1, "jw": [0, 0, 0]}\n', "bad.jsonl:2: unknown control group 'jw'"),
    ("bad.jsonl", '{"jaw": [0, 0, 0]}\n', "bad.jsonl:1: no time 't'"),
    ("bad.jsonl", '{"t": 0, "jaw": [0, 0, 0]\n', "bad.jsonl:1: not JSON"),
    ("bad.jsonl", '{"t": 0, "controls": [], "jaw": [0, 0, 0]}\n', "mixes 'controls' with other keys"),
    ("bad.txt", "whatever", "unknown control file type '.txt'"),
    # values the avatar cannot use, refused when the file is read (not when play meets them)
    ("bad.jsonl", '{"t": 0, "jaw": [0, 0, 0]}\n{"t": 1, "jaw": [1e39, 0, 0]}\n',
     "bad.jsonl:2: jaw[0] is 1e+39, out of range: float32"),
    ("bad.jsonl", '{"t": 0, "jaw": [1' + "0" * 400 + ', 0, 0]}\n', "bad.jsonl:1: jaw[0] is an integer beyond 1.8e308"),
    ("bad.jsonl", '{"t": 0, "jaw": [' + "7" * 5000 + ', 0, 0]}\n',
     "bad.jsonl:1: not JSON: an integer of more than 4300 digits"),
    ("bad.jsonl", '{"t": 0, "controls": ' + "[" * 50000 + "\n", "bad.jsonl:1: not JSON: nested too deep"),
    ("bad.jsonl", '{"t": 0, "jaw": [0, NaN, 0]}\n', "bad.jsonl:1: jaw[1] is nan, expected a finite number"),
    ("bad.jsonl", '{"t": 1' + "0" * 400 + ', "jaw": [0, 0, 0]}\n', "bad.jsonl:1: time 't' is an integer beyond 1.8e308"),
    ("bad.csv", "t,jaw.0\n0,0.1\n1,-1e39\n", "bad.csv:3: column 'jaw.0' is -1e+39, out of range: float32"),
    ("bad.csv", "t,jaw.0\n1e400,0.1\n", "bad.csv:2: column 't' is inf, expected a finite number"),
])
def test_bad_control_files_name_the_line(tmp_path, name, text, words):
    (tmp_path / name).write_text(text)
    with pytest.raises(InputError) as exc:
        load_controls(tmp_path / name)
    assert words in one_line(exc), str(exc.value)
    if "expected 70" in words or "expected 3" in words:
        assert "expression 50, jaw 3" in str(exc.value)


def test_bad_control_npz_is_one_line(tmp_path):
    np.savez(tmp_path / "a.npz", t=np.arange(3.0), controls=np.zeros((3, D - 2)))
    np.savez(tmp_path / "b.npz", controls=np.zeros((3, D)))
    c = np.zeros((3, D))
    c[2, 5] = np.inf
    np.savez(tmp_path / "c.npz", t=np.arange(3.0), controls=c)
    c[2, 5] = 0.0
    c[1, 3] = 1e39  # finite in float64, inf in float32: refused now, not when play meets it
    np.savez(tmp_path / "d.npz", t=np.arange(3.0), controls=c)
    for name, words in (("a.npz", "'controls' has shape (3, 68), expected (3, 70)"), ("b.npz", "'t' is missing"),
                        ("c.npz", "c.npz row 2: controls[5] is inf"),
                        ("d.npz", "d.npz row 1: controls[3] is 1e+39, out of range: float32")):
        with pytest.raises(InputError) as exc:
            load_controls(tmp_path / name)
        assert words in one_line(exc), str(exc.value)


# ------------------------------------------------------------------ live streams

def _wait(pred, timeout=3.0):
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if pred():
            return True
        time.sleep(0.01)
    return False


def test_udp_stream_gives_the_latest_and_counts_bad_lines():
    with open_udp("udp://127.0.0.1:0") as src:
        assert src.latest() == (None, pytest.approx(np.zeros(D)))
        tx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        try:
            tx.sendto(b'{"t": 1.0, "jaw": [0.1, 0, 0]}\n{"t": 1.5, "jaw": [oops]}', src.address)
            assert _wait(lambda: src.stats["received"] == 1 and src.stats["bad"] == 1)
            tx.sendto(b'{"t": 2.0, "head": [0, 0.2, 0]}', src.address)
            tx.sendto(b'\xff\xfe', src.address)
            assert _wait(lambda: src.stats["received"] == 2 and src.stats["bad"] == 2)
        finally:
            tx.close()
        t, c = src.latest()
        assert t == 2.0 and c[HEAD + 1] == pytest.approx(0.2) and c[JAW] == 0.0
        assert "line 4: not UTF-8" in src.stats["last_error"] and "\n" not in src.stats["last_error"]


def test_text_stream_reads_lines_in_the_background():
    lines = io.StringIO('{"controls": ' + json.dumps([0.0] * D) + '}\nnot json\n{"t": 3, "eyelids": [1, 1]}\n')
    src = open_text_stream(lines, L, name="stdin")
    assert _wait(lambda: src.stats["ended"])
    t, c = src.latest()
    assert t == 3 and c[LIDS] == 1.0
    assert src.stats == {"received": 2, "bad": 1, "ended": True, "failed": None,
                         "last_error": "stdin line 2: not JSON: Expecting value at column 1"}
    src.close()


def test_bad_udp_address_is_one_line():
    with pytest.raises(InputError) as exc:
        open_controls("udp://nohost")
    assert "bad UDP address" in one_line(exc)
    assert "udp://127.0.0.1:9000" in str(exc.value) and "0.0.0.0" not in str(exc.value)  # this machine only


# ------------------------------------------------------------------ demo motion

def test_demo_motion_is_deterministic_and_bounded():
    ts = np.arange(0, 30, 1 / 60)
    a = np.stack([demo_controls(t) for t in ts])
    b = np.stack([demo_controls(t) for t in ts])
    np.testing.assert_array_equal(a, b)
    assert np.isfinite(a).all() and a.dtype == np.float32
    yaw = np.degrees(a[:, HEAD + 1])
    assert np.abs(yaw).max() <= DEMO_YAW_DEG + 1e-4 and yaw.max() > 19 and yaw.min() < -19
    jaw = a[:, JAW]
    assert jaw.min() >= 0 and jaw.max() <= DEMO_JAW_RAD + 1e-6 and jaw.max() > 0.1
    lids = a[:, LIDS:LIDS + 2]
    assert lids.min() >= 0 and lids.max() <= 1
    blinks = np.flatnonzero((lids[1:, 0] > 0.5) & (lids[:-1, 0] <= 0.5))
    assert 6 <= len(blinks) <= 10     # every 3.7 s over 30 s
    assert np.abs(a[:, TRANS:TRANS + 3]).max() <= 0.005 + 1e-7
    assert open_controls("demo").latest(1.25)[0] == 1.25


# ------------------------------------------------------------------ the demo avatar

def test_demo_avatar_is_a_head(demo):
    assert 90_000 <= demo.count <= 110_000
    g = demo.canonical.to_numpy()
    lo, hi = g.means.min(0), g.means.max(0)
    size = hi - lo
    assert 0.16 < size[0] < 0.24 and 0.30 < size[1] < 0.40 and 0.18 < size[2] < 0.28, size
    head = g.means[:, 1] > -0.12
    assert 0.22 < np.ptp(g.means[head, 1]) < 0.28
    assert np.abs(g.means.mean(0)).max() < 0.05
    # ears stick out beyond the cheeks on both sides
    x, y = g.means[:, 0], g.means[:, 1]
    cheek = np.abs(x[(y > -0.06) & (y < -0.04)]).max()
    band = (y > -0.03) & (y < 0.045)
    assert ((x > cheek + 0.02) & band).sum() > 500 and ((x < -cheek - 0.02) & band).sum() > 500
    # the nose is the front-most point, on the midline
    tip = np.argmax(g.means[:, 2])
    assert abs(g.means[tip, 0]) < 0.01 and g.means[tip, 2] > 0.11
    # hair (on top) is darker than skin (the cheeks, in front)
    rgb = np.clip(0.5 + SH_C0 * g.sh[:, 0], 0, 1)
    luma = rgb @ [0.3, 0.59, 0.11]
    top = y > 0.125
    cheeks = (g.means[:, 2] > 0.06) & (y > -0.02) & (y < 0.0) & (np.abs(x) > 0.02) & (np.abs(x) < 0.05)
    assert luma[top].mean() < 0.4 * luma[cheeks].mean()
    # surfaces: small, flat, opaque Gaussians
    assert np.median(g.scales.max(1)) < 0.004 and np.median(g.scales.min(1)) < 0.0005
    # and none is a streak: a sphere's pole once gave one Gaussian a 0.49 m axis, a line across every view
    assert g.scales.max() < 0.015, np.sort(g.scales.max(1))[-3:]
    assert np.median(g.opacities) > 0.9
    assert g.sh_degree == 0
    names = demo.control_names
    assert names[:len(DEMO_EXPRESSIONS)] == tuple(f"expression.{e}" for e in DEMO_EXPRESSIONS)
    assert demo.blendshape_count == len(DEMO_EXPRESSIONS) + 2


def test_demo_eyes_turn_and_blink(demo):
    eye = DEMO_BONES.index("eye_l")
    on_eye = demo.skin_weights[:, eye].numpy() == 1
    rgb = np.clip(0.5 + SH_C0 * demo.canonical.sh[:, 0].numpy(), 0, 1)
    assert on_eye.sum() > 1000 and rgb[on_eye].max(1).max() > 0.85 and rgb[on_eye].max(1).min() < 0.1
    g = demo.deform(controls(eyes=[0, 0.3, 0, 0, 0, 0]))
    moved = np.linalg.norm(g.means.numpy() - demo.canonical.means.numpy(), axis=1) > 1e-7
    np.testing.assert_array_equal(moved, on_eye & moved)   # only the left eye moves
    assert moved.sum() > 500
    g = demo.deform(controls(eyelids=[1, 0]))
    d = (g.means - demo.canonical.means).numpy()
    lid = np.abs(d).max(1) > 1e-6
    assert lid.sum() > 200 and (demo.canonical.means.numpy()[lid, 0] > 0).all() and d[lid, 1].mean() < -0.003


def test_demo_avatar_is_reproducible():
    a = make_demo_avatar(seed=3, count=4000).to_arrays()
    b = make_demo_avatar(seed=3, count=4000).to_arrays()
    c = make_demo_avatar(seed=4, count=4000).to_arrays()
    assert a.keys() == b.keys()
    for k in a:
        if k != "provenance":
            np.testing.assert_array_equal(a[k], b[k], err_msg=k)
    assert not np.array_equal(a["means"], c["means"])
    assert len(a["means"]) == 4000
