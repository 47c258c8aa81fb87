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

from ..core.documents import FORMATS, read_document, write_document
from ..core.errors import InputError

DOCUMENT = FORMATS["lenticalib.cameras"]


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
