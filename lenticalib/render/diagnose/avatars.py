"""``diagnose_avatars``: is an avatar fit for the panel?  The LentiAvatar side-view diagnostics
(:mod:`.side_metrics`) of every view along the view cone, for one avatar or several side by side.

For each avatar, in this order (every check of every avatar comes before the first render):

1. The avatar (a static 3DGS PLY or a rig ``.npz``), its pose (``controls``: None for the
   canonical pose, "demo" for the built-in motion, or a control file; ``frame`` K picks its
   K-th sample, the demo's time K / :data:`DEMO_FPS`) and its mesh: the mesh file given
   (``mesh``, OBJ or PLY in the avatar's frame, taken as it is) or the rig's own mesh posed by
   the same controls (:mod:`.rig_mesh`).  A mesh whose box does not fit the avatar's Gaussians
   (:func:`~.camera_models.robust_box`, 1st to 99th percentile of their centres, so floaters do
   not widen it; the box render and play frame an avatar on) is refused
   (:func:`~.mesh.check_mesh_fits`).
2. The cameras: the camera model (``arc``, the LentiAvatar arc, by default) framed on the
   *mesh's* box, so that avatars of one subject are seen by the same cameras whatever their
   floaters; ``n_views`` views over ``yaw_range_deg``.  When the arc has no view at -25 or +25
   degrees (the paper's side views) two more are rendered there.
3. Every view rendered with alpha by the renderer named (the registry: ``cpu``, ``gl``,
   ``gsplat``), the mesh mask of every view (:func:`~.mesh_raster.mesh_masks`), one crop for
   all of them (:func:`~.side_metrics.crop_rule`), the seven metrics per view.

The result (:func:`diagnose_avatars`) is a dict: for one avatar its record (below), for several
``{"avatars": [record, ...], "best": {metric: [best index, second index]}}``.  A record:

    avatar, kind, mask_source, controls, renderer, cameras, view_size, crop
    views       [{"view", "yaw_deg", "O_alpha", "G_m", "G_d", "S_n", "S_alpha", "F_c", "E_c"}, ...]
    side        {"views": [the -25 and +25 degree records], "mean": {metric: mean of the two}}
    worst       {metric: {"yaw_deg", "value"}}: the worst view of the cone per metric (the largest;
                the smallest for E_c, where higher is better)
    seconds     {"render", "masks", "metrics"}

``report``: a folder with, per avatar, ``NAME.json`` (the record as a document,
"lenticalib.avatar-diagnostics", with its provenance), ``NAME-metrics.png`` (every metric against
yaw) and ``NAME-sides.png`` (the -25 and +25 degree views with the dilated mask, the alpha
boundary and the neck-rear region drawn over them); NAME is the avatar file's stem (numbered
when two avatars share one).  Written staged: complete or not at all.

Errors name the argument by its parameter name (``avatar``, ``mesh``, ``controls``, ``frame``,
``n_views`` ...); a command-line front end maps them to its flags.
"""

from __future__ import annotations

import dataclasses
import os
import time
from pathlib import Path
from typing import Any, Callable

import numpy as np

from ...core.errors import InputError
from ...core.files.outputs import check_output_folder
from ..cameras.models import robust_box
from .report import REPORT_CONTENTS, REPORT_WHAT, write_diagnose_report
from .side_metrics import HIGHER_IS_BETTER, METRICS, crop_rule, view_metrics

SIDE_YAW_DEG = 25.0
DEMO_FPS = 30.0


@dataclasses.dataclass(frozen=True)
class DiagnoseOptions:
    """How to pose, frame and render the avatars: ``controls`` (None, "demo" or a control file)
    and ``frame``; the camera model's options as ``render`` takes them (``n_views``,
    ``yaw_range_deg``, ``radius`` in avatar units or None, ``fov_deg`` vertical, ``view_size``
    (W, H) pixels); ``renderer`` (default cpu) and ``device`` (torch device for gsplat)."""

    controls: str | None = None
    frame: int = 0
    camera_model: str = "arc"
    n_views: int = 32
    yaw_range_deg: float = 50.0
    radius: float | None = None
    fov_deg: float = 20.0
    view_size: tuple[int, int] = (960, 540)
    renderer: str | None = None
    device: str | None = None


@dataclasses.dataclass
class _Prepared:
    """One avatar checked and posed: its Gaussians, its mesh (vertices (V, 3) world, triangles (F, 3))."""

    path: str
    avatar: Any
    gaussians: Any
    vertices: np.ndarray
    triangles: np.ndarray
    mask_source: str
    controls: dict | None


def _pose_controls(avatar, options: DiagnoseOptions) -> tuple[np.ndarray | None, dict | None]:
    """The control vector the avatar is posed with (None: canonical) and its record."""
    spec = options.controls
    frame = options.frame
    if isinstance(frame, bool) or not isinstance(frame, (int, np.integer)) or frame < 0:
        raise InputError(f"frame {frame!r} is not a sample number", source="frame", hint="use 0, 1, 2 ...")
    if spec is None:
        return None, None
    if avatar.kind == "static":
        raise InputError("a static avatar (.ply) takes no controls", source="controls",
                         hint="leave the controls out, or give an animated avatar (a rig .npz)")
    if spec == "demo":
        from ..controls.streams import demo_controls

        t = frame / DEMO_FPS
        return demo_controls(t, avatar.layout), {"source": "demo", "frame": int(frame), "t": t}
    if spec in ("-", "stdin") or str(spec).startswith("udp://"):
        raise InputError(f"{spec!r} is a live stream; the diagnostics need one pose", source="controls",
                         hint="give a control file (.npz, .csv, .jsonl) and a frame, or 'demo'")
    from ..controls.files import load_controls

    names = avatar.rig.control_names if avatar.rig is not None else None
    track = load_controls(spec, avatar.layout, names)
    if frame >= len(track):
        raise InputError(f"frame {frame} is past the {len(track)} samples of {spec}", source="frame",
                         hint=f"use 0..{len(track) - 1}")
    return track.controls[frame].copy(), {"source": str(spec), "frame": int(frame), "t": float(track.t[frame])}


def _prepare(path, mesh_file, options: DiagnoseOptions, as_torch: bool, device: str) -> _Prepared:
    from ..avatar.sources import load_avatar
    from ..avatar.mesh import check_mesh_fits

    avatar = load_avatar(path)
    controls, record = _pose_controls(avatar, options)
    if mesh_file is not None:
        vertices, triangles = mesh_file.vertices, mesh_file.triangles
        mask_source = f"mesh file {mesh_file.source} ({len(vertices)} vertices, {len(triangles)} triangles, as given)"
        mesh_source = mesh_file.source
    elif avatar.rig is not None and avatar.rig.mesh is not None:
        vertices = avatar.rig.pose_mesh(avatar.neutral if controls is None else controls).detach().cpu().numpy()
        vertices = vertices.astype(np.float64)
        triangles = avatar.rig.mesh.triangles
        mask_source = (f"the rig's mesh ({len(vertices)} vertices, {len(triangles)} triangles), posed by "
                       f"{'the canonical pose' if record is None else 'the controls'}")
        mesh_source = f"{path} (its mesh)"
    else:
        raise InputError("the avatar carries no mesh", source=str(path),
                         hint="give the avatar's mesh as `mesh` (OBJ or PLY triangles in the avatar's frame and units)")
    gaussians = avatar.pose(controls, device=device, as_torch=as_torch)
    means = gaussians.means.detach().cpu().numpy() if as_torch else gaussians.means
    if not np.isfinite(vertices).all():
        raise InputError("the posed mesh has a vertex that is not a finite number", source=mesh_source)
    check_mesh_fits(mesh_box(vertices, triangles), robust_box(means), mesh_source)
    return _Prepared(str(path), avatar, gaussians, vertices, triangles, mask_source, record)


def mesh_box(vertices: np.ndarray, triangles: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(min, max) (3,) of the vertices the triangles use, world units."""
    used = vertices[np.unique(triangles)]
    return used.min(0), used.max(0)


def diagnose_cameras(box: tuple[np.ndarray, np.ndarray], options: DiagnoseOptions):
    """(arc cameras, side cameras or None) (:class:`~.cameras.ViewCameras`): the camera model
    framed on the mesh's ``box``; the side cameras at -25 and +25 degrees when the arc has no view
    there."""
    from ..cameras.models import make_cameras

    common = {"fov_deg": options.fov_deg, "view_size": options.view_size}
    if options.radius is not None:
        common["radius"] = options.radius
    arc = make_cameras(options.camera_model, box, options.n_views, yaw_range_deg=options.yaw_range_deg, **common)
    have = [np.isclose(arc.yaw_deg, s * SIDE_YAW_DEG, atol=1e-6).any() for s in (-1, 1)]
    side = None if all(have) else make_cameras(options.camera_model, box, 2, yaw_range_deg=2 * SIDE_YAW_DEG, **common)
    return arc, side


def _diagnose_one(prep: _Prepared, options: DiagnoseOptions, render_fn: Callable, renderer: str,
                  step: Callable[..., None]) -> dict:
    from .mesh_raster import mesh_masks

    arc, side = diagnose_cameras(mesh_box(prep.vertices, prep.triangles), options)
    viewmats = arc.viewmats if side is None else np.concatenate([arc.viewmats, side.viewmats])
    Ks = arc.K if side is None else np.concatenate([arc.K, side.K])
    yaws = np.asarray(arc.yaw_deg if side is None else np.concatenate([arc.yaw_deg, side.yaw_deg]), dtype=np.float64)
    W, H = arc.width, arc.height
    t0 = time.perf_counter()
    rgba = render_fn(prep.gaussians, viewmats, Ks, W, H, background=None)
    if hasattr(rgba, "detach"):
        rgba = rgba.detach().cpu().numpy()
    rgba = np.asarray(rgba, dtype=np.float32)
    t1 = time.perf_counter()
    masks = mesh_masks(prep.vertices, prep.triangles, viewmats, Ks, W, H)
    crop = crop_rule(masks)
    t2 = time.perf_counter()
    step()
    rows = []
    for i in range(len(yaws)):
        rows.append({"view": i, "yaw_deg": round(float(yaws[i]), 6),
                     **view_metrics(rgba[i, ..., :3], rgba[i, ..., 3], masks[i], crop)})
    t3 = time.perf_counter()
    step()
    n_arc = len(arc.yaw_deg)
    views = rows[:n_arc]
    sides = [min(rows, key=lambda r: abs(r["yaw_deg"] - s * SIDE_YAW_DEG)) for s in (-1, 1)]
    sides = [{k: v for k, v in r.items() if k != "view"} for r in sides]
    record = {
        "avatar": prep.path, "kind": prep.avatar.kind, "mask_source": prep.mask_source, "controls": prep.controls,
        "renderer": renderer, "view_size": [W, H],
        "cameras": {"model": options.camera_model, "views": int(n_arc), "yaw_range_deg": float(options.yaw_range_deg),
                    "fov_deg": float(options.fov_deg), "radius": float(arc.params["r"]),
                    "framed_on": "the mesh's box", "extra_side_views": side is not None},
        "crop": crop.as_dict(),
        "views": views,
        "side": {"views": sides, "mean": {m: float(np.mean([r[m] for r in sides])) for m in METRICS}},
        "worst": _worst(views),
        "seconds": {"render": round(t1 - t0, 3), "masks": round(t2 - t1, 3), "metrics": round(t3 - t2, 3)},
    }
    record["_maps"] = {"rgba": rgba, "masks": masks, "yaws": yaws}  # for the report; dropped before returning
    return record


def _worst(views: list[dict]) -> dict:
    out = {}
    for m in METRICS:
        pick = (min if m in HIGHER_IS_BETTER else max)(views, key=lambda r: r[m])
        out[m] = {"yaw_deg": pick["yaw_deg"], "value": pick[m]}
    return out


def rank(records: list[dict]) -> dict[str, list[int]]:
    """{metric: [index of the best avatar, index of the second best]} by the mean over the two
    side views (lower is better; higher for E_c); one entry when there is one avatar."""
    out = {}
    for m in METRICS:
        values = [r["side"]["mean"][m] for r in records]
        order = sorted(range(len(values)), key=lambda k: -values[k] if m in HIGHER_IS_BETTER else values[k])
        out[m] = order[:2]
    return out


def report_names(paths: list[str]) -> list[str]:
    """A file-name stem per avatar for the report: the file's stem, numbered when stems repeat."""
    stems = [Path(p).stem or "avatar" for p in paths]
    return [f"{k + 1:02d}-{s}" if stems.count(s) > 1 else s for k, s in enumerate(stems)]


def diagnose_avatars(avatars: list[str | os.PathLike], *, mesh: str | os.PathLike | None = None,
                     options: DiagnoseOptions | None = None, report: str | os.PathLike | None = None,
                     stage: Callable[[str, int], Callable[..., None]] | None = None) -> dict:
    """The side-view diagnostics of ``avatars`` (module docstring); ``stage(name, steps)`` for progress.

    Every InputError (files, mesh, controls, options, renderer, report folder) comes before the
    first render.
    """
    from ..avatar.mesh import load_mesh_file
    from ..renderers import get_renderer

    o = options or DiagnoseOptions()
    if not avatars:
        raise InputError("no avatar given", source="avatar", hint="give one or more avatar files")
    renderer = o.renderer or "cpu"
    device = o.device or ("cuda" if renderer == "gsplat" else "cpu")
    render_fn = get_renderer(renderer, device=device)
    inputs = (*avatars, mesh, None if o.controls in (None, "demo") else o.controls)  # what the report may not hold
    if report is not None:
        check_output_folder(report, REPORT_WHAT, REPORT_CONTENTS, inputs=inputs)
    mesh_file = None
    if mesh is not None:
        mesh_file = load_mesh_file(mesh)
    as_torch = renderer == "gsplat"
    prepared = [_prepare(p, mesh_file, o, as_torch, device) for p in avatars]
    for p in prepared:  # the cameras' options are checked for every avatar before the first render
        diagnose_cameras(mesh_box(p.vertices, p.triangles), o)

    def steps(name: str, total: int):
        return stage(name, total) if stage is not None else (lambda *message: None)

    step = steps("diagnosing", 2 * len(prepared))
    records = [_diagnose_one(p, o, render_fn, renderer, step) for p in prepared]
    if report is not None:
        write_diagnose_report(report, records, report_names([r["avatar"] for r in records]), o, inputs=inputs)
    for r in records:
        r.pop("_maps")
    if len(records) == 1:
        return records[0]
    return {"avatars": records, "best": rank(records)}
