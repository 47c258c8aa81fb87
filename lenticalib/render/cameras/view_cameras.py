"""The N virtual cameras the avatar is rendered from: container, projection, view order, cameras.json.

The camera models that build them (the LentiAvatar arc, the Looking Glass shear rig) and the
``make_cameras`` dispatcher live in :mod:`.camera_models`.

Frames and units
    world   the avatar's frame and units (see :mod:`.gaussians`); right-handed; by default
            y up and the avatar facing +z.
    camera  OpenCV: x right, y down, z forward along the optical axis; world units.
    pixels  OpenCV: pixel centres at integer coordinates, (0, 0) the centre of the top-left
            pixel, so a centred camera has its principal point at ((W-1)/2, (H-1)/2).
    angles  degrees.

Left and right
    "The viewer" stands in front of the avatar and faces it, as someone in front of the panel
    does: they look along -e_forward with e_up up, so their right hand points along
    e_side = e_up x e_forward.  With up=+y, forward=+z that is **+x** (which is the *avatar's*
    left: facing someone, your right is their left).  A camera at yaw theta > 0 sits towards
    +e_side, on the viewer's right; theta < 0 on the viewer's left.  Both models put camera i at
    theta_i = -Y/2 + Y i/(N-1), so as built **view 0 is on the viewer's left (x < 0 by default)
    and view N-1 on the viewer's right (x > 0)**: the view index grows as the camera moves right
    (``view_direction = +1``).  The image x axis of the front camera is e_side too, so the right
    of every rendered view is the viewer's right.

Views with nothing in them
    :func:`empty_views` finds the views in which no Gaussian can show, from the centres alone
    (projected once, before any render), and :func:`empty_views_warning` says so in one line:
    what ``render`` and ``play`` warn about instead of rendering black views without a word.

View order
    A panel profile's ``view_direction`` is +1 when its view index grows as the viewer moves
    right (the convention of optics.md: an eye right of the calibration camera sees higher view
    numbers), -1 when it falls.  View i must be rendered from where a viewer who sees view i
    stands, so :func:`order_for_direction` keeps the cameras for +1 and reverses them for -1.
"""

from __future__ import annotations

import dataclasses
import os
from typing import Any

import numpy as np

from ...core.files.documents import FORMATS, read_document, write_document
from ...core.errors import InputError

DOCUMENT = FORMATS["lenticalib.cameras"]
NEAR_PLANE = 0.01  # camera-frame z, world units: nearer is not drawn (gsplat's default)
ALPHA_MIN = 1.0 / 255.0  # a Gaussian of lower opacity draws nothing (the renderers' cut-off)
FOOTPRINT_SIGMAS = 3.33  # a splat reaches at most this many standard deviations (the renderers' box)


def camera_side(yaw_deg: float) -> str:
    """Where a camera at ``yaw_deg`` sits for the viewer facing the avatar: "left", "right" or "centre".

    yaw > 0 is towards e_side = e_up x e_forward (+x for up=+y, forward=+z), the viewer's right.
    """
    return "right" if yaw_deg > 0 else "left" if yaw_deg < 0 else "centre"


@dataclasses.dataclass(frozen=True)
class ViewCameras:
    """N pinhole cameras, view i rendered by camera i.

    K           (N, 3, 3) float64   intrinsics, pixels, OpenCV (see the module docstring)
    viewmats    (N, 4, 4) float64   world-to-camera, camera frame OpenCV (x right, y down, z forward)
    width, height                   view size, pixels
    yaw_deg     (N,) float64        camera yaw about e_up, degrees, > 0 on the viewer's right
                                    (arc: the angle on the arc; shear: the equivalent viewing angle)
    model       "arc" or "shear"
    params      the model's parameters, JSON-ready (lists, floats), written to cameras.json
    view_direction  +1: the view index grows as the camera moves to the viewer's right; -1: it falls
    """

    K: np.ndarray
    viewmats: np.ndarray
    width: int
    height: int
    yaw_deg: np.ndarray
    model: str
    params: dict[str, Any]
    view_direction: int = 1

    def __post_init__(self):
        _check(self, "cameras")

    @property
    def n_views(self) -> int:
        return int(self.K.shape[0])

    @property
    def centres(self) -> np.ndarray:
        """(N, 3) camera centres in world coordinates, -R^T t."""
        rot, trans = self.viewmats[:, :3, :3], self.viewmats[:, :3, 3]
        return -np.einsum("nji,nj->ni", rot, trans)

    def project(self, points_world: Any) -> tuple[np.ndarray, np.ndarray]:
        """Project world points (P, 3) into every view.

        Returns pixel coordinates (N, P, 2) (x, y; OpenCV pixels) and depths (N, P) (the camera z,
        world units).  Points with depth <= 0 (at or behind a camera) get NaN pixel coordinates.
        """
        pts = np.asarray(points_world, dtype=np.float64)
        if pts.ndim != 2 or pts.shape[1] != 3:
            raise InputError(f"points have shape {pts.shape}, expected (P, 3)", source="points_world")
        cam = np.einsum("nij,pj->npi", self.viewmats[:, :3, :3], pts) + self.viewmats[:, None, :3, 3]
        depth = cam[..., 2]
        pix = np.einsum("nij,npj->npi", self.K, cam)
        ahead = depth > 0
        uv = np.full(pix.shape[:2] + (2,), np.nan)
        uv[ahead] = pix[ahead][:, :2] / pix[ahead][:, 2:3]
        return uv, depth

    def to_json_dict(self) -> dict[str, Any]:
        """The cameras.json content: format tag, model, view size, view_direction, params, and per
        view its index, yaw (degrees), K (3x3, pixels) and world_to_camera (4x4, OpenCV)."""
        return {
            **DOCUMENT.envelope(),
            "model": self.model,
            "width": self.width,
            "height": self.height,
            "view_direction": self.view_direction,
            "params": self.params,
            "views": [{"index": i, "yaw_deg": float(self.yaw_deg[i]), "K": self.K[i].tolist(),
                       "world_to_camera": self.viewmats[i].tolist()} for i in range(self.n_views)],
        }

    def write_json(self, path: str | os.PathLike) -> None:
        """Write cameras.json to ``path`` atomically."""
        write_document(path, DOCUMENT, self.to_json_dict(), indent=1)

    @classmethod
    def from_json(cls, path: str | os.PathLike) -> "ViewCameras":
        """Read a cameras.json written by :meth:`write_json`; InputError naming ``path`` if it is not one."""
        source = str(path)
        data = read_document(path, DOCUMENT)
        try:
            views = data["views"]
            fields = dict(K=np.array([v["K"] for v in views], dtype=np.float64),
                          viewmats=np.array([v["world_to_camera"] for v in views], dtype=np.float64),
                          yaw_deg=np.array([v["yaw_deg"] for v in views], dtype=np.float64),
                          width=data["width"], height=data["height"], model=data["model"],
                          params=data["params"], view_direction=data["view_direction"])
            if [v["index"] for v in views] != list(range(len(views))):
                raise InputError("view indices are not 0..N-1 in order", source=source)
        except (KeyError, TypeError, ValueError) as exc:
            if isinstance(exc, InputError):
                raise
            raise InputError(f"malformed cameras file ({type(exc).__name__}: {exc})", source=source) from None
        try:
            return cls(**fields)
        except InputError as exc:
            raise InputError(exc.message, source=source, hint=exc.hint) from None


def order_for_direction(cameras: ViewCameras, view_direction: int) -> ViewCameras:
    """The cameras in the order a panel with ``view_direction`` (+1 or -1) needs.

    Rule: view i is rendered from where a viewer who sees view i stands.  On a +1 panel the
    view index grows as the viewer moves right, so camera i must be right of camera i-1; on a -1
    panel the order is reversed.  The cameras remember their order (``view_direction``), so the
    call is idempotent: cameras already ordered for ``view_direction`` come back unchanged.
    """
    if view_direction not in (1, -1) or isinstance(view_direction, bool):
        raise InputError(f"view_direction {view_direction!r} is not +1 or -1", source="view_direction",
                         hint="+1 when the view index grows as the viewer moves right, else -1")
    if view_direction == cameras.view_direction:
        return cameras
    return dataclasses.replace(cameras, K=cameras.K[::-1].copy(), viewmats=cameras.viewmats[::-1].copy(),
                               yaw_deg=cameras.yaw_deg[::-1].copy(), view_direction=view_direction)


def empty_views(cameras: ViewCameras, points: Any, reach: Any = None) -> list[int]:
    """The views in which none of ``points`` can show: their indices, ascending.

    ``points`` (P, 3) world; ``reach`` (P,) world units, the radius of each point's footprint (a
    Gaussian's: :data:`FOOTPRINT_SIGMAS` times its largest standard deviation), None for 0.  A
    point shows in view i when it lies at least the renderers' ``NEAR_PLANE`` (0.01) in front of
    camera i and the disc of radius ``f reach / z`` pixels around its projection (f the larger
    focal length) meets the view's pixels, [-0.5, W - 0.5] x [-0.5, H - 0.5].  In chunks of 8192
    points, a view at a time, stopping at the first that shows: a view with the avatar in it
    costs one chunk (the demo avatar's 32 views: 25 ms), an empty one every point (13 ms per
    100 000 points, 2 cores).
    """
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    rad = np.zeros(len(pts)) if reach is None else np.asarray(reach, dtype=np.float64).reshape(-1)
    # points in a spread order (every 997th first), so a view that shows the avatar is told by the first chunk
    order = np.argsort(np.arange(len(pts)) % 997, kind="stable")
    chunks = np.array_split(order, max(1, -(-len(pts) // 8192)))
    return [i for i in range(cameras.n_views) if not any(_shows(cameras, i, pts[c], rad[c]) for c in chunks)]


def _shows(cameras: ViewCameras, i: int, pts: np.ndarray, rad: np.ndarray) -> bool:
    """Whether any of ``pts`` (P, 3) with footprint radii ``rad`` (P,) shows in view ``i`` (:func:`empty_views`)."""
    cam = pts @ cameras.viewmats[i, :3, :3].T + cameras.viewmats[i, :3, 3]
    ahead = cam[:, 2] >= NEAR_PLANE
    z = cam[ahead, 2]
    k = cameras.K[i]
    u = k[0, 0] * cam[ahead, 0] / z + k[0, 2]
    v = k[1, 1] * cam[ahead, 1] / z + k[1, 2]
    r = max(k[0, 0], k[1, 1]) * rad[ahead] / z + 0.5
    return bool(((u >= -r) & (u <= cameras.width - 1 + r) & (v >= -r) & (v <= cameras.height - 1 + r)).any())


def empty_views_warning(cameras: ViewCameras, gaussians: Any) -> str | None:
    """One line naming the views of ``cameras`` that show nothing of ``gaussians`` (a numpy
    :class:`~.gaussians.Gaussians`; those of opacity below :data:`ALPHA_MIN` left out), where the
    cameras look and how to aim them; None when every view shows some of it (:func:`empty_views`)."""
    seen = np.asarray(gaussians.opacities) >= ALPHA_MIN
    empty = empty_views(cameras, np.asarray(gaussians.means)[seen],
                        FOOTPRINT_SIGMAS * np.asarray(gaussians.scales)[seen].max(axis=1, initial=0.0))
    if not empty:
        return None
    look = cameras.params.get("c")
    at = "" if look is None else " (they look at " + ", ".join(f"{float(x):.4g}" for x in look) + ")"
    return (f"{view_list(empty)} of {cameras.n_views} show nothing of the avatar: none of its Gaussians is in their "
            f"field of view{at}; aim the cameras with `target` (in the avatar's frame and units)")


def view_list(indices: list[int]) -> str:
    """``[0, 1, 2, 5]`` -> "views 0-2, 5"; ``[4]`` -> "view 4" (ascending indices)."""
    runs: list[list[int]] = []
    for i in indices:
        if runs and i == runs[-1][1] + 1:
            runs[-1][1] = i
        else:
            runs.append([i, i])
    parts = [f"{a}" if a == b else f"{a}-{b}" for a, b in runs]
    return ("view " if len(indices) == 1 else "views ") + ", ".join(parts)


def _check(cams: ViewCameras, source: str) -> None:
    """Coerce the arrays to contiguous float64 and check shapes and values; InputError naming ``source``."""
    for name in ("K", "viewmats", "yaw_deg"):
        object.__setattr__(cams, name, np.ascontiguousarray(getattr(cams, name), dtype=np.float64))
    n = cams.K.shape[0] if cams.K.ndim == 3 else -1
    expected = {"K": (n, 3, 3), "viewmats": (n, 4, 4), "yaw_deg": (n,)}
    for name, shape in expected.items():
        if getattr(cams, name).shape != shape or n < 1:
            raise InputError(f"{name} has shape {getattr(cams, name).shape}, expected {shape} with N >= 1",
                             source=source)
        if not np.isfinite(getattr(cams, name)).all():
            raise InputError(f"{name} has non-finite values", source=source)
    for name in ("width", "height"):
        value = getattr(cams, name)
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 1:
            raise InputError(f"{name} {value!r} is not a positive integer", source=source)
    if cams.view_direction not in (1, -1) or isinstance(cams.view_direction, bool):
        raise InputError(f"view_direction {cams.view_direction!r} is not +1 or -1", source=source)
    if not isinstance(cams.model, str) or not isinstance(cams.params, dict):
        raise InputError("model must be a string and params a dict", source=source)
    if not np.allclose(cams.viewmats[:, 3], [0.0, 0.0, 0.0, 1.0]) or not np.allclose(cams.K[:, 2], [0.0, 0.0, 1.0]):
        raise InputError("K's last row must be (0, 0, 1) and world_to_camera's (0, 0, 0, 1)", source=source)
    rot = cams.viewmats[:, :3, :3]
    if not np.allclose(np.einsum("nij,nkj->nik", rot, rot), np.eye(3), atol=1e-9) or \
            not np.allclose(np.linalg.det(rot), 1.0, atol=1e-9):
        raise InputError("world_to_camera has a rotation part that is not a proper rotation", source=source)
    if cams.K[:, 0, 0].min() <= 0 or cams.K[:, 1, 1].min() <= 0:
        raise InputError("K has a focal length <= 0", source=source)
