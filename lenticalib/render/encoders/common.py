"""What every encoder checks and shares: the view stack and the output raster."""

from __future__ import annotations

import numpy as np

from ...core.errors import ImageError
from ...core.profile import PanelProfile

SUPPORTED_DTYPES = (np.uint8, np.uint16, np.float32, np.float64)
ASPECT_TOLERANCE = 0.01


def check_views(views, profile: PanelProfile, *, check_aspect: bool = True, source: str = "views") -> np.ndarray:
    """Validate a view stack against ``profile`` and return it C-contiguous.

    ``views``: array ``(N, H_v, W_v, 3)``, RGB, one of uint8, uint16, float32, float64, with
    ``N == profile.views``.  With ``check_aspect`` the views' aspect ratio must match the panel's
    within 1 % (views made for another panel would be stretched).
    """
    if not isinstance(views, np.ndarray):
        raise ImageError(f"expected a numpy array, got {type(views).__name__}", source=source)
    if views.ndim != 4 or views.shape[-1] != 3:
        raise ImageError(f"expected shape (N={profile.views}, H_v, W_v, 3), got {views.shape}", source=source)
    if views.shape[0] != profile.views:
        raise ImageError(f"got {views.shape[0]} views, the profile has {profile.views}", source=source,
                         hint="supply exactly one view per view of the panel")
    if views.shape[1] < 1 or views.shape[2] < 1:
        raise ImageError(f"views are empty: {views.shape}", source=source)
    if views.dtype.type not in SUPPORTED_DTYPES:
        raise ImageError(f"unsupported pixel type {views.dtype}", source=source,
                         hint="use uint8, uint16, float32 or float64")
    if check_aspect:
        view_aspect = views.shape[2] / views.shape[1]
        panel_aspect = profile.width / profile.height
        if abs(view_aspect / panel_aspect - 1.0) > ASPECT_TOLERANCE:
            raise ImageError(
                f"views of {views.shape[2]}x{views.shape[1]} (aspect {view_aspect:.3f}) do not fit the "
                f"{profile.width}x{profile.height} panel of the profile (aspect {panel_aspect:.3f})",
                source=source, hint="render views at the panel's aspect ratio, or use the profile of "
                                    "the panel they were made for (allow_stretch to force)")
    return np.ascontiguousarray(views)


def output_like(views: np.ndarray, profile: PanelProfile, out: np.ndarray | None) -> np.ndarray:
    """The panel raster ``(height, width, 3)`` in the views' dtype (``out`` reused when it fits)."""
    shape = (profile.height, profile.width, 3)
    if out is None:
        return np.empty(shape, dtype=views.dtype)
    if out.shape != shape or out.dtype != views.dtype or not out.flags.c_contiguous:
        raise ImageError(f"output buffer must be C-contiguous {views.dtype} {shape}, got "
                         f"{out.dtype} {out.shape}", source="out")
    return out


def finish(values: np.ndarray, dtype) -> np.ndarray:
    """Round float64 panel values to ``dtype``: half up and clipped for integers, cast for floats."""
    if np.issubdtype(dtype, np.integer):
        top = np.iinfo(dtype).max
        return np.clip(np.floor(values + 0.5), 0, top).astype(dtype)
    return values.astype(dtype)
