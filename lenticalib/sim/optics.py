"""The lens sheet and pixel plane of a virtual slanted-lenticular panel (``docs/optics.md``).

Frames and units
----------------
World (mm): x right along panel rows, y down along columns, z into the screen.  The origin is
the panel centre on the lens surface (z = 0); the pixel plane is at z = +g.  A camera or eye
sits at ``E = (ex, ey, -D)`` with ``D > 0`` its distance to the lens plane.

Raster (continuous): ``X`` in subpixels (subpixel ``x_s`` covers ``[x_s, x_s + 1)``), ``Y`` in
rows (row ``y`` covers ``[y, y + 1)``).  On the pixel plane

    x_mm = X p / 3 - W p / 2,        y_mm = Y p - H p / 2.

Lens sheet: lens boundaries ``x = x0 + k P_h + y tan(phi)``; across-lens coordinate
``u = x cos(phi) - y sin(phi)``, along-lens ``v = x sin(phi) + y cos(phi)``; lens pitch across
``P_u = P_h cos(phi)``; lens ``k`` spans ``[x0 cos(phi) + k P_u, x0 cos(phi) + (k + 1) P_u)``
in u, its centre line is ``u_c = x0 cos(phi) + (k + 0.5) P_u``.

Seen point: a ray from E that meets the lens plane at L in lens k shows the pixel-plane point

    u_P = u_c + (u_c - u_E) g / D,   v_P = v_L + (v_L - v_E) g / D

(focused across the lens, straight on along it).

View coordinate ``w*`` of a pixel-plane point P for an eye E (N views): where the chief ray
from P through a lens centre reaches the eye plane, measured in view zones from the eye,

    w*(P) = N/2 + N g (u_c (1 + D/g) - u_P D/g - u_E) / (P_u (D + g))   (mod N).

Any lens centre gives the same value modulo N.  The eye itself sits at ``w* = N/2``.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any, Mapping

import numpy as np

from ..core.errors import InputError
from ..core.files.fields import unknown_key_message
from ..core.layout import SubpixelLayout, layout_from_dict
from ..core.profile import SUBPIXEL_ORDERS, PanelProfile

BACKLIGHT_TERMS = ("x", "y", "xx", "yy", "xy")
BLUR_SHAPES = ("gaussian", "disc", "lorentzian")


@dataclasses.dataclass(frozen=True)
class PanelOptics:
    """Physical description of one virtual panel: raster, lens sheet and light emission.

    ARGUMENTS (all lengths in mm, world frame of the module docstring)
    width, height       raster size W x H in pixels
    pixel_pitch         p, square pixel pitch; a subpixel is p/3 wide and p tall
    lens_pitch          P_h, horizontal lens pitch (along x at fixed y)
    slant_angle         phi in radians; lens boundaries run along x = y tan(phi) + const,
                        so the routing slant is C_r = tan(phi) (pixels per row)
    gap                 g, effective optical gap lens surface -> pixel plane (thickness / index)
    x0                  lens boundary position at y = 0 (world x, mm), in [0, P_h)
    subpixel_order      "RGB" or "BGR": colour of subpixel positions 0, 1, 2 in a pixel
                        ("RGB" with a subpixel_layout)
    black_matrix_h      dark fraction of each subpixel cell across x (the open aperture is
                        centred: [x_s + b/2, x_s + 1 - b/2))
    black_matrix_v      dark fraction of each cell along y (aperture [y + b/2, y + 1 - b/2))
    blur_sigma          sigma_u on axis: Gaussian spread of the seen point across the lens (u), mm
    blur_growth         off-axis growth: sigma_u(theta) = blur_sigma (1 + blur_growth tan^2 theta),
                        theta the angle between the ray and the panel normal
    scatter             fraction of the light scattered by the sheet (a wide halo of the
                        raster around the seen point; a crosstalk floor)
    angular_falloff     emitted luminance scales as cos(theta) ** angular_falloff
    backlight           smooth backlight non-uniformity: luminance factor
                        1 + bx xn + by yn + bxx xn^2 + byy yn^2 + bxy xn yn with
                        xn = x / (W p / 2), yn = y / (H p / 2); tuple in BACKLIGHT_TERMS order
    sheet_margin        the lens sheet reaches this far beyond the raster on every side
    subpixel_layout     None (a stripe panel by ``subpixel_order``) or a cell layout: channel c
                        of pixel (x, y) has its centre at (x + 0.5 + dx_c, y + 0.5 + dy_c) pixels,
                        (dx_c, dy_c) of the pixel's cell (:mod:`lenticalib.core.layout`)
    blur_shape          profile of the blur across the lens (``BLUR_SHAPES``, docs/crosstalk.md "What the
                        measurement assumes"): "gaussian" (the default), "disc" (a defocused lens:
                        a uniform disc's projection across u, a semicircle of radius 2 sigma_u, the
                        Gaussian's variance) or "lorentzian" (a Cauchy profile of half width
                        sigma_u sqrt(2 ln 2), the Gaussian's half maximum, its tail cut at 20
                        half widths); each drawn as a sum of Gaussians (:meth:`blur_components`)
    lenticule_aperture  vignetting across a lenticule: the light of a pixel-plane point ``o`` mm
                        (across the lens) from its lens' axis is weighted ``exp(-o^2 / (2 a^2))``,
                        ``a`` this fraction of the lens pitch P_u (its aperture cuts the steep
                        rays); 0 (the default) = no vignetting
    bezel_width         dark frame around the sheet (mm on every side)
    bezel_level         bezel radiance, relative to a fully open white subpixel
    background_level    radiance of everything outside the bezel (a dim room), same unit
    """

    width: int
    height: int
    pixel_pitch: float
    lens_pitch: float
    slant_angle: float
    gap: float
    x0: float
    subpixel_order: str = "RGB"
    black_matrix_h: float = 0.2
    black_matrix_v: float = 0.1
    blur_sigma: float = 0.015
    blur_growth: float = 0.8
    scatter: float = 0.02
    angular_falloff: float = 1.0
    backlight: tuple[float, float, float, float, float] = (0.0, 0.0, 0.0, 0.0, 0.0)
    sheet_margin: float = 0.5
    bezel_width: float = 8.0
    bezel_level: float = 0.005
    background_level: float = 0.03
    subpixel_layout: SubpixelLayout | None = None
    blur_shape: str = "gaussian"
    lenticule_aperture: float = 0.0

    def __post_init__(self):
        def fail(field, message):
            raise InputError(f"panel optics field '{field}': {message}", source="scene")

        for key in ("width", "height"):
            if not isinstance(getattr(self, key), int) or getattr(self, key) < 1:
                fail(key, f"must be a positive whole number of pixels, got {getattr(self, key)!r}")
        for key in ("pixel_pitch", "lens_pitch", "gap", "blur_sigma"):
            value = getattr(self, key)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
                fail(key, f"must be a number > 0 mm, got {value!r}")
        if not abs(self.slant_angle) < math.radians(60):
            fail("slant_angle", f"must be within +-60 degrees (radians), got {self.slant_angle!r}")
        if self.subpixel_order not in SUBPIXEL_ORDERS:
            fail("subpixel_order", f"must be \"RGB\" or \"BGR\", got {self.subpixel_order!r}")
        if self.subpixel_layout is not None:
            if not isinstance(self.subpixel_layout, SubpixelLayout):
                fail("subpixel_layout", "must be a SubpixelLayout")
            if self.subpixel_order != "RGB":
                fail("subpixel_order", "must be \"RGB\" with a subpixel_layout (its slots are R, G, B)")
        for key in ("black_matrix_h", "black_matrix_v"):
            if not 0.0 <= getattr(self, key) < 0.9:
                fail(key, f"must be a fraction in [0, 0.9), got {getattr(self, key)!r}")
        if not 0.0 <= self.scatter < 1.0:
            fail("scatter", f"must be a fraction in [0, 1), got {self.scatter!r}")
        if len(self.backlight) != len(BACKLIGHT_TERMS):
            fail("backlight", f"needs {len(BACKLIGHT_TERMS)} coefficients ({', '.join(BACKLIGHT_TERMS)})")
        if self.blur_shape not in BLUR_SHAPES:
            fail("blur_shape", f"must be one of {', '.join(BLUR_SHAPES)}, got {self.blur_shape!r}")
        for key in ("lenticule_aperture", "blur_growth", "angular_falloff", "sheet_margin", "bezel_width", "bezel_level",
                    "background_level"):
            value = getattr(self, key)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value >= 0):
                fail(key, f"must be a finite number >= 0, got {value!r}")

    # --- derived quantities -------------------------------------------------------------------
    @property
    def slant(self) -> float:
        """C_r = tan(phi), pixels per row."""
        return math.tan(self.slant_angle)

    @property
    def lens_pitch_u(self) -> float:
        """P_u = P_h cos(phi), lens pitch across the lens (mm)."""
        return self.lens_pitch * math.cos(self.slant_angle)

    @property
    def panel_size(self) -> tuple[float, float]:
        """Raster extent (W p, H p) in mm."""
        return self.width * self.pixel_pitch, self.height * self.pixel_pitch

    @property
    def rho(self) -> tuple[int, int, int]:
        """Subpixel position (0, 1, 2) of the R, G, B channels."""
        return (0, 1, 2) if self.subpixel_order == "RGB" else (2, 1, 0)

    def slot_shifts(self) -> np.ndarray:
        """Slot shift ``e`` (subpixels) of every slot, float64 ``(rows, 3 * columns)`` indexed
        ``[y % rows, 3 (x % columns) + slot]``: zeros ``(1, 3)`` on a stripe panel.

        Channel ``c`` of pixel ``x`` lies, across the lenses, where a stripe subpixel at
        ``x_s = 3 x + c + e`` lies (``e = 1 + 3 dx_c - 3 C_r dy_c - c``,
        :meth:`~lenticalib.core.layout.SubpixelLayout.slot_shifts`): its centre
        ``(x_s + 1 + 3 dx_c - c + 0.5, y + 0.5 + dy_c)`` is on the same lens line as
        ``(x_s + e + 0.5, y + 0.5)`` (moving a point down by ``dy`` rows and left by ``3 C_r dy``
        subpixels keeps it on the same lens line).  The truth routes by this; the renderer puts
        the apertures at the true centres (:meth:`channel_offsets`).
        """
        layout = self.subpixel_layout
        return np.zeros((1, 3)) if layout is None else layout.slot_shift_table(self.slant)

    def channel_offsets(self) -> np.ndarray:
        """Where each slot's channel sits relative to the stripe RGB slot, float64
        ``(2, rows, 3 * columns)`` indexed ``[:, y % rows, 3 (x % columns) + slot]``: along the row in
        subpixels, ``1 + 3 dx_c - c``, and down in rows, ``dy_c`` (zeros ``(2, 1, 3)`` on a stripe
        panel).  The renderer puts each channel's aperture there (its true centre)."""
        layout = self.subpixel_layout
        if layout is None:
            return np.zeros((2, 1, 3))
        along = [[1.0 + 3.0 * dx - c for c, (dx, _) in enumerate(cell)] for cell in layout.cells]
        down = [[float(dy) for _, dy in cell] for cell in layout.cells]
        return np.array([layout.per_slot(table) for table in (along, down)])

    def slot_shift_at(self, xs, y) -> np.ndarray:
        """The slot shift ``e`` (subpixels) of slots ``xs`` (``3 x + slot``) in rows ``y`` (integer
        arrays, broadcast); float64, zeros on a stripe panel."""
        shifts = self.slot_shifts()
        xs, y = np.asarray(xs, np.int64), np.asarray(y, np.int64)
        cols3 = shifts.shape[1]
        return shifts[y % shifts.shape[0], (3 * ((xs // 3) % (cols3 // 3))) + xs % 3]

    def period_at(self, distance: float) -> float:
        """Delta_r = 3 P_h (1 + g / D) / p: the routing period (subpixels) for eyes at ``distance`` mm."""
        return 3.0 * self.lens_pitch * (1.0 + self.gap / distance) / self.pixel_pitch

    def view_zone_width(self, distance: float, views: int) -> float:
        """Lateral width (mm, along world x) of one view zone in the eye plane at ``distance``.

        Moving an eye by this much along x changes the view it sees by one:
        ``P_u (D + g) / (g N cos(phi)) = P_h (D + g) / (g N)``.
        """
        return self.lens_pitch * (distance + self.gap) / (self.gap * views)

    def blur_components(self) -> np.ndarray:
        """The blur profile as a sum of Gaussians: float64 ``(K, 3)`` rows ``(weight, offset, scale)``,
        weights summing to 1, offset and scale in units of sigma_u (the component is centred
        ``offset sigma_u`` from the seen point, ``scale sigma_u`` wide).  ``[[1, 0, 1]]`` for
        "gaussian"; "disc": 9 Gaussians 0.2 R wide at even offsets over ``[-0.75 R, 0.75 R]``, R = 2
        sigma_u, weighted by the semicircle (variance 0.98 sigma_u^2, within 0.05 / sigma_u of the
        semicircle's density); "lorentzian": the Cauchy profile as its Gaussian scale mixture
        (precision ``1/s^2`` Gamma-distributed, shape 1/2), 12 scales from 0.1 to 20 half widths
        (within 0.01 / sigma_u of the Cauchy density)."""
        if self.blur_shape == "disc":
            offsets = np.linspace(-1.5, 1.5, 9)
            weights = np.sqrt(4.0 - offsets ** 2)
            scales = np.full_like(offsets, 0.4)
        elif self.blur_shape == "lorentzian":
            half = math.sqrt(2.0 * math.log(2.0))  # the half width gamma, in sigma_u
            log_s = np.linspace(math.log(0.1), math.log(20.0), 12)
            # density of log s when 1/s^2 ~ Gamma(1/2, rate gamma^2 / 2) (s in half widths)
            weights = np.exp(-log_s - 0.5 * np.exp(-2.0 * log_s))
            scales = half * np.exp(log_s)
            offsets = np.zeros_like(scales)
        else:
            return np.array([[1.0, 0.0, 1.0]])
        return np.column_stack([weights / weights.sum(), offsets, scales])

    # --- coordinates ---------------------------------------------------------------------------
    def raster_to_world(self, X, Y) -> tuple[np.ndarray, np.ndarray]:
        """Continuous raster coordinates (subpixels, rows) -> pixel-plane (x, y) in mm."""
        p = self.pixel_pitch
        return (np.asarray(X, np.float64) * p / 3.0 - self.width * p / 2.0,
                np.asarray(Y, np.float64) * p - self.height * p / 2.0)

    def world_to_raster(self, x, y) -> tuple[np.ndarray, np.ndarray]:
        """Pixel-plane (x, y) in mm -> continuous raster coordinates (X subpixels, Y rows)."""
        p = self.pixel_pitch
        return ((np.asarray(x, np.float64) + self.width * p / 2.0) * 3.0 / p,
                (np.asarray(y, np.float64) + self.height * p / 2.0) / p)

    def to_uv(self, x, y) -> tuple[np.ndarray, np.ndarray]:
        """World (x, y) -> lens coordinates (u across the lenses, v along them), mm."""
        c, s = math.cos(self.slant_angle), math.sin(self.slant_angle)
        x, y = np.asarray(x, np.float64), np.asarray(y, np.float64)
        return x * c - y * s, x * s + y * c

    def from_uv(self, u, v) -> tuple[np.ndarray, np.ndarray]:
        """Lens coordinates (u, v) -> world (x, y), mm."""
        c, s = math.cos(self.slant_angle), math.sin(self.slant_angle)
        u, v = np.asarray(u, np.float64), np.asarray(v, np.float64)
        return u * c + v * s, -u * s + v * c

    def lens_index(self, u) -> np.ndarray:
        """Index k of the lens containing across-lens coordinate ``u`` (mm), int64."""
        x0u = self.x0 * math.cos(self.slant_angle)
        return np.floor((np.asarray(u, np.float64) - x0u) / self.lens_pitch_u).astype(np.int64)

    def lens_centre(self, k) -> np.ndarray:
        """Across-lens coordinate u_c (mm) of the centre line of lens ``k``."""
        x0u = self.x0 * math.cos(self.slant_angle)
        return x0u + (np.asarray(k, np.float64) + 0.5) * self.lens_pitch_u

    def seen_point(self, eye, lens_x, lens_y) -> tuple[np.ndarray, np.ndarray]:
        """Pixel-plane point (x_P, y_P) mm that an eye sees through lens-plane point (lens_x, lens_y).

        ARGUMENTS
        eye               (ex, ey, ez) world mm with ez = -D < 0
        lens_x, lens_y    where the ray meets the lens plane z = 0 (world mm, any shape)

        RETURNED VALUE
        (x_P, y_P) arrays of the broadcast shape, world mm on the pixel plane (z = g); the
        focus-free blur is not applied.
        """
        ex, ey, ez = (float(c) for c in eye)
        distance = -ez
        if not distance > 0:
            raise InputError(f"the eye must be in front of the panel (z < 0), got z = {ez}", source="eye")
        ratio = self.gap / distance
        u_l, v_l = self.to_uv(lens_x, lens_y)
        u_e, v_e = self.to_uv(ex, ey)
        u_c = self.lens_centre(self.lens_index(u_l))
        return self.from_uv(u_c + (u_c - u_e) * ratio, v_l + (v_l - v_e) * ratio)

    # --- construction --------------------------------------------------------------------------
    @classmethod
    def from_routing(cls, period: float, slant: float, distance: float, *, width: int, height: int,
                     pixel_pitch: float, kappa: float = 1.3, x0_fraction: float = 0.0,
                     **extras: Any) -> "PanelOptics":
        """A panel whose ideal routing seen from ``distance`` mm has ``period`` and ``slant``.

        ARGUMENTS
        period          Delta_r in subpixels at the eye distance (> 0)
        slant           C_r = tan(phi), pixels per row
        distance        D, eye distance to the lens plane (mm)
        width, height   raster in pixels; pixel_pitch p in mm
        kappa           gap in lens pitches: g = kappa P_u (sets the view-cone width,
                        full cone angle ~ 2 atan(1 / (2 kappa)) in air)
        x0_fraction     lens boundary offset x0 as a fraction of P_h, in [0, 1)
        extras          any other PanelOptics field (black matrix, blur, ...)

        The lens pitch solves ``3 P_h (1 + kappa P_h cos(phi) / D) / p = Delta_r`` (a quadratic
        in P_h, positive root), so ``period_at(distance)`` returns ``period`` to rounding.
        """
        if not (period > 0 and distance > 0 and pixel_pitch > 0 and kappa > 0):
            raise InputError("period, distance, pixel pitch and kappa must be > 0", source="scene",
                             hint=f"got period={period}, distance={distance}, pixel_pitch={pixel_pitch}, "
                                  f"kappa={kappa}")
        phi = math.atan(slant)
        a = 3.0 * kappa * math.cos(phi) / (distance * pixel_pitch)
        b = 3.0 / pixel_pitch
        # a P^2 + b P - period = 0, positive root in the cancellation-free form
        lens_pitch = 2.0 * period / (b + math.sqrt(b * b + 4.0 * a * period))
        gap = kappa * lens_pitch * math.cos(phi)
        return cls(width=width, height=height, pixel_pitch=pixel_pitch, lens_pitch=lens_pitch,
                   slant_angle=phi, gap=gap, x0=(x0_fraction % 1.0) * lens_pitch, **extras)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready mapping of every field."""
        data = dataclasses.asdict(self)
        data["backlight"] = list(self.backlight)
        for key, default in (("blur_shape", "gaussian"), ("lenticule_aperture", 0.0)):
            if data[key] == default:  # a scene without them reads as before they existed
                del data[key]
        if self.subpixel_layout is None:  # a stripe panel's scene reads as before layouts existed
            del data["subpixel_layout"]
        else:
            data["subpixel_layout"] = self.subpixel_layout.to_dict()
        return data

    @classmethod
    def from_dict(cls, data: Mapping[str, Any], source: str = "scene") -> "PanelOptics":
        """Inverse of :meth:`to_dict`; InputError naming ``source`` for unknown or missing fields."""
        fields = fields_from(cls, data, source, "optics", tuples=("backlight",))
        if fields.get("subpixel_layout") is not None:
            try:
                fields["subpixel_layout"] = layout_from_dict(fields["subpixel_layout"], source)
            except InputError as exc:
                raise InputError(exc.message.replace("field 'subpixel_layout", "optics field 'subpixel_layout"),
                                 source=source, hint=exc.hint) from None
        return cls(**fields)


def fields_from(cls, data: Any, source: str, what: str, tuples: tuple[str, ...] = ()) -> dict[str, Any]:
    """Keyword arguments for dataclass ``cls`` from a JSON mapping, with one-line errors."""
    if not isinstance(data, Mapping):
        raise InputError(f"'{what}' must be a JSON object", source=source)
    names = {f.name for f in dataclasses.fields(cls)}
    required = {f.name for f in dataclasses.fields(cls)
                if f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING}
    unknown = set(data) - names
    if unknown:
        raise InputError(unknown_key_message(unknown, names, f"{what} field"), source=source,
                         hint="known: " + ", ".join(sorted(names)))
    missing = sorted(required - set(data))
    if missing:
        raise InputError(f"missing {what} field(s): {', '.join(missing)}", source=source)
    out = dict(data)
    for key in tuples:
        if key in out and out[key] is not None:
            if not isinstance(out[key], (list, tuple)):
                raise InputError(f"{what} field '{key}' must be a list of numbers", source=source)
            out[key] = tuple(out[key])
    return out
