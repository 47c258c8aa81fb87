"""The ``gl`` renderer: 3D Gaussian splatting in OpenGL through moderngl, the ``cpu`` renderer's maths.

    r = GLSplatRenderer(ctx, n_views, width, height)   # ctx: the caller's, current
    r.render(gaussians, viewmats, Ks, background=None)  # N views into r.views (a texture array)
    views = r.read()                                   # (N, height, width, 4) float32, as render_cpu
    render_gl(gaussians, viewmats, Ks, width, height)  # the registry's form, its own context

Per call, with the GPU sort (OpenGL 4.3 compute shaders; :mod:`.gl_shaders` holds the sources,
:mod:`.gl_upload` what is computed on the host):

projection (compute, one invocation per (Gaussian, view))
    the ``cpu`` renderer's (gsplat 1.5's) in float32, like gsplat itself: camera-frame mean,
    culling (near 0.01 <= z <= far, opacity >= 1/255, det > 0, gsplat's opacity-aware box on
    screen), EWA covariance with the clamped J, + 0.3 px^2, conic, SH colour of degree 0-3 for the
    direction camera centre -> mean (+ 0.5, clamped at 0 below); writes the ``cpu`` renderer's
    per-Gaussian record (:mod:`.cpu_project`) and a depth key, and counts the visible Gaussians
    into each view's indirect draw command.
sort (compute, :mod:`.gl_sort`)
    per view, the keys (float bits of z: ascending = front to back) with their slots, a stable
    radix sort (ties in index order, as gsplat's sort); culled Gaussians sort last.
draw (one indirect multi-draw, a command per view whose count the projection wrote)
    the visible Gaussians of each view, front to back, into its layer of ``views`` (layered
    framebuffer; ``gl_Layer`` from the vertex shader, or from a pass-through geometry shader
    where the driver lacks GL_ARB_shader_viewport_layer_array), one triangle each: the equilateral
    triangle circumscribing the ellipse where alpha can reach 1/255 (mapped by the ellipse's
    affine frame; its corners reach past gsplat's box, their fragments fail the alpha test), or
    the whole view for a splat far larger than the view.  No instancing: llvmpipe runs every
    instance as a draw of its own.  The fragment shader computes sigma at the pixel centre,
    alpha = min(0.999, o exp(-sigma)), discards sigma < 0 or alpha < 1/255, and blending (src
    ONE_MINUS_DST_ALPHA, dst ONE, on (c alpha, alpha) into RGBA32F) composites front to back:
    C += T c alpha, A = 1 - T.
background
    one full-view triangle per layer blended the same way: RGB += (1 - A) background.

The three run for all N views at once, or in batches of views where the per-view buffers would
exceed the driver's GL_MAX_SHADER_STORAGE_BLOCK_SIZE (llvmpipe's 128 MiB holds 27 views of 100k
Gaussians).

With the CPU sort (``sort="cpu"``; what runs where OpenGL 4.3 is missing, e.g. macOS's 4.1), the
projection and the order are the ``cpu`` renderer's own kernels (:func:`.cpu_project.project_view`,
:func:`.cpu_project.front_to_back`, float64) on the host; the records are uploaded in drawing
order as one RGBA32F texture and drawn, a draw call per view, by the same triangles and fragment
shader (OpenGL 3.3).

Difference from ``cpu``: the cpu renderer stops a pixel *before* the Gaussian that would take its
transmittance T to <= 1e-4, and adds nothing after; blending cannot stop, so here that Gaussian
and all behind it are composited too, adding to each channel and to alpha at most the T left at
the stop (times the colours behind, which are >= 0 and usually <= 1).  That T is below
1e-4 / (1 - alpha) of the stopping Gaussian: below 1e-3 unless its alpha exceeds 0.9, below 0.1
at worst (alpha <= 0.999).  Measured on the test scenes: at most 0.008, in a few pixels where
opaque Gaussians stack (73-87 dB PSNR in the layered scene).  Otherwise float32 rounding, as
gsplat's own.

Speed on Mesa's llvmpipe (2 cores; tools/bench_gl_render.py): the draw dominates, and it costs in
proportion to the pixels the triangles cover (about 11 ns a pixel per core, blending included;
the geometry itself about 0.2 us a triangle).  The triangle covers 1.65 times its ellipse (a
parallelogram 1.27 times, but as two triangles it drew 20% slower), and blending cannot stop
pixels early as the cpu renderer does; so on llvmpipe the numba ``cpu`` renderer is the faster
one (32 views of 960x540 of the 100k-Gaussian demo avatar: cpu 1.07 s, gl 3.8 s, of which draw
3.5 s, projection 0.28 s, sort 0.17 s), and this renderer is for GPUs, where fragments are cheap
and the views stay on the GPU for the ``gl`` encoder.

Frames: ``viewmats`` world-to-camera, OpenCV camera (x right, y down, z forward); ``Ks`` in pixels
with pixel centres at integer coordinates (+ 0.5 to cx, cy as :mod:`.cpu` does).  Layer i of
``views`` holds view i with texel (x, y) = pixel column x, image row y (row 0 the top), not flipped.
"""

from __future__ import annotations

import logging

import numpy as np

from ...core.errors import DisplayError, InputError
from ..avatar.gaussians import Gaussians
from . import gl_shaders as sh
from .cpu_project import RECORD_FIELDS
from .gl_resources import VIEW_SIZE_HINT, GLViewsRenderer, RendererCache, gl_version
from .gl_upload import camera_table, host_records, pack_gaussians, record_table

__all__ = ["GLSplatRenderer", "render_gl"]

_log = logging.getLogger(__name__)

_HINT = "or use the cpu renderer"
_VERTEX_STORAGE_BLOCKS = 2  # the GPU-sort path's vertex shader reads SPLATS and VALS (gl_shaders)


def _framebuffer_limits(ctx) -> dict[str, int]:
    """The driver's limits on a layered framebuffer of the views, by GL name (the smaller side of
    GL_MAX_VIEWPORT_DIMS; GL_MAX_FRAMEBUFFER_WIDTH / _HEIGHT / _LAYERS from OpenGL 4.3); 0 where unknown."""
    info = ctx.info
    limits = {name: int(info.get(name, 0) or 0) for name in (
        "GL_MAX_FRAMEBUFFER_WIDTH", "GL_MAX_FRAMEBUFFER_HEIGHT", "GL_MAX_FRAMEBUFFER_LAYERS")}
    limits["GL_MAX_VIEWPORT_DIMS"] = int(min(info.get("GL_MAX_VIEWPORT_DIMS") or (0,)))
    return limits


def _check_framebuffer_limits(ctx, n_views: int, width: int, height: int) -> None:
    """One DisplayError naming the first of the driver's framebuffer limits (:func:`_framebuffer_limits`)
    that N views of ``width`` x ``height`` exceed, before anything is allocated."""
    limits = _framebuffer_limits(ctx)
    asked = {"GL_MAX_FRAMEBUFFER_WIDTH": width, "GL_MAX_FRAMEBUFFER_HEIGHT": height,
             "GL_MAX_FRAMEBUFFER_LAYERS": n_views, "GL_MAX_VIEWPORT_DIMS": max(width, height)}
    for name, value in asked.items():
        if limits[name] and value > limits[name]:
            raise DisplayError(f"the OpenGL driver's {name} is {limits[name]}, {n_views} views of {width}x{height} "
                               "were asked for", hint=VIEW_SIZE_HINT)


def _vertex_layer(ctx) -> bool:
    """Whether the vertex shaders may write gl_Layer (else a pass-through geometry shader does)."""
    return sh.LAYER_EXTENSION in ctx.extensions


def _gpu_sort_missing(ctx) -> str | None:
    """What the GPU-sort path needs and ``ctx``'s driver lacks (one phrase), or None: OpenGL 4.3
    compute shaders, and storage buffers in the vertex shader (4.3 allows a driver none)."""
    if ctx.version_code < 430:
        return f"OpenGL {gl_version(ctx)} has no compute shaders (4.3 needed)"
    blocks = int(ctx.info.get("GL_MAX_VERTEX_SHADER_STORAGE_BLOCKS", 0) or 0)
    if blocks < _VERTEX_STORAGE_BLOCKS:
        return f"the driver allows {blocks} storage buffers in a vertex shader ({_VERTEX_STORAGE_BLOCKS} needed)"
    return None


class GLSplatRenderer(GLViewsRenderer):
    """N views of Gaussians splatted into a texture array of the caller's moderngl context.

    ARGUMENTS
        ctx         a moderngl context the caller owns and has made current (never released here)
        n_views     N, the views rendered per call
        width, height   view size, pixels
        sort        "gpu" (compute shaders, OpenGL 4.3), "cpu" (projection and order on the host,
                    OpenGL 3.3), or None: "gpu" where the context has 4.3, else "cpu"

    ATTRIBUTES
        views           moderngl TextureArray (width, height, N), RGBA32F, the last render
                        (see the module docstring for its layout and meaning)
        sort_kind       "gpu" or "cpu", the sort used
        fallback_reason one line when the CPU sort is used because the driver lacks OpenGL 4.3,
                        else None
        profile         False; set True to time the stages of each render (ctx.finish() after
                        each, which stalls)
        stage_ms        with ``profile``: {"project", "sort", "draw"} of the last render,
                        milliseconds; "project" includes packing and uploading the Gaussians
                        (with the CPU sort: the host's projection and order; "sort" gathering
                        the records)

    DisplayError (one line: what is missing, and the fallback) when the driver's texture limits
    are too small for the views, or when ``sort="gpu"`` and there is no OpenGL 4.3.  Without
    GL_ARB_shader_viewport_layer_array, a pass-through geometry shader picks each layer.

    Context state: :meth:`render` binds its own framebuffer and shader storage buffers (bindings
    0-11) and leaves blending, depth test and face culling disabled.
    """

    def __init__(self, ctx, n_views: int, width: int, height: int, *, sort: str | None = None):
        super().__init__(ctx, n_views, width, height)
        if sort not in (None, "gpu", "cpu"):
            raise InputError(f"must be 'gpu', 'cpu' or None, got {sort!r}", source="sort")
        missing = _gpu_sort_missing(ctx)
        if sort == "gpu" and missing:
            raise DisplayError(f"the gpu sort cannot run here: {missing}", hint="use sort='cpu', which sorts on the host")
        self.sort_kind = sort or ("cpu" if missing else "gpu")
        self.fallback_reason = None
        if sort is None and missing:
            self.fallback_reason = f"the gl renderer projects and sorts on the CPU: {missing}"
        self._check_views()
        _check_framebuffer_limits(ctx, self.n_views, self.width, self.height)
        self._vao = None
        with self._allocating("gl", hint="use the cpu renderer"):
            self.views = self._keep(ctx.texture_array((self.width, self.height, self.n_views), 4, dtype="f4"))
            self.views.filter = (ctx.NEAREST, ctx.NEAREST)
            self._fbo = self._keep(ctx.framebuffer(color_attachments=[self.views]))
            vertex_layer = _vertex_layer(ctx)
            self._background = self._keep(ctx.program(
                vertex_shader=sh.vertex_shader(sh.BACKGROUND_VERTEX, vertex_layer),
                geometry_shader=None if vertex_layer else sh.geometry_shader(splat=False),
                fragment_shader=sh.BACKGROUND_FRAGMENT))
            self._background_vao = self._keep(ctx.vertex_array(self._background, []))
            vertex = sh.SPLAT_VERTEX_GPU if self.sort_kind == "gpu" else sh.SPLAT_VERTEX_HOST
            self._splat = self._keep(ctx.program(
                vertex_shader=sh.vertex_shader(vertex, vertex_layer),
                geometry_shader=None if vertex_layer else sh.geometry_shader(splat=True),
                fragment_shader=sh.SPLAT_FRAGMENT))
            self._splat["size"].value = (float(self.width), float(self.height))
            if self.sort_kind == "gpu":
                self._make_projection()

    # -- buffers -------------------------------------------------------------------------------

    def _buffer_grown(self) -> None:
        """The vertex array is made again after a buffer was reallocated."""
        if self._vao is not None:
            self._vao.release()
            self._vao = None

    # -- rendering -----------------------------------------------------------------------------

    def render(self, gaussians: Gaussians, viewmats, Ks, background=None) -> None:
        """Render the N views of ``gaussians`` into :attr:`views` (see :func:`.cpu.render_cpu` for
        the arguments; N must be this renderer's ``n_views``)."""
        g, viewmats, Ks, background, stage = self._begin(gaussians, viewmats, Ks, background,
                                                         ("project", "sort", "draw"))
        ctx = self.ctx
        self._fbo.use()
        self._fbo.clear(0.0, 0.0, 0.0, 0.0)
        ctx.disable(ctx.DEPTH_TEST | ctx.CULL_FACE)
        ctx.enable(ctx.BLEND)
        ctx.blend_equation = ctx.FUNC_ADD
        ctx.blend_func = ctx.ONE_MINUS_DST_ALPHA, ctx.ONE
        try:
            if g.count:
                (self._render_gpu if self.sort_kind == "gpu" else self._render_host)(g, viewmats, Ks, stage)
            if background is not None:
                self._fbo.use()
                self._background["background"].value = tuple(float(c) for c in background)
                self._background_vao.render(mode=ctx.TRIANGLES, vertices=3, instances=self.n_views)
            stage("draw")
        finally:
            ctx.disable(ctx.BLEND)
            ctx.blend_func = ctx.SRC_ALPHA, ctx.ONE_MINUS_SRC_ALPHA

    def _render_gpu(self, g: Gaussians, viewmats, Ks, stage) -> None:
        ctx, n, count = self.ctx, self.n_views, g.count
        data = pack_gaussians(g)
        batch = self._batch(count, data.shape[1])
        gauss = self._buffer("gauss", data.nbytes)
        splats = self._buffer("splats", batch * count * RECORD_FIELDS * 4)
        keys = self._buffer("keys", batch * count * 4)
        vals = self._buffer("vals", batch * count * 4)
        gauss.write(data)
        self._cams.write(camera_table(viewmats, Ks, self.width, self.height))
        cmds = np.zeros((n, 5), dtype=np.uint32)
        cmds[:, 1] = 1
        cmds[:, 2] = 3 * count * (np.arange(n) % batch)
        self._cmds.write(cmds)
        draw = self._splat
        draw["count"].value = count
        if self._vao is None:
            self._vao = ctx.vertex_array(draw, [])
        for first in range(0, n, batch):
            views = min(batch, n - first)
            if first:  # the last batch's draw must have read the buffers this batch rewrites
                ctx.memory_barrier()
            self._run_projection(g, data.shape[1], first, views, (gauss, splats, keys, vals))
            stage("project")
            self._sorter.sort(keys, vals, count, views)
            stage("sort")
            draw["first_view"].value = first
            self._fbo.use()
            self._vao.render_indirect(self._cmds, mode=ctx.TRIANGLES, count=views, first=first)
            stage("draw")

    def _render_host(self, g: Gaussians, viewmats, Ks, stage) -> None:
        ctx, n = self.ctx, self.n_views
        largest = self._texture_limits()[0] or 1 << 14
        per_row = min(sh.RECORDS_PER_ROW, largest // 3)
        drawn = host_records(g, viewmats, Ks, self.width, self.height)
        stage("project")
        offsets = np.cumsum([0] + [len(d) for d in drawn])
        if not offsets[-1]:
            return
        if -(-offsets[-1] // per_row) > largest:
            raise DisplayError(f"{offsets[-1]} splats exceed the OpenGL driver's texture size ({largest} pixels) for "
                               f"the CPU sort's record texture", hint="render fewer views or use the cpu renderer")
        table = record_table(drawn, per_row)
        stage("sort")
        texture = self._buffers.get("records")
        if texture is None or texture.size != (3 * per_row, table.shape[0]):
            if texture is not None:
                texture.release()
            texture = self._buffers["records"] = ctx.texture((3 * per_row, table.shape[0]), 4, dtype="f4")
            texture.filter = (ctx.NEAREST, ctx.NEAREST)
        texture.write(table)
        texture.use(0)
        if self._vao is None:
            self._vao = ctx.vertex_array(self._splat, [])
        self._splat["records"].value = 0
        self._splat["per_row"].value = per_row
        self._fbo.use()
        for view in range(n):
            if offsets[view + 1] > offsets[view]:
                self._splat["layer"].value = view
                self._vao.render(mode=ctx.TRIANGLES, vertices=3 * int(offsets[view + 1] - offsets[view]),
                                 first=3 * int(offsets[view]))

    def release(self) -> None:
        """Free this renderer's GL objects (not the context)."""
        if getattr(self, "_vao", None) is not None:
            self._vao.release()
        self._vao = None
        super().release()


def _make(ctx, n_views: int, width: int, height: int) -> GLSplatRenderer:
    """A renderer for the registry's cache; its ``fallback_reason`` logged as a warning."""
    renderer = GLSplatRenderer(ctx, n_views, width, height)
    if renderer.fallback_reason:
        _log.warning(renderer.fallback_reason)
    return renderer


_RENDERERS = RendererCache(_make, _HINT)  # in the one offscreen context of the registry's renderers


def render_gl(gaussians: Gaussians, viewmats, Ks, width: int, height: int, *, background=None) -> np.ndarray:
    """The registry's form, as :func:`.cpu.render_cpu` (same arguments and result): a
    :class:`GLSplatRenderer` per (N, width, height), kept in a small cache, in one headless context
    of the process (OpenGL 3.3 or newer; made current for the call).  Where that context lacks
    OpenGL 4.3 the CPU sort is used, and its ``fallback_reason`` logged as a warning."""
    return _RENDERERS.render(gaussians, viewmats, Ks, width, height, background)


render_gl.unavailable = _RENDERERS.unavailable  # why not here (no OpenGL 3.3 context), or None
