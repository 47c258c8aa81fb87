"""Renderers: Gaussians + N cameras -> N RGBA views, selected by name through a lazy registry.

    cpu      a tile-based 3DGS rasterizer in numba, gsplat's forward maths (the default)
    gsplat   gsplat's CUDA rasterizer, all views in one batched call (needs torch and a CUDA GPU)
    gl       OpenGL through moderngl: projection and sort in compute shaders (4.3; on the CPU where
             only 3.3 is there), a triangle per splat blended into a texture array (any GPU, Mesa)
    gl-compute  OpenGL compute shaders built like gsplat: projection, tile intersection, sort and
             per-tile compositing in shared memory (OpenGL 4.3; the ``gl`` triangles where it is missing)

Modules: ``cpu`` (the ``cpu`` renderer) with ``cpu_project`` (its projection, colour and
binning kernels), ``gsplat_backend`` (the ``gsplat`` renderer), ``gl_renderer`` (the ``gl``
renderer; :class:`~.gl_renderer.GLSplatRenderer` draws into a caller's context) with
``gl_shaders`` (its GLSL), ``gl_sort`` (its GPU sort) and ``gl_upload`` (what it computes on the
host), ``gl_compute`` (the ``gl-compute`` renderer; :func:`~.gl_compute.gl_renderer_for` picks
it, or the triangles, for a context) with ``gl_compute_shaders`` (its GLSL), ``gl_resources`` (what
the two OpenGL renderers share: their base class, the driver's limits, the registry's cache), and ``common`` (the
checks every renderer makes at its boundary and the conventions they share).  Part of the render layer: imports only core and render.

Every renderer has the signature of :func:`render` without ``renderer`` and returns
(N, H, W, 4) float32 RGBA (numpy for ``cpu`` and ``gl``, a torch tensor on the GPU for
``gsplat``): RGB composited over ``background`` (black when None, i.e. premultiplied) and alpha.
Cameras are OpenCV's: ``viewmats`` world-to-camera with x right, y down, z forward; ``Ks`` in
pixels with pixel centres at integer coordinates (the backends shift to gsplat's half-pixel frame themselves).

Modules are imported only when a renderer is asked for, and a renderer that cannot run on this
machine is refused when it is asked for, before anything else is loaded (its function's
``unavailable(device)``, see :mod:`lenticalib.core.plugins`).  Third-party renderers register through
the ``lenticalib.renderers`` entry-point group with a value ``"module:function"``.
"""

from __future__ import annotations

from typing import Callable

from ...core.plugins import Registry

DEFAULT_RENDERER = "cpu"

RENDERERS = Registry("renderer", {
    "cpu": "lenticalib.render.renderers.cpu:render_cpu",
    "gsplat": "lenticalib.render.renderers.gsplat_backend:render_gsplat",
    "gl": "lenticalib.render.renderers.gl_renderer:render_gl",
    "gl-compute": "lenticalib.render.renderers.gl_compute:render_gl_compute",
}, "lenticalib.renderers")


def available_renderers() -> list[str]:
    """Names of every registered renderer."""
    return RENDERERS.names()


def get_renderer(name: str, device: str | None = None) -> Callable:
    """The render function registered as ``name``, able to run here (on torch ``device``, if given).

    Raises InputError (naming ``renderer``) for an unknown name, BackendUnavailableError when its
    module fails to import or it cannot run here (``gsplat`` without a CUDA GPU): one line naming
    the renderers that can.
    """
    return RENDERERS.load(name, "renderer", device=device)


def render(gaussians, viewmats, Ks, width: int, height: int, *, renderer: str = DEFAULT_RENDERER,
           background=None):
    """Render N views with the renderer named ``renderer``; see the module docstring."""
    return get_renderer(renderer)(gaussians, viewmats, Ks, width, height, background=background)
