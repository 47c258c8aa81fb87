"""A photo of the virtual panel: the camera's photometric chain and the photo files.

:func:`photograph` (uint8 RGB), :func:`photograph_jpeg` and :func:`photograph_raw_png` render the
radiance (:func:`.render.render_radiance`) and develop it (:func:`develop`).

Photometric chain (:func:`develop`)
    colour mixing -> exposure -> vignetting -> defocus -> lateral chromatic aberration ->
    veiling glare + flare -> Bayer RGGB mosaic -> shot (Gaussian approximation of Poisson) +
    read noise -> 16-bit raw -> demosaicing (OpenCV: edge-aware, or bilinear) -> sRGB tone curve
    with the camera's gamma tweak and S-curve -> sharpening -> 8 bit; then JPEG
    (:func:`photograph_jpeg`, OpenCV, 4:2:0 or 4:4:4 chroma).
"""

from __future__ import annotations

import functools

import numpy as np

from ..core.colour import srgb_encode
from ..core.errors import ImageError
from .camera import JPEG_CHROMA, Camera
from .panel_light import render_radiance
from .scene import Scene


@functools.lru_cache(maxsize=1)
def _vignetting_map(width: int, height: int, cx: float, cy: float, a2: float, a4: float) -> np.ndarray:
    yy, xx = np.mgrid[0:height, 0:width].astype(np.float32)
    r2 = ((xx - cx) ** 2 + (yy - cy) ** 2) / (0.25 * (width ** 2 + height ** 2))
    v = np.clip(1.0 - a2 * r2 - a4 * r2 * r2, 0.05, None).astype(np.float32)
    v.setflags(write=False)
    return v


@functools.lru_cache(maxsize=8)
def _tone_lut(gamma: float, contrast: float = 0.0) -> np.ndarray:
    """uint16 raw -> encoded value in [0, 1] (sRGB curve, ** gamma, then the S-curve of strength
    ``contrast``: v + contrast (3 v^2 - 2 v^3 - v)), float32 (65536,)."""
    v = np.arange(65536, dtype=np.float64) / 65535.0
    enc = np.power(srgb_encode(v), gamma)
    out = (enc + contrast * (3 * enc ** 2 - 2 * enc ** 3 - enc)).astype(np.float32)
    out.setflags(write=False)
    return out


def _lateral_chromatic(img: np.ndarray, camera: Camera) -> np.ndarray:
    """Magnify the red and blue planes by (1 + m_R), (1 + m_B) about the principal point."""
    import cv2

    h, w = img.shape[:2]
    planes = list(cv2.split(img))
    for c, m in ((0, camera.chromatic[0]), (2, camera.chromatic[1])):
        if m:
            s = 1.0 / (1.0 + m)  # destination -> source
            inverse = np.array([[s, 0.0, camera.cx * (1 - s)], [0.0, s, camera.cy * (1 - s)]])
            planes[c] = cv2.warpAffine(planes[c], inverse, (w, h), flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP,
                                       borderMode=cv2.BORDER_REPLICATE)
    return cv2.merge(planes)


def develop(radiance: np.ndarray, camera: Camera, rng: np.random.Generator, linear: bool = False) -> np.ndarray:
    """The camera's photometric chain: radiance per panel primary -> 8-bit sRGB photo.

    ARGUMENTS
    radiance   float32 ``(h, w, 3)`` from :func:`render_radiance`
    camera     photometric settings (see :class:`.camera.Camera`)
    rng        noise source (only used when ``camera.full_well`` is set)

    linear     stop after demosaicing: the camera's raw data as a raw converter writes it
               (linear 16-bit RGB, no tone curve, no sharpening, no JPEG)

    RETURNED VALUE
    uint8 ``(h, w, 3)`` RGB, before JPEG compression (uint16 linear with ``linear``).
    """
    import cv2

    h, w = radiance.shape[:2]
    m = np.asarray(camera.colour_matrix, np.float32).reshape(3, 3) * np.float32(camera.exposure)
    img = cv2.transform(radiance, m)
    a2, a4 = camera.vignetting
    if a2 or a4:
        img *= _vignetting_map(w, h, float(camera.cx), float(camera.cy), float(a2), float(a4))[:, :, None]
    if camera.defocus_sigma > 0:
        img = cv2.GaussianBlur(img, (0, 0), camera.defocus_sigma, borderType=cv2.BORDER_REFLECT)
    if any(camera.chromatic):
        img = _lateral_chromatic(img, camera)
    if camera.glare_fraction > 0:
        factor = 8
        small = cv2.resize(img, (max(1, w // factor), max(1, h // factor)), interpolation=cv2.INTER_AREA)
        small = cv2.GaussianBlur(small, (0, 0), max(camera.glare_sigma * w / factor, 0.5),
                                 borderType=cv2.BORDER_REPLICATE)
        veil = cv2.resize(small, (w, h), interpolation=cv2.INTER_LINEAR)
        img = cv2.addWeighted(img, 1.0 - camera.glare_fraction, veil, camera.glare_fraction, 0.0)
    if camera.flare > 0:
        img += np.float32(camera.flare)
    raw = np.empty((h, w), dtype=np.float32)  # Bayer RGGB
    raw[0::2, 0::2] = img[0::2, 0::2, 0]
    raw[0::2, 1::2] = img[0::2, 1::2, 1]
    raw[1::2, 0::2] = img[1::2, 0::2, 1]
    raw[1::2, 1::2] = img[1::2, 1::2, 2]
    if camera.full_well is not None:
        # shot noise (variance = electrons) and read noise together: one Gaussian per pixel
        fw = np.float32(camera.full_well)
        electrons = np.clip(raw, 0.0, 1.5) * fw
        sigma = np.sqrt(electrons + np.float32(camera.read_noise) ** 2)
        raw = (electrons + rng.standard_normal((h, w), dtype=np.float32) * sigma) / fw
    raw16 = np.clip(raw * np.float32(65535.0) + np.float32(0.5), 0.0, 65535.0).astype(np.uint16)
    rgb16 = cv2.demosaicing(raw16, cv2.COLOR_BayerRGGB2RGB_EA if camera.demosaicing == "edge-aware"
                            else cv2.COLOR_BayerRGGB2RGB)
    if linear:
        return rgb16
    enc = _tone_lut(float(camera.tone_gamma), float(camera.tone_contrast))[rgb16]
    if camera.sharpen > 0:
        soft = cv2.GaussianBlur(enc, (0, 0), 1.0, borderType=cv2.BORDER_REFLECT)
        enc = cv2.addWeighted(enc, 1.0 + camera.sharpen, soft, -camera.sharpen, 0.0)
    return cv2.convertScaleAbs(cv2.max(enc, 0.0), alpha=255.0)  # rounded, saturated to 0..255


def encode_jpeg(photo: np.ndarray, quality: int, chroma: str = "4:2:0") -> bytes:
    """uint8 RGB ``(h, w, 3)`` -> JPEG bytes (OpenCV; ``chroma`` "4:2:0", half resolution as most
    cameras write it, or "4:4:4")."""
    import cv2

    params = [cv2.IMWRITE_JPEG_QUALITY, int(quality)]
    if chroma == "4:4:4":
        params += [cv2.IMWRITE_JPEG_SAMPLING_FACTOR, cv2.IMWRITE_JPEG_SAMPLING_FACTOR_444]
    elif chroma not in JPEG_CHROMA:
        raise ImageError(f"unknown JPEG chroma {chroma!r}", source="photo", hint="use " + " or ".join(JPEG_CHROMA))
    ok, data = cv2.imencode(".jpg", np.ascontiguousarray(photo[:, :, ::-1]), params)
    if not ok:
        raise ImageError("JPEG encoding failed", source="photo")
    return data.tobytes()


def photograph_raw_png(raster: np.ndarray, scene: Scene, rng: np.random.Generator) -> bytes:
    """The camera's raw photo of the panel showing ``raster``: 16-bit linear RGB PNG bytes (as a raw
    converter such as dcraw -4 or rawpy writes them: demosaiced, no tone curve)."""
    import cv2

    rgb16 = develop(render_radiance(raster, scene), scene.camera, rng, linear=True)
    ok, data = cv2.imencode(".png", np.ascontiguousarray(rgb16[:, :, ::-1]))
    if not ok:
        raise ImageError("PNG encoding failed", source="photo")
    return data.tobytes()


def photograph_jpeg(raster: np.ndarray, scene: Scene, rng: np.random.Generator) -> bytes:
    """The camera's JPEG file of the panel showing ``raster`` (quality ``scene.camera.jpeg_quality``,
    95 when that is None)."""
    photo = develop(render_radiance(raster, scene), scene.camera, rng)
    return encode_jpeg(photo, scene.camera.jpeg_quality or 95, scene.camera.jpeg_chroma)


def photograph(raster: np.ndarray, scene: Scene, rng: np.random.Generator) -> np.ndarray:
    """A photo of the panel showing ``raster``: uint8 RGB ``(h, w, 3)`` at the camera's resolution.

    ARGUMENTS
    raster   uint8 ``(H, W, 3)`` sRGB panel raster of the scene's size
    scene    panel optics + camera
    rng      numpy Generator for the sensor noise (same seed -> identical photo)

    With ``scene.camera.jpeg_quality`` set the photo has been through JPEG (encoded and decoded
    again); otherwise it is the camera's 8-bit output.
    """
    photo = develop(render_radiance(raster, scene), scene.camera, rng)
    if scene.camera.jpeg_quality is None:
        return photo
    import cv2

    data = encode_jpeg(photo, scene.camera.jpeg_quality, scene.camera.jpeg_chroma)
    return cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_COLOR)[:, :, ::-1].copy()
