"""What every renderer checks at its boundary, and the conventions they share."""

from __future__ import annotations

import numbers

import numpy as np

from ...core.errors import InputError
from ..gaussians import Gaussians

NEAR_PLANE = 0.01  # camera-frame z, world units (gsplat's default)
FAR_PLANE = 1e10
EPS2D = 0.3  # px^2 added to the projected covariance's diagonal (gsplat's default)
TILE_SIZE = 16


def _as_numpy(a) -> np.ndarray:
    if hasattr(a, "detach"):  # a torch tensor
        a = a.detach().to("cpu").double().numpy()
    return np.asarray(a, dtype=np.float64)


def _shape_error(name: str, got, expected: str) -> InputError:
    return InputError(f"shape {tuple(got)}, expected {expected}", source=name)


def check_render_inputs(gaussians, viewmats, Ks, width, height, background):
    """Refuse bad renderer inputs with one InputError naming the argument.

    Returns ``(viewmats, Ks, background)`` as float64 numpy (``background`` None or (3,)); the
    Gaussians are validated in place (numpy or torch, any device).
    """
    if not isinstance(gaussians, Gaussians):
        raise InputError(f"expected a Gaussians, got {type(gaussians).__name__}", source="gaussians")
    gaussians.validate("gaussians")
    for name, value in (("width", width), ("height", height)):
        if isinstance(value, bool) or not isinstance(value, numbers.Integral) or value <= 0:
            raise InputError(f"must be a positive integer, got {value!r}", source=name)
    v = _as_numpy(viewmats)
    k = _as_numpy(Ks)
    if v.ndim != 3 or v.shape[1:] != (4, 4) or v.shape[0] == 0:
        raise _shape_error("viewmats", v.shape, "(N, 4, 4) with N >= 1")
    if k.shape != (v.shape[0], 3, 3):
        raise _shape_error("Ks", k.shape, f"({v.shape[0]}, 3, 3), one per viewmat")
    if not np.isfinite(v).all():
        raise InputError("non-finite values", source="viewmats")
    if not np.isfinite(k).all():
        raise InputError("non-finite values", source="Ks")
    rot = v[:, :3, :3]
    rigid = (np.abs(rot @ rot.transpose(0, 2, 1) - np.eye(3)).max(axis=(1, 2)) < 1e-3) & \
            (np.linalg.det(rot) > 0) & (np.abs(v[:, 3] - [0, 0, 0, 1]).max(axis=1) == 0)
    if not rigid.all():
        i = int(np.flatnonzero(~rigid)[0])
        raise InputError(f"view {i} is not a rigid world-to-camera transform [R t; 0 0 0 1]",
                         source="viewmats")
    pinhole = (k[:, 0, 0] > 0) & (k[:, 1, 1] > 0) & (k[:, 0, 1] == 0) & (k[:, 1, 0] == 0) & \
              (np.abs(k[:, 2] - [0, 0, 1]).max(axis=1) == 0)
    if not pinhole.all():
        i = int(np.flatnonzero(~pinhole)[0])
        raise InputError(f"view {i} is not [[fx, 0, cx], [0, fy, cy], [0, 0, 1]] with fx, fy > 0",
                         source="Ks")
    if background is not None:
        background = _as_numpy(background)
        if background.shape != (3,) or not np.isfinite(background).all():
            raise InputError(f"expected 3 finite values (RGB), got shape {background.shape}",
                             source="background")
    return v, k, background


def check_finite_gaussians(g: Gaussians) -> None:
    """InputError (naming ``gaussians``) for non-finite parameters or a zero-length quaternion
    (``g`` numpy): what the renderers that compute on the host refuse before any work."""
    for name in ("means", "quats", "scales", "opacities", "sh"):
        if not np.isfinite(getattr(g, name)).all():
            raise InputError(f"{name} has non-finite values", source="gaussians")
    if not (np.linalg.norm(g.quats, axis=1) > 0).all():
        raise InputError("quats has a zero-length quaternion", source="gaussians")


def jacobian_limits(width: int, height: int, fx, fy, cx, cy):
    """gsplat's clamp of x/z and y/z inside the EWA Jacobian (1.3 x the field of view's
    half-extent): ``(lim_x_pos, lim_x_neg, lim_y_pos, lim_y_neg)``, with ``cx``, ``cy`` in gsplat's
    frame (+ 0.5); scalars or arrays (one per view)."""
    tan_fovx = 0.5 * width / fx
    tan_fovy = 0.5 * height / fy
    return ((width - cx) / fx + 0.3 * tan_fovx, cx / fx + 0.3 * tan_fovx,
            (height - cy) / fy + 0.3 * tan_fovy, cy / fy + 0.3 * tan_fovy)
