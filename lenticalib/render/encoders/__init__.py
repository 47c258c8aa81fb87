"""Encoders: N rendered views -> one panel raster, selected by name through a lazy registry.

    reference   canonical routing and float64 bilinear sampling written out plainly (the golden model)
    tables      a precomputed view table per subpixel (canonical routing) + sample points
    fast        canonical routing, vectorized numba kernels (the default)
    torch       sparse tables on a torch device (CPU or CUDA); numpy in, numpy out through the registry,
                tensors in and out with ``torch_encoder.TorchEncoder`` (needs PyTorch)
    gl          a fragment shader in an OpenGL 3.3 context (any GPU driver, or Mesa's llvmpipe); numpy in
                and out through the registry (an offscreen EGL context), straight into a presenter's
                framebuffer with ``gl_encoder.GLEncoder`` (uint8 views)

Modules: ``reference``, ``tables`` and ``fast`` (one encoder each, as above), ``_permute`` and
``_simd`` (the explicitly vectorized uint8 block kernels of ``fast``: byte permutes on CPUs with
AVX-512 VBMI, gathers elsewhere), ``gl_encoder`` (the ``gl`` encoder), ``torch_encoder`` (the ``torch`` encoder)
with ``torch_tables`` (its sparse tables), and ``common`` (what every encoder checks and shares:
the view stack and the output raster).  Part of the render layer: imports only core and render.

All of them route by :func:`lenticalib.core.routing.view_map` (same view for every subpixel, ties
included; subpixel layouts and reversed views included) and sample where
:mod:`lenticalib.render.compose.sampling` says (the image flips included).  ``tables`` and ``torch`` equal ``reference`` bit for bit; ``fast`` does too for uint16 and float
views and is within 1 LSB for uint8 (fixed-point weights); ``gl`` is within 1 LSB (float32).

Modules are imported only when an encoder is asked for, so ``lenticalib --help`` stays instant.
Third-party encoders register through the ``lenticalib.encoders`` entry-point group (a plugin
group name, like ``lenticalib.transports``, not this module's path) with a value
``"module:function"``; the function takes ``(views, profile)`` and returns the raster.
"""

from __future__ import annotations

from typing import Callable

import numpy as np

from ...core.plugins import Registry
from ...core.profile import PanelProfile
from .common import check_views, output_like

DEFAULT_ENCODER = "fast"

ENCODERS = Registry("encoder", {
    "reference": "lenticalib.render.encoders.reference:encode_reference",
    "tables": "lenticalib.render.encoders.tables:encode_tables",
    "fast": "lenticalib.render.encoders.fast:encode_fast",
    "torch": "lenticalib.render.encoders.torch_encoder:encode_torch",
    "gl": "lenticalib.render.encoders.gl_encoder:encode_gl",
}, "lenticalib.encoders")


def available_encoders() -> list[str]:
    """Names of every registered encoder."""
    return ENCODERS.names()


def get_encoder(name: str, device: str | None = None) -> Callable[..., np.ndarray]:
    """The encode function registered as ``name``, able to run here (on torch ``device``, if given).

    Raises InputError for an unknown name, BackendUnavailableError when its module fails to import
    or it cannot run here (``torch`` on a CUDA device torch does not see): one line naming the
    encoders that can.
    """
    return ENCODERS.load(name, "encoder", device=device)


def compensates_on_device(method: str) -> bool:
    """Whether encoder ``method`` applies crosstalk pre-compensation itself, on its device (``gl``:
    on the GPU), when :func:`encode` is given a compensator."""
    return bool(getattr(get_encoder(method), "compensates", False))


def encode(views: np.ndarray, profile: PanelProfile, method: str = DEFAULT_ENCODER, *,
           out: np.ndarray | None = None, allow_stretch: bool = False, compensator=None) -> np.ndarray:
    """Encode ``views`` ``(N, H_v, W_v, 3)`` RGB into the panel raster ``(height, width, 3)``.

    The output has the views' dtype (uint8, uint16, float32 or float64).  ``out`` may supply a
    preallocated raster (honoured by the ``fast`` encoder, copied into otherwise).  ``compensator``
    (a :class:`lenticalib.render.compose.compensation.Compensator`, uint8 views): the views are
    pre-compensated first, by the encoder on its device where it can (:func:`compensates_on_device`),
    else on the host (:meth:`Compensator.apply`).
    """
    views = check_views(views, profile, check_aspect=not allow_stretch)
    func = get_encoder(method)
    if compensator is not None:
        if getattr(func, "compensates", False):
            result = func(views, profile, compensator=compensator)
            if out is not None:
                np.copyto(output_like(views, profile, out), result)
                return out
            return result
        views = compensator.apply(views)
    if method == "fast":
        return func(views, profile, out=output_like(views, profile, out))
    result = func(views, profile)
    if out is not None:
        np.copyto(output_like(views, profile, out), result)
        return out
    return result
