"""The ``gl-compute`` renderer: 3D Gaussian splatting in OpenGL compute shaders, built like gsplat.

    r = GLComputeRenderer(ctx, n_views, width, height)   # ctx: the caller's, current, OpenGL 4.3
    r.render(gaussians, viewmats, Ks, background=None)    # N views into r.views (a texture array)
    views = r.read()                                     # (N, height, width, 4) float32, as render_cpu
    r, which, reason = gl_renderer_for(ctx, n_views, width, height)  # this one, or the ``gl``
                                                         # renderer's triangles (see there)
    render_gl_compute(gaussians, viewmats, Ks, width, height)  # the registry's form, its own context

Per call, for all N views at once (or in batches of views that keep every storage buffer within
the driver's GL_MAX_SHADER_STORAGE_BLOCK_SIZE), five compute stages, no draw call:

projection
    the ``gl`` renderer's own shader (:data:`.gl_shaders.PROJECT`: the ``cpu`` renderer's maths
    in float32), writing per (view, Gaussian) the ``cpu`` renderer's record and a depth key.
depth sort
    the ``gl`` renderer's stable radix sort (:class:`.gl_sort.GLSorter`) per view: front to back,
    ties by index, culled last.
intersect
    per depth-sorted splat, the 16 x 16 tiles its alpha >= 1/255 ellipse reaches on each tile
    row (:mod:`.gl_compute_shaders`): counted per chunk, the counts scanned, then one (key, slot)
    pair written per (splat, tile) in depth order, key = local view x tiles + tile.
tile sort
    the same stable radix sort of those keys (two 8-bit passes while they fit 16 bits): since the
    pairs entered front to back, the order is gsplat's key view | tile | depth, ties by index;
    then each tile's [first, end) range.
composite
    per (tile, view) a 16 x 16 work group: the tile's splats staged in shared memory, 256 at a
    time, each pixel front to back with the ``cpu`` renderer's rule (it stops before the splat
    that would take T to <= 1e-4), the tile ending early when all its pixels have stopped; the
    result (RGB over ``background``, alpha) stored into the view's layer of :attr:`views`.

The total number of intersections is read back (4 bytes) between intersect and tile sort, to
size the sort, as gsplat does; the views are never read back unless :meth:`read` is called.

Precision: float32 throughout; ``precision="fp16"`` stages the conic, opacity and colour as
float16 (the mean stays float32: pixel coordinates).  Measured against ``cpu`` on the scenes of
tests/test_renderer_cpu (per view, RGB / alpha PSNR): float32 130-161 dB (max difference 3e-6:
the same stop rule as ``cpu``, where the triangles' blending gives 73-152 dB), float16 68-98 dB
(max difference 0.004, one 8-bit level).  float16 passes the 60 dB the tests hold every renderer
to, but with 8 dB to spare and for a saving (shared memory, bandwidth) only a GPU can show, so
float32 is the default and float16 is left to be chosen by a GPU measurement.

Frames and layout as the ``gl`` renderer (:mod:`.gl_renderer`): OpenCV cameras, layer i of
``views`` = view i, texel (x, y) = pixel column x, image row y (row 0 the top).
"""

from __future__ import annotations

import logging

import numpy as np

from ...core.errors import DisplayError, InputError
from ..avatar.gaussians import Gaussians
from . import gl_compute_shaders as cs
from . import gl_shaders as sh
from .common import TILE_SIZE
from .cpu_project import RECORD_FIELDS
from .gl_renderer import GLSplatRenderer
from .gl_resources import GLViewsRenderer, RendererCache, byte_size, gl_version
from .gl_upload import camera_table, pack_gaussians

__all__ = ["GLComputeRenderer", "compute_missing", "gl_renderer_for", "render_gl_compute"]

_log = logging.getLogger(__name__)
_HINT = "or use the cpu renderer"
_MAX_GROUPS = 65535  # work groups along one axis that OpenGL 4.3 guarantees


def compute_missing(ctx) -> str | None:
    """What the compute renderer needs and ``ctx``'s driver lacks (one phrase), or None: OpenGL 4.3
    compute shaders."""
    if ctx.version_code < 430:
        return f"OpenGL {gl_version(ctx)} has no compute shaders (4.3 needed)"
    return None


class GLComputeRenderer(GLViewsRenderer):
    """N views of Gaussians composited by compute shaders into a texture array of the caller's
    moderngl context (OpenGL 4.3; see the module docstring).

    ARGUMENTS
        ctx         a moderngl context the caller owns and has made current (never released here)
        n_views     N, the views rendered per call
        width, height   view size, pixels
        precision   "fp32" or "fp16" (the staged splats; see the module docstring)

    ATTRIBUTES
        views       moderngl TextureArray (width, height, N), RGBA32F, the last render
        kind        "compute"
        fallback_reason  None (the triangle path is :func:`gl_renderer_for`'s fallback)
        profile     False; set True to time the stages (ctx.finish() after each, which stalls)
        stage_ms    with ``profile``: {"project", "sort", "intersect", "tile_sort", "composite"}
                    of the last render, milliseconds ("project" includes packing and uploading)
        intersections  the (splat, tile) pairs of the last render, all views

    DisplayError (one line) without OpenGL 4.3, or when the textures exceed the driver's limits.
    Context state: :meth:`render` binds shader storage buffers 0-15 and image unit 0.
    """

    kind = "compute"
    fallback_reason = None

    def __init__(self, ctx, n_views: int, width: int, height: int, *, precision: str = "fp32"):
        super().__init__(ctx, n_views, width, height)
        if precision not in ("fp32", "fp16"):
            raise InputError(f"must be 'fp32' or 'fp16', got {precision!r}", source="precision")
        missing = compute_missing(ctx)
        if missing:
            raise DisplayError(f"the gl-compute renderer cannot run here: {missing}",
                               hint="use the gl renderer, which draws triangles")
        self.precision = precision
        self.tiles = (-(-self.width // TILE_SIZE), -(-self.height // TILE_SIZE))
        if self.tiles[0] > _MAX_GROUPS or self.tiles[1] > _MAX_GROUPS or self.n_views > _MAX_GROUPS:
            raise DisplayError(f"{self.n_views} views of {self.width}x{self.height} exceed OpenGL's work-group "
                               "counts", hint="render smaller views with `view_size`")
        self._check_views()
        self.intersections = 0
        with self._allocating("gl-compute", hint="use the gl renderer, which draws triangles"):
            self.views = self._keep(ctx.texture_array((self.width, self.height, self.n_views), 4, dtype="f4"))
            self.views.filter = (ctx.NEAREST, ctx.NEAREST)
            self._make_projection()  # PROJECT's draw-command counts (CMDS) are unused here
            self._count = self._keep(ctx.compute_shader(cs.INTERSECT_COUNT))
            self._scan = self._keep(ctx.compute_shader(cs.SCAN))
            self._emit = self._keep(ctx.compute_shader(cs.INTERSECT_EMIT))
            self._ranges = self._keep(ctx.compute_shader(cs.RANGES_OF_TILES))
            self._composite = self._keep(ctx.compute_shader(cs.composite_source(precision == "fp16")))
            self._composite["size"].value = (self.width, self.height)
            for prog in (self._count, self._emit):
                prog["tiles"].value = self.tiles

    # -- rendering -----------------------------------------------------------------------------

    def render(self, gaussians: Gaussians, viewmats, Ks, background=None) -> None:
        """Render the N views of ``gaussians`` into :attr:`views` (see :func:`.cpu.render_cpu` for
        the arguments; N must be this renderer's ``n_views``)."""
        g, viewmats, Ks, background, stage = self._begin(gaussians, viewmats, Ks, background,
                                                         ("project", "sort", "intersect", "tile_sort", "composite"))
        ctx = self.ctx
        self.intersections = 0
        count = g.count
        data = pack_gaussians(g) if count else np.zeros((1, 13), np.float32)
        batch = self._batch(count, data.shape[1])
        self._buffer("gauss", data.nbytes).write(data)
        self._cams.write(camera_table(viewmats, Ks, self.width, self.height))
        self._cmds.clear()  # PROJECT counts into it (the triangles' draw commands): kept from wrapping
        self._composite["background"].value = tuple(float(c) for c in (background if background is not None
                                                                          else (0.0, 0.0, 0.0)))
        self.views.bind_to_image(0, read=False, write=True)
        stage("project")
        first = 0
        while first < self.n_views:
            views = min(batch, self.n_views - first)
            if self._render_batch(g, data.shape[1], first, views, stage):
                first += views
            else:  # the batch's intersections exceed a storage block: fewer views at once
                batch = views // 2
        ctx.memory_barrier(ctx.TEXTURE_FETCH_BARRIER_BIT | ctx.SHADER_IMAGE_ACCESS_BARRIER_BIT
                           | ctx.TEXTURE_UPDATE_BARRIER_BIT)

    def _render_batch(self, g: Gaussians, stride: int, first: int, views: int, stage) -> bool:
        """Views [first, first + views) into :attr:`views`; False (nothing drawn) when their
        intersections would exceed the storage block size and ``views`` > 1."""
        ctx, count = self.ctx, g.count
        tiles = self.tiles[0] * self.tiles[1]
        ranges = self._buffer("ranges", views * tiles * 8)
        ranges.clear()
        ranges.bind_to_storage_buffer(cs.RANGES)
        total = 0
        if count:
            entries = views * count
            splats = self._buffer("splats", entries * RECORD_FIELDS * 4)
            keys = self._buffer("keys", entries * 4)
            vals = self._buffer("vals", entries * 4)
            self._run_projection(g, stride, first, views, (self._buffers["gauss"], splats, keys, vals))
            stage("project")
            self._sorter.sort(keys, vals, count, views)
            stage("sort")
            for binding, buf in ((sh.SPLATS, splats), (sh.KEYS, keys), (sh.VALS, vals)):
                buf.bind_to_storage_buffer(binding)
            chunks = -(-entries // cs.CHUNK)
            sums = self._buffer("sums", 4 * (chunks + 1))
            sums.bind_to_storage_buffer(cs.SUMS)
            for prog in (self._count, self._emit):
                prog["entries"].value = entries
                prog["chunks"].value = chunks
            self._emit["count"].value = count
            self._scan["chunks"].value = chunks
            self._count.run(-(-chunks // sh.GROUP))
            ctx.memory_barrier()
            self._scan.run(1)
            ctx.memory_barrier()
            total = int(np.frombuffer(sums.read(size=4, offset=4 * chunks), np.uint32)[0])
            limit = self._storage_limit()
            if limit and total * 4 > limit:
                if views > 1:
                    return False
                raise DisplayError(f"one view's {total} splat-tile pairs exceed the OpenGL driver's shader storage "
                                   f"block size ({byte_size(limit)})",
                                   hint="render smaller views or use the cpu renderer")
            tkeys = self._buffer("tkeys", 4 * total)
            tvals = self._buffer("tvals", 4 * total)
            tkeys.bind_to_storage_buffer(cs.TKEYS)
            tvals.bind_to_storage_buffer(cs.TVALS)
            if total:
                self._emit.run(-(-chunks // sh.GROUP))
                ctx.memory_barrier()
            stage("intersect")
            if total:
                self._sorter.sort(tkeys, tvals, total, 1, bits=16 if views * tiles <= 1 << 16 else 32)
                tkeys.bind_to_storage_buffer(cs.TKEYS)
                tvals.bind_to_storage_buffer(cs.TVALS)
                ranges.bind_to_storage_buffer(cs.RANGES)
                self._ranges["total"].value = total
                groups = -(-total // sh.GROUP)
                across = min(groups, _MAX_GROUPS)
                self._ranges.run(across, -(-groups // across))
                ctx.memory_barrier()
            stage("tile_sort")
        else:
            self._buffer("splats", 16).bind_to_storage_buffer(sh.SPLATS)
            self._buffer("tvals", 16).bind_to_storage_buffer(cs.TVALS)
        self.intersections += total
        self._composite["first_view"].value = first
        self._composite.run(self.tiles[0], self.tiles[1], views)
        ctx.memory_barrier()
        stage("composite")
        return True

# Drivers that rasterise on the CPU: there the triangles are faster (measured on llvmpipe, 2 cores,
# demo avatar 20k Gaussians, 8 views of 320x180: triangles draw 458-473 ms, tiles composite
# 1485-1612 ms: a tile evaluates all 256 of its pixels for every splat in it, 6.7 times the
# pixels the triangles cover, and llvmpipe runs masked-off lanes all the same)
CPU_RASTERIZERS = ("llvmpipe", "softpipe", "swrast")


def gl_renderer_for(ctx, n_views: int, width: int, height: int, prefer: str | None = None):
    """(renderer, which, reason) for ``ctx``: the compute renderer (which = "gl-compute") or the
    ``gl`` renderer's triangles (which = "gl triangles"), both drawing into ``renderer.views``
    with the same ``render`` / ``read`` / ``release``.

    ``prefer`` None: compute where ``ctx`` has OpenGL 4.3 compute shaders, unless the driver
    rasterises on the CPU (:data:`CPU_RASTERIZERS`, where the triangles are faster); "compute":
    compute wherever ``ctx`` has them; "triangles": the triangles.  ``reason`` is one line when
    compute was preferred and the driver lacks it (else None).
    """
    if prefer not in (None, "compute", "triangles"):
        raise InputError(f"must be 'compute', 'triangles' or None, got {prefer!r}", source="prefer")
    missing = compute_missing(ctx)
    on_cpu = any(name in str(ctx.info.get("GL_RENDERER", "")).lower() for name in CPU_RASTERIZERS)
    if missing is None and (prefer == "compute" or (prefer is None and not on_cpu)):
        return GLComputeRenderer(ctx, n_views, width, height), "gl-compute", None
    reason = f"the gl-compute renderer draws triangles (the gl renderer): {missing}" \
        if prefer == "compute" and missing else None
    return GLSplatRenderer(ctx, n_views, width, height), "gl triangles", reason


def _make(ctx, n_views: int, width: int, height: int):
    """A renderer for the registry's cache (:func:`gl_renderer_for`, compute preferred); the reason
    it draws triangles, where it does, logged as a warning."""
    renderer, _, reason = gl_renderer_for(ctx, n_views, width, height, prefer="compute")
    if reason:
        _log.warning(reason)
    return renderer


_RENDERERS = RendererCache(_make, _HINT)  # in the one offscreen context of this renderer in the process


def render_gl_compute(gaussians: Gaussians, viewmats, Ks, width: int, height: int, *, background=None) -> np.ndarray:
    """The registry's form, as :func:`.cpu.render_cpu` (same arguments and result): a
    :class:`GLComputeRenderer` per (N, width, height), kept in a small cache, in one headless
    context of the process.  Where that context lacks compute shaders the ``gl`` renderer's
    triangles run, and say so in a warning (once per renderer made)."""
    return _RENDERERS.render(gaussians, viewmats, Ks, width, height, background)


render_gl_compute.unavailable = _RENDERERS.unavailable  # why not here (no OpenGL 3.3 context at all), or None
