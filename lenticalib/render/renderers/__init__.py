"""Renderers: Gaussians + N cameras -> N RGBA views, selected by name through a lazy registry.

    cpu      a tile-based 3DGS rasterizer in numba, gsplat's forward maths (the default)
    gsplat   gsplat's CUDA rasterizer, all views in one batched call (needs torch and a CUDA GPU)

Every renderer has the signature of :func:`render` without ``renderer`` and returns
(N, H, W, 4) float32 RGBA (numpy for ``cpu``, a torch tensor on the GPU for ``gsplat``): RGB
composited over ``background`` (black when None, i.e. premultiplied) and alpha.  Cameras are
OpenCV's: ``viewmats`` world-to-camera with x right, y down, z forward; ``Ks`` in pixels with
pixel centres at integer coordinates (the backends shift to gsplat's half-pixel frame themselves).

Modules are imported only when a renderer is asked for.  Third-party renderers register through
the ``lenticalib.renderers`` entry-point group with a value ``"module:function"``.
"""

from __future__ import annotations

import importlib
from importlib import metadata
from typing import Callable

from ...errors import BackendUnavailableError, InputError

DEFAULT_RENDERER = "cpu"

_BUILTIN = {
    "cpu": "lenticalib.render.renderers.cpu:render_cpu",
    "gsplat": "lenticalib.render.renderers.gsplat_backend:render_gsplat",
}


def _registry() -> dict[str, str]:
    entries = dict(_BUILTIN)
    try:
        for ep in metadata.entry_points(group="lenticalib.renderers"):
            entries.setdefault(ep.name, ep.value)
    except Exception:  # a broken third-party distribution must not break the built-ins
        pass
    return entries


def available_renderers() -> list[str]:
    """Names of every registered renderer."""
    return sorted(_registry())


def get_renderer(name: str) -> Callable:
    """The render function registered as ``name``.

    Raises InputError (naming ``--renderer``) for an unknown name, BackendUnavailableError when its
    module fails to import.
    """
    registry = _registry()
    if name not in registry:
        raise InputError(f"unknown renderer {name!r}", source="--renderer",
                         hint="choose one of " + ", ".join(sorted(registry)))
    module_name, _, attr = registry[name].partition(":")
    try:
        module = importlib.import_module(module_name)
    except ImportError as exc:
        raise BackendUnavailableError(f"renderer {name!r} is not available: {exc}", source="--renderer",
                                      hint="install its dependencies") from None
    return getattr(module, attr)


def render(gaussians, viewmats, Ks, width: int, height: int, *, renderer: str = DEFAULT_RENDERER,
           background=None):
    """Render N views with the renderer named ``renderer``; see the module docstring."""
    return get_renderer(renderer)(gaussians, viewmats, Ks, width, height, background=background)
