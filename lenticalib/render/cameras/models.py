"""The camera models, selected by name: the LentiAvatar arc and the Looking Glass shear rig.

Both take a box around the Gaussian centres and share one rig (world units, degrees).
:func:`make_cameras` frames an avatar on its *robust* box (:func:`robust_box`: the 1st to 99th
percentile of the centres per axis, the box ``avatar diagnose`` checks meshes against), so a few
stray Gaussians far away (floaters) neither move the look-at point nor shrink the avatar.

    e_up      = up / |up|;  e_forward = forward with its e_up component removed, normalised
                (the direction the avatar faces);  e_side = e_up x e_forward (the viewer's right,
                see :mod:`.cameras`; +x for up=+y, forward=+z)
    c0        = centre of the bounding box            (``centre`` overrides)
    h         = the box's extent along e_up            (``height`` overrides)
    c         = c0 + 0.08 h e_up                       (the look-at point, about eye level;
                                                        ``target`` overrides c itself)
    theta_i   = -Y/2 + Y i/(N-1), i = 0..N-1           (N = 1: theta_0 = 0)
    r         = (h / 0.8) / (2 tan(fov/2)) + d/2       (``radius`` overrides) where d is the box's
                extent along e_forward: the front face of the box, at r - d/2 from the front camera,
                spans 80 % of the vertical field of view (the box reaches 0.58 h below c and 0.42 h
                above it, inside the +-0.625 h the view shows there)
    K         = [[f, 0, (W-1)/2], [0, f, (H-1)/2], [0, 0, 1]],  f = H / (2 tan(fov/2)) pixels,
                fov the vertical field of view (default 20 degrees), square pixels

arc     camera i at o_i = c + r (sin theta_i e_side + cos theta_i e_forward), LookAt(o_i, c, e_up).
shear   camera i at o_i = c + r e_forward + x_i e_side, x_i = r tan theta_i, looking along
        -e_forward (all cameras share one rotation); its principal point is shifted to
        K[0, 2] = (W-1)/2 + f x_i / r so that every camera sees the same window of the focal plane
        (through c, perpendicular to e_forward) centred: a point of that plane projects to the
        same pixel in every view (Looking Glass quilts are rendered this way).

Both return cameras ordered with ``view_direction = +1`` (view 0 on the viewer's left); reorder
for a panel with :func:`.cameras.order_for_direction`.

The models are a registry on the package's one loader (:mod:`lenticalib.core.plugins`): third
parties add models through the entry-point group ``lenticalib.camera_models`` (value
``"module:function"``, the function called as ``arc_cameras`` is and returning a ViewCameras).
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np

from ...core.errors import InputError
from ...core.plugins import Registry
from ...core.profile import MAX_VIEWS
from .view_cameras import ViewCameras
from ..avatar.gaussians import Gaussians

DEFAULT_FOV_DEG = 20.0
FILL = 0.8          # fraction of the view height the box's front face fills at the default radius
CENTRE_LIFT = 0.08  # c = c0 + CENTRE_LIFT * h * e_up
BOX_PERCENTILES = (1.0, 99.0)  # the robust box: these percentiles of the Gaussian centres, per axis


@dataclasses.dataclass(frozen=True)
class _Rig:
    """What both models share: unit vectors and c (3,) float64 (world); r world units; yaw_deg (N,) degrees."""

    e_up: np.ndarray
    e_forward: np.ndarray
    e_side: np.ndarray
    c: np.ndarray
    r: float
    yaw_deg: np.ndarray
    K: np.ndarray  # (3, 3) the centred camera's intrinsics
    width: int
    height: int
    params: dict[str, Any]

    @property
    def theta(self) -> np.ndarray:
        return np.radians(self.yaw_deg)


def arc_cameras(bbox_min: Any, bbox_max: Any, n_views: int = 32, *, radius: float | None = None,
                fov_deg: float = DEFAULT_FOV_DEG, yaw_range_deg: float = 50.0,
                view_size: tuple[int, int] = (960, 540), up: Any = (0, 1, 0), forward: Any = (0, 0, 1),
                centre: Any = None, height: float | None = None, target: Any = None) -> ViewCameras:
    """The LentiAvatar arc: N cameras on a horizontal arc of radius r around c, all looking at c.

    ``bbox_min``, ``bbox_max``: (3,) corners of the box around the Gaussian centres (world);
    ``view_size``: (width, height) pixels; ``target``: the look-at point c, (3,) world units (the
    avatar's frame: metres for the demo avatar), or None for c0 + 0.08 h e_up; see the module
    docstring for every formula.  View 0 is
    at yaw -Y/2, on the viewer's left; view N-1 on the viewer's right.
    """
    rig = _rig(bbox_min, bbox_max, n_views, radius, fov_deg, yaw_range_deg, view_size, up, forward, centre,
               height, target)
    origins = rig.c + rig.r * (np.sin(rig.theta)[:, None] * rig.e_side + np.cos(rig.theta)[:, None] * rig.e_forward)
    viewmats = np.stack([_look_at(o, rig.c, rig.e_up) for o in origins])
    return ViewCameras(np.repeat(rig.K[None], len(origins), axis=0), viewmats, rig.width, rig.height, rig.yaw_deg,
                       "arc", rig.params)


def shear_cameras(bbox_min: Any, bbox_max: Any, n_views: int = 32, *, radius: float | None = None,
                  fov_deg: float = DEFAULT_FOV_DEG, yaw_range_deg: float = 50.0,
                  view_size: tuple[int, int] = (960, 540), up: Any = (0, 1, 0), forward: Any = (0, 0, 1),
                  centre: Any = None, height: float | None = None, target: Any = None) -> ViewCameras:
    """Parallel off-axis cameras on a line through c + r e_forward along e_side, converging on the
    focal plane through c.  Options as :func:`arc_cameras`; yaw_deg holds the viewing angle
    theta_i = atan(x_i / r) of camera i towards c.
    """
    rig = _rig(bbox_min, bbox_max, n_views, radius, fov_deg, yaw_range_deg, view_size, up, forward, centre,
               height, target)
    offsets = rig.r * np.tan(rig.theta)  # x_i along e_side
    origins = rig.c + rig.r * rig.e_forward + offsets[:, None] * rig.e_side
    viewmats = np.stack([_look_at(o, o - rig.e_forward, rig.e_up) for o in origins])
    K = np.repeat(rig.K[None], len(origins), axis=0)
    K[:, 0, 2] += K[:, 0, 0] * offsets / rig.r
    return ViewCameras(K, viewmats, rig.width, rig.height, rig.yaw_deg, "shear", rig.params)


CAMERA_MODELS = Registry("camera model", {
    "arc": "lenticalib.render.cameras.models:arc_cameras",
    "shear": "lenticalib.render.cameras.models:shear_cameras",
}, "lenticalib.camera_models", choices="use one of {names}")


def make_cameras(model: str, gaussians_or_bbox: Gaussians | tuple[Any, Any], n_views: int = 32,
                 **options: Any) -> ViewCameras:
    """N cameras of the named model (``CAMERA_MODELS``) around a Gaussians avatar or a (min, max) box.

    An avatar is framed on its :func:`robust_box`; a box is taken as given.  ``options`` are the
    model's keyword options (radius, fov_deg, yaw_range_deg, view_size, up, forward, centre,
    height, target); ``target=None`` is left out, so a plug-in model need not take it.  An
    unknown model is an InputError naming ``model`` (before the avatar is looked at).
    """
    build = CAMERA_MODELS.load(model, "model")
    if options.get("target", 0) is None:
        del options["target"]
    if "target" in options and not _takes(build, "target"):
        raise InputError(f"camera model {model!r} takes no target", source="target",
                         hint="leave the target out, or use the arc or shear model")
    if isinstance(gaussians_or_bbox, Gaussians):
        if gaussians_or_bbox.count == 0:
            raise InputError("the avatar has no Gaussians", source="avatar")
        means = gaussians_or_bbox.means
        bbox_min, bbox_max = robust_box(means if isinstance(means, np.ndarray) else gaussians_or_bbox.to_numpy().means)
    else:
        try:
            bbox_min, bbox_max = gaussians_or_bbox
        except (TypeError, ValueError):
            raise InputError("expected a Gaussians avatar or a (min, max) box", source="bbox") from None
    return build(bbox_min, bbox_max, n_views, **options)


def robust_box(means: Any) -> tuple[np.ndarray, np.ndarray]:
    """(min, max), (3,) float64 each, world units: the :data:`BOX_PERCENTILES` (1st and 99th) of the
    Gaussian centres ``means`` (G, 3) per axis, so that stray Gaussians do not widen it.  The box
    every avatar is framed on (:func:`make_cameras`) and ``avatar diagnose`` fits meshes to; its
    centre is where the cameras look (lifted by 0.08 h, module docstring).  With few Gaussians a
    stray one still pulls it (the percentiles interpolate: 1 of 11 moves the 99th 90 % of the way)."""
    lo, hi = np.percentile(np.asarray(means, dtype=np.float64), BOX_PERCENTILES, axis=0)
    return lo, hi


def _takes(build: Any, name: str) -> bool:
    """Whether the callable ``build`` accepts the keyword ``name`` (or any keyword)."""
    import inspect

    try:
        parameters = inspect.signature(build).parameters.values()
    except (TypeError, ValueError):
        return True
    return any(p.name == name or p.kind is p.VAR_KEYWORD for p in parameters)


def _look_at(origin: np.ndarray, target: np.ndarray, e_up: np.ndarray) -> np.ndarray:
    """(4, 4) world-to-camera, OpenCV: z towards ``target``, y towards -e_up (image down), x = y x z."""
    z = (target - origin) / np.linalg.norm(target - origin)
    x = np.cross(z, e_up)
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    view = np.eye(4)
    view[:3, :3] = np.stack([x, y, z])
    view[:3, 3] = -view[:3, :3] @ origin
    return view


def _rig(bbox_min, bbox_max, n_views, radius, fov_deg, yaw_range_deg, view_size, up, forward, centre,
         height, target=None) -> _Rig:
    """Check every option (InputError naming it) and compute the shared rig."""
    if isinstance(n_views, bool) or not isinstance(n_views, (int, np.integer)) or not 1 <= n_views <= MAX_VIEWS:
        raise InputError(f"{n_views!r} views is out of range", source="n_views", hint=f"use 1..{MAX_VIEWS}")
    width, height_px = _view_size(view_size)
    fov = _number(fov_deg, "fov_deg", "give the vertical field of view in degrees, 1 < fov < 120")
    if not 1.0 < fov < 120.0:
        raise InputError(f"field of view {fov:g} degrees is out of range", source="fov_deg",
                         hint="use 1 < fov < 120 degrees (vertical)")
    span = _number(yaw_range_deg, "yaw_range_deg", "give the yaw range in degrees, 0 < range < 180")
    if not 0.0 < span < 180.0:
        raise InputError(f"yaw range {span:g} degrees is out of range", source="yaw_range_deg",
                         hint="use 0 < range < 180 degrees")
    e_up, e_forward = _frame(up, forward)
    e_side = np.cross(e_up, e_forward)
    lo, hi = _vector(bbox_min, "bbox"), _vector(bbox_max, "bbox")
    if (hi < lo).any():
        raise InputError("the box's max corner is below its min corner", source="bbox")
    c0 = (lo + hi) / 2 if centre is None else _vector(centre, "centre")
    h = float(np.abs(e_up) @ (hi - lo))
    if height is not None:
        h = _number(height, "height", "give the avatar's height in world units")
        if not 0.0 < h < math.inf:
            raise InputError(f"height {h:g} is not positive", source="height")
    tan_half = math.tan(math.radians(fov) / 2)
    if radius is None:
        if h <= 0:
            raise InputError("the box has no extent along up, so no default radius", source="bbox",
                             hint="pass height or radius")
        r = (h / FILL) / (2 * tan_half) + float(np.abs(e_forward) @ (hi - lo)) / 2
    else:
        r = _number(radius, "radius", "give the camera distance in world units")
        if not 0.0 < r < math.inf:
            raise InputError(f"radius {r:g} is not positive", source="radius", hint="use a radius > 0")
    c = c0 + CENTRE_LIFT * h * e_up if target is None else _target(target)
    yaw = np.zeros(1) if n_views == 1 else -span / 2 + span * np.arange(n_views) / (n_views - 1)
    f = height_px / (2 * tan_half)
    K = np.array([[f, 0.0, (width - 1) / 2], [0.0, f, (height_px - 1) / 2], [0.0, 0.0, 1.0]])
    params = {"c0": c0.tolist(), "h": h, "c": c.tolist(), "r": r, "Y": span, "N": int(n_views),
              "up": e_up.tolist(), "forward": e_forward.tolist(), "side": e_side.tolist(), "fov": fov,
              "fov_axis": "vertical"}
    return _Rig(e_up, e_forward, e_side, c, r, yaw, K, width, height_px, params)


def _frame(up: Any, forward: Any) -> tuple[np.ndarray, np.ndarray]:
    """(e_up, e_forward): unit vectors, forward made perpendicular to up."""
    u = _vector(up, "up")
    if not np.linalg.norm(u) > 0:
        raise InputError("the up axis is zero", source="up")
    e_up = u / np.linalg.norm(u)
    f = _vector(forward, "forward")
    if not np.linalg.norm(f) > 0:
        raise InputError("the forward axis is zero", source="forward")
    f = f / np.linalg.norm(f)
    f = f - (f @ e_up) * e_up
    if np.linalg.norm(f) < 1e-3:
        raise InputError("the forward axis is parallel to up", source="forward",
                         hint="give the direction the avatar faces, perpendicular to up")
    return e_up, f / np.linalg.norm(f)


def _view_size(value: Any) -> tuple[int, int]:
    hint = "give WIDTH, HEIGHT as two positive integers, e.g. 960, 540"
    try:
        width, height = value
    except (TypeError, ValueError):
        raise InputError(f"{value!r} is not a (width, height) pair", source="view_size", hint=hint) from None
    for v in (width, height):
        if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < 1:
            raise InputError(f"view size {value!r} is not two positive integers", source="view_size", hint=hint)
    return int(width), int(height)


def _number(value: Any, source: str, hint: str) -> float:
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise InputError(f"{value!r} is not a number", source=source, hint=hint) from None
    if not math.isfinite(x):
        raise InputError(f"{value!r} is not finite", source=source, hint=hint)
    return x


def _target(value: Any) -> np.ndarray:
    """The look-at point ``target`` as a (3,) float64, or one InputError naming it."""
    try:
        return _vector(value, "target")
    except InputError as exc:
        raise InputError(exc.message, source="target",
                         hint="give X, Y, Z, three finite numbers in the avatar's frame and units "
                              "(metres for the demo avatar)") from None


def _vector(value: Any, source: str) -> np.ndarray:
    try:
        v = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise InputError(f"{value!r} is not a 3-vector", source=source) from None
    if v.shape != (3,) or not np.isfinite(v).all():
        raise InputError(f"{value!r} is not a finite 3-vector", source=source)
    return v
