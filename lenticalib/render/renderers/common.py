"""What every renderer checks at its boundary, and the conventions they share.

Memory of the views.  A renderer holds the N views of a frame as float32 RGBA, N x H x W x 4
channels x 4 bytes (:data:`VIEW_BYTES_PER_PIXEL`), on the host (``cpu``) or on the GPU (``gl``,
``gsplat``); the pipeline adds 3 bytes a pixel for the 8-bit views.  :func:`check_view_memory`
refuses, in one line before anything is allocated, views of one frame above
:data:`MAX_VIEW_BYTES` (8 GiB: 32 views of 3840x2160, or 100 views of 2560x1440, still fit; 200
views of 16384x9216, 534 GiB, do not); every renderer calls it with its inputs, and the avatar
session (``render``, ``play``) before the avatar is loaded.
"""

from __future__ import annotations

import numbers

import numpy as np

from ...core.errors import InputError
from ..avatar.gaussians import Gaussians

FAR_PLANE = 1e10
EPS2D = 0.3  # px^2 added to the projected covariance's diagonal (gsplat's default)
TILE_SIZE = 16
VIEW_BYTES_PER_PIXEL = 4 * 4 + 3  # float32 RGBA as rendered, and the 8-bit RGB views made from it
MAX_VIEW_BYTES = 8 * 2**30  # the views of one frame, at most (module docstring)


def _as_numpy(a) -> np.ndarray:
    if hasattr(a, "detach"):  # a torch tensor
        a = a.detach().to("cpu").double().numpy()
    return np.asarray(a, dtype=np.float64)


def _shape_error(name: str, got, expected: str) -> InputError:
    return InputError(f"shape {tuple(got)}, expected {expected}", source=name)


def check_view_memory(n_views: int, width: int, height: int) -> int:
    """The bytes the N views of ``width`` x ``height`` pixels take (N x W x H x
    :data:`VIEW_BYTES_PER_PIXEL`); one InputError naming ``view_size`` when they exceed
    :data:`MAX_VIEW_BYTES`, before anything is allocated.  Sizes that are not positive whole
    numbers are left to the callers' own checks (0 is returned)."""
    if not all(isinstance(v, numbers.Integral) and not isinstance(v, bool) and v > 0 for v in (n_views, width, height)):
        return 0
    need = int(n_views) * int(width) * int(height) * VIEW_BYTES_PER_PIXEL
    if need > MAX_VIEW_BYTES:
        raise InputError(f"{n_views} views of {width}x{height} pixels take {need / 2**30:.4g} GiB "
                         f"({n_views} x {width} x {height} x {VIEW_BYTES_PER_PIXEL} bytes), more than the "
                         f"{MAX_VIEW_BYTES / 2**30:.0f} GiB the views of a frame may take", source="view_size",
                         hint="render smaller views with `view_size`, or for a panel with fewer views")
    return need


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
    check_view_memory(v.shape[0], width, height)
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
