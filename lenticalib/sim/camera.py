"""The virtual camera: OpenCV pinhole + distortion model, pose, and photometric settings.

Frames and units
----------------
World (mm): as in :mod:`.optics` (x right, y down, z into the screen, lens plane z = 0).
Camera frame: OpenCV's (x right, y down, z along the optical axis).  A camera at
``(0, 0, -D)`` with no roll looking at the panel centre has the camera axes equal to the
world axes.

Pixel coordinates: OpenCV's, (0, 0) is the *centre* of the top-left pixel; pixel (i, j)
(row i, column j) covers ``[j - 0.5, j + 0.5) x [i - 0.5, i + 0.5)``.

Projection: ``cv2.projectPoints`` with ``K = [[fx, 0, cx], [0, fy, cy], [0, 0, 1]]`` and
distortion ``(k1, k2, p1, p2, k3)``; rays come from ``cv2.undistortPoints`` (iterated to
1e-12), so rendering and projection are exact inverses of each other.

Photometric unit: 1.0 is sensor saturation.  ``exposure`` converts panel radiance (1.0 = a fully
open white subpixel seen head-on, before the black matrix) into sensor signal.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any, Mapping

import numpy as np

from ..core.errors import InputError
from .optics import fields_from

JPEG_CHROMA = ("4:2:0", "4:4:4")  # the JPEG chroma resolutions the camera writes (Camera.jpeg_chroma)
DEMOSAICING = ("edge-aware", "bilinear")  # how the camera fills in each pixel's missing colours (Camera.demosaicing)
UNDISTORT_CRITERIA = (3, 100, 1e-13)  # cv2.TERM_CRITERIA_COUNT | EPS, iterations, epsilon


@dataclasses.dataclass(frozen=True)
class Camera:
    """A camera photographing the panel.

    GEOMETRY
    width, height     sensor size in pixels
    fx, fy, cx, cy    OpenCV intrinsics in pixels (principal point in pixel coordinates)
    distortion        (k1, k2, p1, p2, k3), OpenCV's radial-tangential model
    position          camera centre (ex, ey, ez) in world mm; ez = -D < 0 (D = distance to
                      the lens plane)
    aim               (ax, ay): the point of the lens plane z = 0 (world mm) on the optical axis
    roll              rotation about the optical axis, degrees (positive turns the image
                      content counter-clockwise)

    RENDERING
    subsamples        n: every sensor pixel integrates an n x n grid of stratified rays

    PHOTOMETRY (applied in this order after the radiance is rendered)
    colour_matrix     3 x 3 row-major: camera channel (R, G, B) response to the panel's
                      (R, G, B) primaries, white-balanced rows (sum ~ 1)
    exposure          sensor signal per unit panel radiance (1.0 = saturation)
    vignetting        (a2, a4): relative illumination 1 - a2 r^2 - a4 r^4, r = distance from
                      the principal point / half the sensor diagonal
    defocus_sigma     Gaussian defocus blur, pixels
    chromatic         lateral chromatic aberration: (m_R, m_B), magnification of the red and blue
                      images relative to green about the principal point (0.0003 moves a
                      point 3000 px off-centre by 0.9 px)
    glare_fraction    share of the light spread as veiling glare (a blurred copy of the image)
    glare_sigma       width of the veiling glare, as a fraction of the sensor width
    flare             constant flare added everywhere (saturation units)
    full_well         electrons at saturation (shot noise); None = no noise at all
    read_noise        read noise, electrons RMS
    tone_gamma        exponent applied after the sRGB encoding (1.0 = plain sRGB)
    tone_contrast     strength s in [0, 1] of a phone-style S-curve after that:
                      v -> (1 - s) v + s (3 v^2 - 2 v^3)  (0 = none, 1 = a strong S)
    sharpen           unsharp-mask amount of the camera's processing (0 = none)
    jpeg_quality      JPEG quality (1..100); None = no JPEG compression
    jpeg_chroma       the JPEG's chroma resolution: "4:2:0" (half in both directions, what
                      phones and most cameras write) or "4:4:4" (full)
    demosaicing       how the colours missing at each Bayer site are filled in: "edge-aware"
                      (OpenCV's, not linear: it takes light off rows the camera resolves, as
                      most cameras' do) or "bilinear" (linear: every area keeps its light)

    PER PHOTO (drawn afresh for every photo by :meth:`for_photo`; 0 = a locked, still camera)
    exposure_jitter   bound of the relative exposure change from photo to photo (auto
                      exposure that was not locked): exposure * (1 + U(-j, j))
    shake             bound of the image shift from photo to photo, pixels (a tripod that
                      shakes: a tiny rotation, modelled as a principal-point shift of
                      U(0, shake) pixels in a uniformly random direction)
    """

    width: int
    height: int
    fx: float
    fy: float
    cx: float
    cy: float
    distortion: tuple[float, float, float, float, float]
    position: tuple[float, float, float]
    aim: tuple[float, float] = (0.0, 0.0)
    roll: float = 0.0
    subsamples: int = 3
    colour_matrix: tuple[float, ...] = (1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0)
    exposure: float = 1.0
    vignetting: tuple[float, float] = (0.0, 0.0)
    defocus_sigma: float = 0.5
    chromatic: tuple[float, float] = (0.0, 0.0)
    glare_fraction: float = 0.0
    glare_sigma: float = 0.05
    flare: float = 0.0
    full_well: float | None = None
    read_noise: float = 0.0
    tone_gamma: float = 1.0
    sharpen: float = 0.0
    jpeg_quality: int | None = 90
    tone_contrast: float = 0.0
    exposure_jitter: float = 0.0
    shake: float = 0.0
    jpeg_chroma: str = "4:2:0"
    demosaicing: str = "edge-aware"

    def __post_init__(self):
        def fail(field, message, hint=None):
            raise InputError(f"camera field '{field}': {message}", source="scene", hint=hint)

        for key in ("width", "height", "subsamples"):
            if not isinstance(getattr(self, key), int) or getattr(self, key) < 1:
                fail(key, f"must be a positive whole number, got {getattr(self, key)!r}")
        if self.width < 16 or self.height < 16:
            fail("width", f"sensor {self.width}x{self.height} is too small (at least 16x16)")
        if self.subsamples > 16:
            fail("subsamples", f"must be at most 16, got {self.subsamples}")
        for key in ("fx", "fy"):
            if not getattr(self, key) > 0:
                fail(key, f"must be > 0 pixels, got {getattr(self, key)!r}")
        for key, n in (("distortion", 5), ("position", 3), ("aim", 2), ("colour_matrix", 9),
                       ("vignetting", 2), ("chromatic", 2)):
            value = getattr(self, key)
            if len(value) != n or not all(isinstance(v, (int, float)) and math.isfinite(v) for v in value):
                fail(key, f"needs {n} finite numbers, got {value!r}")
        if not self.position[2] < 0:
            fail("position", f"the camera must be in front of the panel (z < 0), got z = {self.position[2]}")
        if self.jpeg_quality is not None and not (isinstance(self.jpeg_quality, int)
                                                  and 1 <= self.jpeg_quality <= 100):
            fail("jpeg_quality", f"must be a whole number 1..100 or null, got {self.jpeg_quality!r}")
        if self.jpeg_chroma not in JPEG_CHROMA:
            fail("jpeg_chroma", f"must be one of {', '.join(JPEG_CHROMA)}, got {self.jpeg_chroma!r}")
        if self.demosaicing not in DEMOSAICING:
            fail("demosaicing", f"must be one of {', '.join(DEMOSAICING)}, got {self.demosaicing!r}")
        if self.full_well is not None and not self.full_well > 0:
            fail("full_well", f"must be > 0 electrons or null, got {self.full_well!r}")
        for key in ("exposure", "tone_gamma", "glare_sigma"):
            if not getattr(self, key) > 0:
                fail(key, f"must be > 0, got {getattr(self, key)!r}")
        for key in ("defocus_sigma", "glare_fraction", "flare", "read_noise", "sharpen", "shake"):
            if not getattr(self, key) >= 0:
                fail(key, f"must be >= 0, got {getattr(self, key)!r}")
        if not 0 <= self.tone_contrast <= 1:
            fail("tone_contrast", f"must be in [0, 1], got {self.tone_contrast!r}")
        if not 0 <= self.exposure_jitter < 0.5:
            fail("exposure_jitter", f"must be a fraction in [0, 0.5), got {self.exposure_jitter!r}")
        if not 0 <= self.glare_fraction < 1:
            fail("glare_fraction", f"must be a fraction in [0, 1), got {self.glare_fraction!r}")
        self._check_distortion_invertible()

    # --- pose --------------------------------------------------------------------------------
    @property
    def distance(self) -> float:
        """D: distance of the camera centre to the lens plane, mm."""
        return -float(self.position[2])

    @property
    def rotation(self) -> np.ndarray:
        """R_world_cam (3 x 3): columns are the camera x, y, z axes in world coordinates."""
        centre = np.asarray(self.position, np.float64)
        forward = np.array([self.aim[0], self.aim[1], 0.0]) - centre
        z_c = forward / np.linalg.norm(forward)
        x_c = np.cross([0.0, 1.0, 0.0], z_c)
        x_c /= np.linalg.norm(x_c)
        y_c = np.cross(z_c, x_c)
        r = math.radians(self.roll)
        x_r = math.cos(r) * x_c + math.sin(r) * y_c
        y_r = -math.sin(r) * x_c + math.cos(r) * y_c
        return np.stack([x_r, y_r, z_c], axis=1)

    @property
    def camera_matrix(self) -> np.ndarray:
        """K, 3 x 3 float64."""
        return np.array([[self.fx, 0.0, self.cx], [0.0, self.fy, self.cy], [0.0, 0.0, 1.0]])

    @property
    def dist_coeffs(self) -> np.ndarray:
        """(k1, k2, p1, p2, k3) as float64 array of shape (5,)."""
        return np.asarray(self.distortion, np.float64)

    def extrinsics(self) -> tuple[np.ndarray, np.ndarray]:
        """(rvec, tvec) of the world -> camera transform, as cv2.projectPoints takes them."""
        import cv2

        r_cw = self.rotation.T
        tvec = -r_cw @ np.asarray(self.position, np.float64)
        rvec, _ = cv2.Rodrigues(r_cw)
        return rvec.reshape(3), tvec

    # --- projection and rays ------------------------------------------------------------------
    def project(self, points: np.ndarray) -> np.ndarray:
        """World points ``(n, 3)`` mm -> pixel coordinates ``(n, 2)`` (cv2.projectPoints)."""
        import cv2

        rvec, tvec = self.extrinsics()
        pts = np.ascontiguousarray(np.asarray(points, np.float64).reshape(-1, 3))
        out, _ = cv2.projectPoints(pts, rvec, tvec, self.camera_matrix, self.dist_coeffs)
        return out.reshape(-1, 2)

    def normalized(self, px, py) -> tuple[np.ndarray, np.ndarray]:
        """Pixel coordinates -> undistorted normalized camera coordinates (x/z, y/z), same shape."""
        import cv2

        px, py = np.broadcast_arrays(np.asarray(px, np.float64), np.asarray(py, np.float64))
        pts = np.stack([px.ravel(), py.ravel()], axis=1).reshape(-1, 1, 2)
        und = cv2.undistortPoints(pts, self.camera_matrix, self.dist_coeffs, criteria=UNDISTORT_CRITERIA)
        und = und.reshape(-1, 2)
        return und[:, 0].reshape(px.shape), und[:, 1].reshape(px.shape)

    def pixel_rays(self, px, py) -> np.ndarray:
        """World directions (not normalized, camera-frame z component 1) of the rays through pixel
        coordinates ``(px, py)``: float64 array of shape ``px.shape + (3,)``."""
        xn, yn = self.normalized(px, py)
        cam = np.stack([xn, yn, np.ones_like(xn)], axis=-1)
        return cam @ self.rotation.T

    def lens_plane_points(self, px, py) -> tuple[np.ndarray, np.ndarray]:
        """Where the rays through pixel coordinates meet the lens plane z = 0: (x, y) world mm.

        NaN where the ray does not reach the plane in front of the camera.
        """
        d = self.pixel_rays(px, py)
        with np.errstate(divide="ignore", invalid="ignore"):
            t = np.where(d[..., 2] > 1e-9, self.distance / d[..., 2], np.nan)
        return self.position[0] + t * d[..., 0], self.position[1] + t * d[..., 1]

    def _check_distortion_invertible(self) -> None:
        """The radial distortion must be monotonic out to the sensor corners (else rays are ambiguous)."""
        k1, k2, _, _, k3 = self.distortion
        corners = np.array([[0, 0], [self.width, 0], [0, self.height], [self.width, self.height]], float) - 0.5
        rd_max = float(np.max(np.hypot((corners[:, 0] - self.cx) / self.fx, (corners[:, 1] - self.cy) / self.fy)))
        r = np.linspace(0.0, 4.0, 4001)
        r2 = r * r
        slope = 1 + 3 * k1 * r2 + 5 * k2 * r2 * r2 + 7 * k3 * r2 ** 3
        bad = np.nonzero(slope <= 0)[0]
        if bad.size:
            rc = r[bad[0]]
            reach = rc * (1 + k1 * rc ** 2 + k2 * rc ** 4 + k3 * rc ** 6)
            if reach < 1.02 * rd_max:
                raise InputError("camera field 'distortion': the radial distortion folds over inside the "
                                 f"image (monotonic only to normalized radius {reach:.3f}, corners at "
                                 f"{rd_max:.3f})", source="scene",
                                 hint="use smaller |k2|, |k3| or a longer focal length")

    # --- variants and JSON --------------------------------------------------------------------
    def clean(self) -> "Camera":
        """A copy without noise, JPEG, vignetting, glare, flare and sharpening (for tests)."""
        return dataclasses.replace(self, full_well=None, read_noise=0.0, jpeg_quality=None,
                                   vignetting=(0.0, 0.0), glare_fraction=0.0, flare=0.0, sharpen=0.0)

    def for_photo(self, rng: np.random.Generator) -> tuple["Camera", dict[str, float]]:
        """This camera as it takes one photo: exposure drift and shake drawn from ``rng``.

        Returns (camera, {"exposure_factor", "shift_x", "shift_y"}) -- the factor applied to
        ``exposure`` and the principal-point shift in pixels.  Draws nothing from ``rng`` and
        returns ``self`` unchanged when both ``exposure_jitter`` and ``shake`` are 0.
        """
        if not (self.exposure_jitter or self.shake):
            return self, {"exposure_factor": 1.0, "shift_x": 0.0, "shift_y": 0.0}
        factor = 1.0 + float(rng.uniform(-self.exposure_jitter, self.exposure_jitter))
        radius = float(rng.uniform(0.0, self.shake))
        angle = float(rng.uniform(0.0, 2.0 * math.pi))
        dx, dy = radius * math.cos(angle), radius * math.sin(angle)
        camera = dataclasses.replace(self, exposure=self.exposure * factor, cx=self.cx + dx, cy=self.cy + dy)
        return camera, {"exposure_factor": factor, "shift_x": dx, "shift_y": dy}

    def replace(self, **changes: Any) -> "Camera":
        """A copy with some fields changed (validated again)."""
        return dataclasses.replace(self, **changes)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready mapping of every field."""
        data = dataclasses.asdict(self)
        for key in ("distortion", "position", "aim", "colour_matrix", "vignetting", "chromatic"):
            data[key] = list(data[key])
        return data

    @classmethod
    def from_dict(cls, data: Mapping[str, Any], source: str = "scene") -> "Camera":
        """Inverse of :meth:`to_dict`; InputError naming ``source`` for unknown or missing fields."""
        return cls(**fields_from(cls, data, source, "camera",
                                  tuples=("distortion", "position", "aim", "colour_matrix", "vignetting",
                                          "chromatic")))
