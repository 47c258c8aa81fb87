"""A simulated capture scene (panel optics + camera + seed), random scenes, and their JSON form.

:func:`random_scene` draws every parameter from a documented range (``RANGES``); any range can
be narrowed or fixed by keyword (``random_scene(7, distance=(600, 600), blur=(0.3, 0.3))``).

RANGES (uniform unless noted)
    period            Delta_r at the camera distance, subpixels            [14, 24]
    slant             |C_r|, pixels per row; the sign is drawn +-           [0.10, 0.35]
    order             subpixel order, drawn from                            RGB, BGR
                      (a ``layout`` argument replaces the drawn order; see :mod:`.layouts`)
    panel_width       raster width in mm; p = panel_width / W               [650, 740]
                      (a 3840-wide raster: p in [0.169, 0.193] mm)
    kappa             gap in lens pitches, g = kappa P_u                    [1.0, 1.6]
    black_matrix_h    dark fraction of a subpixel cell across x             [0.15, 0.30]
    black_matrix_v    dark fraction along y                                 [0.05, 0.15]
    blur              sigma_u on axis, in subpixel widths (p/3)             [0.15, 0.35]
    blur_growth       sigma_u(theta) = sigma_u (1 + growth tan^2 theta)     [0.3, 1.5]
    scatter           sheet scatter fraction                                [0.005, 0.03]
    angular_falloff   luminance ~ cos(theta) ** a                           [0.3, 1.5]
    backlight         each of the 5 backlight coefficients                  [-0.03, 0.03]
    bezel_width       mm                                                    [3, 12]
    bezel_level       relative radiance                                     [0.002, 0.01]
    background_level  relative radiance                                     [0.005, 0.04]
    distance          D, camera centre to lens plane, mm                    [450, 800]
    offset            ex and ey of the camera centre, each, mm              [-50, 50]
    fill              panel width / image width                             [0.6, 0.9]
                      (reduced when needed to keep the panel in the frame)
    principal         principal point offset from the centre, fraction of the size  [-0.02, 0.02]
    aspect            fy / fx                                               [0.998, 1.002]
    k1, k2            radial distortion                                     [-0.15, 0.10], [-0.03, 0.05]
    p1, p2            tangential distortion, each                           [-0.002, 0.002]
    aim               aim point offset on the panel, fraction of the panel size  [-0.03, 0.03]
    roll              degrees                                               [-3, 3]
    crosstalk         off-diagonal colour mixing, each                      [0.02, 0.25]
    white_balance     per-channel gain error                                [0.95, 1.05]
    exposure          white panel peak level at the image centre            [0.78, 0.95]
    vignetting        relative illumination lost at the corners             [0.10, 0.30]
    defocus           Gaussian, pixels                                      [0.3, 1.0]
    chromatic         lateral chromatic aberration m_R, m_B, each            [-0.0004, 0.0004]
    glare             veiling glare fraction                                [0.01, 0.05]
    glare_sigma       glare width, fraction of the image width              [0.03, 0.10]
    flare             constant flare, saturation units                      [0.002, 0.01]
    full_well         electrons at saturation                               [3000, 12000]
    read_noise        electrons RMS                                         [1.5, 5.0]
    tone_gamma        exponent after the sRGB curve                         [0.92, 1.08]
    sharpen           unsharp-mask amount                                   [0.0, 0.5]
    jpeg_quality      integer                                               [80, 95]
    tone_contrast     phone S-curve strength (see :class:`.camera.Camera`)  0
    exposure_jitter   per-photo exposure drift bound, relative              0
    shake             per-photo image shift bound, pixels                   0

CONDITIONS: named sets of range overrides, ``random_scene(seed, conditions="hard")``
    standard   the ranges above: a locked camera on a steady tripod, a near-sRGB tone curve
    hard       what phones and consumer cameras do unless told not to: a tone curve from
               near-sRGB to a strong S (tone_contrast [0.1, 1.0]), exposure drifting by up
               to +-4 % from photo to photo, a tripod shaking by up to 0.3 pixel between
               photos, and high-ISO noise (full_well [500, 2500] electrons, read_noise
               [3, 10] electrons)

The three per-photo keys were added after the others and are drawn last, so a seed draws the
same scene under ``standard`` as before they existed.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any, Mapping

import numpy as np

from ..core.files.documents import FORMATS, check_envelope
from ..core.errors import InputError
from ..core.layout import SubpixelLayout
from ..core.profile import PanelProfile
from .camera import Camera
from .optics import PanelOptics
from .truth import truth_profile

DOCUMENT = FORMATS["lenticalib.simulation"]
DEFAULT_RESOLUTION = (4000, 3000)

RANGES: dict[str, tuple[float, float]] = {  # see the module docstring for units
    "period": (14.0, 24.0), "slant": (0.1, 0.35), "panel_width": (650.0, 740.0), "kappa": (1.0, 1.6),
    "black_matrix_h": (0.15, 0.3), "black_matrix_v": (0.05, 0.15), "blur": (0.15, 0.35),
    "blur_growth": (0.3, 1.5), "scatter": (0.005, 0.03), "angular_falloff": (0.3, 1.5),
    "backlight": (-0.03, 0.03), "bezel_width": (3.0, 12.0), "bezel_level": (0.002, 0.01),
    "background_level": (0.005, 0.04), "distance": (450.0, 800.0), "offset": (-50.0, 50.0),
    "fill": (0.6, 0.9), "principal": (-0.02, 0.02), "aspect": (0.998, 1.002), "k1": (-0.15, 0.1),
    "k2": (-0.03, 0.05), "p1": (-0.002, 0.002), "p2": (-0.002, 0.002), "aim": (-0.03, 0.03),
    "roll": (-3.0, 3.0), "crosstalk": (0.02, 0.25), "white_balance": (0.95, 1.05), "exposure": (0.78, 0.95),
    "vignetting": (0.1, 0.3), "defocus": (0.3, 1.0), "chromatic": (-0.0004, 0.0004), "glare": (0.01, 0.05),
    "glare_sigma": (0.03, 0.1), "flare": (0.002, 0.01), "full_well": (3000.0, 12000.0),
    "read_noise": (1.5, 5.0), "tone_gamma": (0.92, 1.08), "sharpen": (0.0, 0.5), "jpeg_quality": (80, 95),
    "tone_contrast": (0.0, 0.0), "exposure_jitter": (0.0, 0.0), "shake": (0.0, 0.0),
}

CONDITIONS: dict[str, dict[str, tuple[float, float]]] = {  # see the module docstring
    "standard": {},
    "hard": {"tone_contrast": (0.1, 1.0), "exposure_jitter": (0.04, 0.04), "shake": (0.3, 0.3),
             "full_well": (500.0, 2500.0), "read_noise": (3.0, 10.0)},
}


@dataclasses.dataclass(frozen=True)
class Scene:
    """One simulated set-up: the panel, the camera in front of it and the seed that drew them.

    ``seed`` is None for hand-made scenes.  The ground truth for this camera position is
    :meth:`truth_profile`; the eye is the camera centre ``camera.position``.
    """

    optics: PanelOptics
    camera: Camera
    seed: int | None = None

    @property
    def eye(self) -> tuple[float, float, float]:
        """The camera centre (ex, ey, -D), world mm."""
        return tuple(float(c) for c in self.camera.position)

    def truth_profile(self, views: int, **kwargs: Any) -> PanelProfile:
        """The ideal profile for this camera position (see :func:`.truth.truth_profile`)."""
        return truth_profile(self.optics, self.eye, views, **kwargs)

    def replace_camera(self, **changes: Any) -> "Scene":
        """A copy whose camera has some fields changed."""
        return dataclasses.replace(self, camera=self.camera.replace(**changes))

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready mapping: format, version, seed, optics, camera."""
        return {**DOCUMENT.envelope(), "seed": self.seed,
                "optics": self.optics.to_dict(), "camera": self.camera.to_dict()}

    @classmethod
    def from_dict(cls, data: Any, source: str = "scene") -> "Scene":
        """Inverse of :meth:`to_dict`.  Also accepts a ``simulation.json`` (its ``scene`` entry)."""
        if isinstance(data, Mapping) and "scene" in data and "optics" not in data:
            check_envelope(data, FORMATS["lenticalib.simulation-run"], source)
            data = data["scene"]
        check_envelope(data, DOCUMENT, source)
        seed = data.get("seed")
        if seed is not None and (not isinstance(seed, int) or isinstance(seed, bool)):
            raise InputError(f"field 'seed' must be a whole number or null, got {seed!r}", source=source)
        try:
            optics = PanelOptics.from_dict(data.get("optics"), source)
            camera = Camera.from_dict(data.get("camera"), source)
        except InputError as exc:
            raise InputError(exc.message, source=source, hint=exc.hint) from None
        except TypeError as exc:
            raise InputError(f"a field has the wrong type: {exc}", source=source) from None
        return cls(optics=optics, camera=camera, seed=seed)


def _range(ranges: Mapping[str, Any], key: str) -> tuple[float, float]:
    value = ranges[key]
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        return float(value), float(value)
    try:
        lo, hi = (float(v) for v in value)
    except (TypeError, ValueError):
        raise InputError(f"range '{key}' must be a number or a (low, high) pair, got {value!r}",
                         source="random_scene") from None
    if not (math.isfinite(lo) and math.isfinite(hi) and lo <= hi):
        raise InputError(f"range '{key}' must be finite with low <= high, got {value!r}",
                         source="random_scene")
    return lo, hi


def _place_camera(optics: PanelOptics, width: int, height: int, position, aim, roll, fill, principal,
                  aspect, distortion, **photometry) -> Camera:
    """A camera at ``position`` aimed at ``aim`` whose focal length makes the panel fill ``fill`` of
    the image width, shortened until the whole panel with its bezel lies inside the frame."""
    panel_w, panel_h = optics.panel_size
    outer_w = panel_w / 2 + optics.sheet_margin + optics.bezel_width
    outer_h = panel_h / 2 + optics.sheet_margin + optics.bezel_width
    distance = -position[2]
    fx = fill * width * distance / panel_w
    cx = (width - 1) / 2 + principal[0] * width
    cy = (height - 1) / 2 + principal[1] * height
    side = np.linspace(-1.0, 1.0, 33)
    outline = np.concatenate([np.stack([side * outer_w, np.full(33, s * outer_h)], 1) for s in (-1, 1)]
                             + [np.stack([np.full(33, s * outer_w), side * outer_h], 1) for s in (-1, 1)])
    pts = np.concatenate([outline, np.zeros((len(outline), 1))], 1)
    for _ in range(60):
        cam = Camera(width=width, height=height, fx=fx, fy=fx * aspect, cx=cx, cy=cy,
                     distortion=distortion, position=tuple(position), aim=tuple(aim), roll=roll, **photometry)
        px = cam.project(pts)
        margin = 0.02
        if (np.all(px[:, 0] > margin * width) and np.all(px[:, 0] < (1 - margin) * width)
                and np.all(px[:, 1] > margin * height) and np.all(px[:, 1] < (1 - margin) * height)):
            return cam
        fx *= 0.97
    raise InputError("cannot fit the panel into the camera frame", source="random_scene",
                     hint="use a wider image aspect or a smaller fill")


def random_scene(seed: int, *, width: int = 3840, height: int = 2160,
                 resolution: tuple[int, int] | None = None, period: float | None = None,
                 slant: float | None = None, order: str | None = None, distance: float | None = None,
                 jpeg_quality: int | None = None, subsamples: int = 3, conditions: str = "standard",
                 layout: SubpixelLayout | None = None, **ranges: Any) -> Scene:
    """A random but plausible scene, fully determined by ``seed``.

    ARGUMENTS
    seed           integer seed of every random draw
    width, height  panel raster in pixels (the pattern set's size)
    resolution     camera (w, h) in pixels; default 4000 x 3000 (12 MP)
    period         fixed Delta_r (subpixels, at the camera distance) instead of a draw
    slant          fixed C_r (signed) instead of a draw
    order          fixed "RGB" or "BGR"
    layout         a subpixel layout for the panel (:class:`~lenticalib.core.layout.SubpixelLayout`,
                   e.g. from :data:`.layouts.NAMED_LAYOUTS`) instead of a stripe; its order is RGB
                   (the slots are R, G, B).  Drawn nothing: every other draw stays the seed's
    distance       fixed camera distance D (mm)
    jpeg_quality   fixed JPEG quality (1..100)
    subsamples     rays per pixel side (n x n per sensor pixel)
    conditions     a key of ``CONDITIONS``: "standard" or "hard" (phone-like camera behaviour)
    ranges         any key of ``RANGES`` -> (low, high) or a fixed number, overriding its range
                   (and the conditions' range)

    Every parameter is drawn whether or not it is overridden, so fixing one parameter leaves all the
    others as the seed drew them.
    """
    unknown = sorted(set(ranges) - set(RANGES))
    if unknown:
        raise InputError(f"unknown range(s): {', '.join(unknown)}", source="random_scene",
                         hint="known: " + ", ".join(RANGES))
    if conditions not in CONDITIONS:
        raise InputError(f"unknown conditions {conditions!r}", source="conditions",
                         hint="known: " + ", ".join(CONDITIONS))
    if order is not None and order not in ("RGB", "BGR"):
        raise InputError(f"order must be RGB or BGR, got {order!r}", source="order")
    if layout is not None and not isinstance(layout, SubpixelLayout):
        raise InputError(f"must be a SubpixelLayout, got {type(layout).__name__}", source="layout")
    if layout is not None and order not in (None, "RGB"):
        raise InputError(f"order {order} cannot be combined with a subpixel layout", source="order",
                         hint="a layout fixes where every channel sits; give one or the other")
    cam_w, cam_h = resolution or DEFAULT_RESOLUTION
    table = {**RANGES, **CONDITIONS[conditions], **ranges}
    rng = np.random.default_rng(seed)

    def draw(key):
        lo, hi = _range(table, key)
        return float(rng.uniform(lo, hi))

    # -- panel ---------------------------------------------------------------------------------
    d_period, d_slant = draw("period"), draw("slant")
    sign = 1.0 if rng.random() < 0.5 else -1.0
    d_order = "RGB" if rng.random() < 0.5 else "BGR"
    d_distance = draw("distance")
    panel_width = draw("panel_width")
    kappa = draw("kappa")
    x0_fraction = float(rng.random())
    period = d_period if period is None else float(period)
    slant = sign * d_slant if slant is None else float(slant)
    order = "RGB" if layout is not None else (order or d_order)
    distance = d_distance if distance is None else float(distance)
    if not abs(slant) < 1.5 or not period > 0 or not distance > 0:
        raise InputError(f"need |slant| < 1.5, period > 0 and distance > 0 (got slant {slant}, "
                         f"period {period}, distance {distance})", source="random_scene")
    pixel_pitch = panel_width / width
    optics_extras = dict(
        subpixel_order=order, black_matrix_h=draw("black_matrix_h"), black_matrix_v=draw("black_matrix_v"),
        blur_sigma=draw("blur") * pixel_pitch / 3.0, blur_growth=draw("blur_growth"), scatter=draw("scatter"),
        angular_falloff=draw("angular_falloff"), backlight=tuple(draw("backlight") for _ in range(5)),
        bezel_width=draw("bezel_width"), bezel_level=draw("bezel_level"),
        background_level=draw("background_level"), subpixel_layout=layout)
    optics = PanelOptics.from_routing(period, slant, distance, width=width, height=height,
                                      pixel_pitch=pixel_pitch, kappa=kappa, x0_fraction=x0_fraction,
                                      **optics_extras)
    # -- camera --------------------------------------------------------------------------------
    position = (draw("offset"), draw("offset"), -distance)
    fill = draw("fill")
    principal = (draw("principal"), draw("principal"))
    aspect = draw("aspect")
    k1, k2, p1, p2 = draw("k1"), draw("k2"), draw("p1"), draw("p2")
    panel_w, panel_h = optics.panel_size
    aim = (draw("aim") * panel_w, draw("aim") * panel_h)
    roll = draw("roll")
    mix = np.eye(3)
    for r in range(3):
        for c in range(3):
            if r != c:
                mix[r, c] = draw("crosstalk")
    mix /= mix.sum(axis=1, keepdims=True)
    mix *= np.array([draw("white_balance") for _ in range(3)])[:, None]
    target = draw("exposure")
    white = (1 - optics.black_matrix_h) * (1 - optics.black_matrix_v) * float(mix.sum(axis=1).max())
    corner_loss = draw("vignetting")
    photometry = dict(
        subsamples=int(subsamples), colour_matrix=tuple(float(v) for v in mix.ravel()),
        exposure=target / white, vignetting=(0.6 * corner_loss, 0.4 * corner_loss),
        defocus_sigma=draw("defocus"), glare_fraction=draw("glare"), glare_sigma=draw("glare_sigma"),
        flare=draw("flare"), full_well=draw("full_well"), read_noise=draw("read_noise"),
        tone_gamma=draw("tone_gamma"), sharpen=draw("sharpen"),
        chromatic=(draw("chromatic"), draw("chromatic")))
    lo, hi = _range(table, "jpeg_quality")
    d_quality = int(rng.integers(int(round(lo)), int(round(hi)) + 1))
    photometry["jpeg_quality"] = d_quality if jpeg_quality is None else int(jpeg_quality)
    for key in ("tone_contrast", "exposure_jitter", "shake"):  # drawn last: see the module docstring
        photometry[key] = draw(key)
    for _ in range(20):  # a distortion that folds over inside the frame: soften k2 and try again
        try:
            camera = _place_camera(optics, int(cam_w), int(cam_h), position, aim, roll, fill, principal,
                                   aspect, (k1, k2, p1, p2, 0.0), **photometry)
            break
        except InputError as exc:
            if "distortion" not in str(exc):
                raise
            k2 = k2 * 0.5 + abs(k1) * 0.1
    else:
        raise InputError("no invertible distortion found", source="random_scene")
    return Scene(optics=optics, camera=camera, seed=int(seed))
