"""What a render for a panel takes when nobody says: the views' size, their count, the camera arc.

Views are drawn at the panel's aspect ratio (the encoders refuse views more than 1 % off it:
they would be stretched), so every default and every size proposed in a hint follows the
panel, never a fixed 16:9 size.

VIEW SIZE (:func:`default_view_size`).  For a Looking Glass profile whose calibration serial
names a model (:mod:`lenticalib.core.looking_glass.models`), the views are as tall as a tile of the quilt
Looking Glass's software renders for that model, and as wide as the panel's aspect makes them:
420 x 560 on a Portrait (its 3360 x 3360 quilt of 8 x 6 tiles of 420 x 560).  Otherwise about
the pixels of a 960 x 540 view at the panel's aspect, the height a multiple of 4: 960 x 540 on a
16:9 panel, 624 x 832 on a 3:4 one.

VIEW COUNT (:func:`default_views`).  A ``visual.json`` does not record it; Looking Glass takes
it from the model's quilt (48 on a Portrait, 66 on a Go, 45 on the first-generation units).

CAMERA ARC (:func:`default_camera_arc`).  The full yaw range the N cameras span, degrees: the
Looking Glass calibration's ``viewCone`` (their cameras span it), else the profile's physical
``view_cone_deg`` (the data sheet's cone), else LentiAvatar's 50.

Sizes are ``(width, height)`` in pixels.
"""

from __future__ import annotations

import math
from typing import Any

from .looking_glass.models import QuiltModel, model_of
from .profile import PanelProfile
from .sizes import MAX_SIDE

DEFAULT_VIEW_SIZE = (960, 540)
"""The view size of a 16:9 panel that is no known Looking Glass model (LentiAvatar's)."""
DEFAULT_CAMERA_ARC_DEG = 50.0
"""LentiAvatar's yaw range: -25 .. +25 degrees."""
FIT_TOLERANCE = 0.005
"""How far (relative) a proposed size's aspect may be off the panel's: half the 1 % the encoders allow."""


def aspect_error(view_size: tuple[int, int], panel_size: tuple[int, int]) -> float:
    """``|(w_v / h_v) / (W / H) - 1|``: how far (relative) views of ``view_size`` are off the
    aspect of a panel of ``panel_size``."""
    (w, h), (pw, ph) = view_size, panel_size
    return abs((w / h) / (pw / ph) - 1.0)


def size_at_height(panel_size: tuple[int, int], height: int) -> tuple[int, int]:
    """The view size at the aspect of a panel of ``panel_size`` (W, H) about ``height`` pixels
    tall: the first height from ``height`` up (down when that passes :data:`MAX_SIDE`) whose
    rounded width is within :data:`FIT_TOLERANCE` of the aspect (at most a few pixels taller)."""
    pw, ph = panel_size
    aspect = pw / ph
    height = max(1, min(int(height), MAX_SIDE))
    candidates = list(range(height, MAX_SIDE + 1)) + list(range(height - 1, 0, -1))
    for h in candidates:
        w = max(1, round(h * aspect))
        if w <= MAX_SIDE and aspect_error((w, h), panel_size) <= FIT_TOLERANCE:
            return w, h
    return pw, ph  # no smaller size fits: the panel's own (not reached for panels of sides <= MAX_SIDE)


def quilt_model(profile: PanelProfile) -> QuiltModel | None:
    """The Looking Glass model of ``profile`` (from its calibration's serial), else None."""
    return model_of(profile.looking_glass)


def default_view_size(profile: PanelProfile) -> tuple[int, int]:
    """The views' size for ``profile`` when none is given (module docstring, VIEW SIZE)."""
    panel = (profile.width, profile.height)
    model = quilt_model(profile)
    if model is not None:
        return size_at_height(panel, model.tile_size[1])
    pixels = DEFAULT_VIEW_SIZE[0] * DEFAULT_VIEW_SIZE[1]
    height = 4 * max(1, round(math.sqrt(pixels * profile.height / profile.width) / 4))
    return size_at_height(panel, height)


def view_size_origin(profile: PanelProfile) -> str:
    """Where :func:`default_view_size` takes its size from, in words (for messages)."""
    model = quilt_model(profile)
    if model is not None:
        return (f"the {model.name}'s quilt, {model.columns}x{model.rows} tiles of {model.quilt_width}x"
                f"{model.quilt_height}")
    return f"the {profile.width}x{profile.height} panel's aspect"


def default_views(looking_glass: Any) -> int | None:
    """The view count of the quilt Looking Glass renders for the model of a calibration (a
    visual.json's fields or a profile's ``looking_glass`` block), None for no known model."""
    model = model_of(looking_glass) if isinstance(looking_glass, dict) else None
    return model.views if model is not None else None


def default_camera_arc(profile: PanelProfile) -> float:
    """The cameras' full yaw range in degrees for ``profile`` (module docstring, CAMERA ARC)."""
    for block, key in ((profile.looking_glass, "viewCone"), (profile.physical, "view_cone_deg")):
        value = (block or {}).get(key)
        if isinstance(value, (int, float)) and not isinstance(value, bool) and 0.0 < value < 180.0:
            return float(value)
    return DEFAULT_CAMERA_ARC_DEG


def fitting_size(profile: PanelProfile, view_size: tuple[int, int]) -> tuple[int, int]:
    """A size at the panel's aspect near ``view_size`` (W, H) and no larger: as tall when that
    makes the views no wider, else as wide (for a hint after a size of another aspect)."""
    w, h = view_size
    panel = (profile.width, profile.height)
    same_height = size_at_height(panel, h)
    if same_height[0] <= w:
        return same_height
    return size_at_height(panel, max(1, math.floor(w * profile.height / profile.width)))


def view_size_hint(profile: PanelProfile, view_size: tuple[int, int]) -> str:
    """The hint after views of ``view_size`` (W, H) that do not fit ``profile``'s aspect: sizes that
    do (:func:`fitting_size`, and the default with where it comes from)."""
    fit, default = fitting_size(profile, view_size), default_view_size(profile)
    return (f"render at the panel's aspect ratio, e.g. {fit[0]}x{fit[1]}, or leave `view_size` out for "
            f"{default[0]}x{default[1]} ({view_size_origin(profile)})")
