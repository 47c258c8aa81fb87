"""The views stage on the host: rendered RGBA views -> the uint8 views an encoder takes.

:func:`prepare_views` puts the background under the premultiplied colour, desaturates the edges,
rounds to 8 bits and pre-compensates crosstalk; :mod:`.gl_views` is the same on the GPU.  Both
:class:`~.loop.AvatarPipeline` and :class:`~.gl_pipeline.GLFrame` (its host path) call it.
"""

from __future__ import annotations

import numpy as np


def desaturate_edges(rgba, strength: float):
    """The LentiAvatar alpha-boundary chroma attenuation: where alpha is partial, pull the colour
    toward its own luminance by ``strength * (1 - alpha)`` (numpy or torch, (..., 4))."""
    rgb, alpha = rgba[..., :3], rgba[..., 3:4]
    luma = 0.2126 * rgb[..., 0:1] + 0.7152 * rgb[..., 1:2] + 0.0722 * rgb[..., 2:3]
    keep = 1.0 - strength * (1.0 - alpha)
    return luma + (rgb - luma) * keep


def prepare_views(rgba: np.ndarray, background, edge_desaturation: float, compensator, *,
                  background_rendered: bool) -> np.ndarray:
    """Rendered (N, H_v, W_v, 4) float32 RGBA -> the uint8 views to encode (N, H_v, W_v, 3), on the
    host: ``background`` (None, (3,) or (H_v, W_v, 3)) under the premultiplied colour unless the
    renderer already put it there (``background_rendered``), edge desaturation, rounding to 8
    bits, crosstalk pre-compensation (``compensator`` or None).  ``rgba`` may be modified.
    :class:`lenticalib.render.compose.gl_views.GLViewStage` is the same on the GPU."""
    if background is not None and not background_rendered:  # rgb += (1 - alpha) * background
        rgba[..., :3] += (1.0 - rgba[..., 3:4]) * (background if np.ndim(background) == 1 else background[None])
    views = to_uint8(np.ascontiguousarray(desaturate_edges(rgba, edge_desaturation))
                     if edge_desaturation > 0 else rgba)
    return compensator.apply(views) if compensator is not None else views


def views_on_host(views) -> np.ndarray:
    """The views a pipeline frame returned, as numpy (N, H_v, W_v, 3) uint8: as they are (numpy), read
    back from OpenGL (:class:`lenticalib.render.pipeline.gl_frame.FrameViews`) or from a torch device."""
    if isinstance(views, np.ndarray):
        return views
    if hasattr(views, "to_host"):
        return views.to_host()
    return views.cpu().numpy()


def to_uint8(rgb: np.ndarray) -> np.ndarray:
    """(..., 3 or 4) float in 0..1 -> (..., 3) uint8, rounded (alpha dropped); numba, in one pass."""
    return _to_uint8(rgb.reshape(-1, rgb.shape[-1])).reshape(rgb.shape[:-1] + (3,))


def _to_uint8_kernel():
    import numba

    @numba.njit(parallel=True, cache=True)
    def kernel(flat):
        out = np.empty((flat.shape[0], 3), np.uint8)
        for i in numba.prange(flat.shape[0]):
            for c in range(3):
                v = flat[i, c] * 255.0 + 0.5
                out[i, c] = 0 if v < 0.0 else (255 if v >= 255.0 else np.uint8(v))
        return out

    return kernel


_KERNEL = None


def _to_uint8(flat):
    global _KERNEL
    if _KERNEL is None:
        _KERNEL = _to_uint8_kernel()
    return _KERNEL(flat)
