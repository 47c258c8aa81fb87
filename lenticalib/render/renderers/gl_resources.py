"""What the two OpenGL renderers share: :mod:`.gl_renderer`'s triangles and :mod:`.gl_compute`'s tiles.

:class:`GLViewsRenderer` is their base class: N views of ``width`` x ``height`` pixels rendered
into a texture array of a caller's moderngl context.  It checks the view count and size (against
the driver's texture limits too), keeps the GL objects it makes and releases them, grows named
storage buffers, makes and runs the shared projection (:data:`.gl_shaders.PROJECT`, one
invocation per (Gaussian, view)) with the depth sort (:class:`.gl_sort.GLSorter`), sizes the
batches of views that keep the per-view buffers within the driver's
GL_MAX_SHADER_STORAGE_BLOCK_SIZE, times the stages (``profile``), and turns a shader the driver
refuses into one DisplayError line.

:class:`RendererCache` is the registry's form of either renderer: one renderer per
(N, width, height), a few kept, in one headless context of the process.
"""

from __future__ import annotations

import collections
import contextlib
import numbers
import threading
import time
from typing import Callable, Iterable

import numpy as np

from ...core.errors import DisplayError, InputError
from ..avatar.gaussians import Gaussians
from ..gpu.gl_context import headless_context, headless_unavailable
from . import gl_shaders as sh
from .common import check_finite_gaussians, check_render_inputs, check_view_memory
from .cpu_project import RECORD_FIELDS
from .gl_sort import GLSorter

__all__ = ["VIEW_SIZE_HINT", "GLViewsRenderer", "RendererCache", "byte_size", "driver_refusal", "gl_version"]

VIEW_SIZE_HINT = "render smaller views with `view_size`, for a panel with fewer views, or use the cpu renderer"


def gl_version(ctx) -> str:
    """``ctx``'s OpenGL version as "major.minor" (from ``ctx.version_code``, e.g. 410 -> "4.1")."""
    return f"{ctx.version_code // 100}.{ctx.version_code // 10 % 10}"


def byte_size(size: int) -> str:
    """``size`` bytes in words: "N MiB" from 1 MiB up (rounded down), else "N bytes"."""
    return f"{size >> 20} MiB" if size >= 1 << 20 else f"{size} bytes"


def driver_refusal(exc: Exception) -> str:
    """The line of a moderngl.Error (a shader or object the driver refused) that names the error:
    the first that says "error", else the last one, else the exception's repr."""
    lines = [line.strip() for line in str(exc).splitlines() if line.strip() and not line.startswith("=")]
    errors = [line for line in lines if "error" in line.lower()] or lines[-1:] or [repr(exc)]
    return errors[0]


class GLViewsRenderer:
    """Base of the OpenGL renderers: N views of Gaussians into :attr:`views`, a texture array of the
    caller's moderngl context (``ctx``, current; never released here).

    ARGUMENTS
        ctx             the caller's moderngl context
        n_views         N, the views rendered per call (a positive integer)
        width, height   view size, pixels (positive integers)

    InputError (naming the argument) for a count or size that is not a positive integer.  The
    subclass makes its GL objects inside :meth:`_allocating` (kept with :meth:`_keep`), after
    :meth:`_check_views`; :meth:`read` and :meth:`release` are shared.

    ATTRIBUTES
        ctx, n_views, width, height   as given (ints)
        profile     False; set True to time the stages of each render (ctx.finish() after each,
                    which stalls)
        stage_ms    with ``profile``: milliseconds per stage of the last render (the subclass names
                    the stages)
    """

    def __init__(self, ctx, n_views: int, width: int, height: int):
        for name, value in (("n_views", n_views), ("width", width), ("height", height)):
            if isinstance(value, bool) or not isinstance(value, numbers.Integral) or value <= 0:
                raise InputError(f"must be a positive integer, got {value!r}", source=name)
        self.ctx = ctx
        self.n_views, self.width, self.height = int(n_views), int(width), int(height)
        self.profile = False
        self.stage_ms: dict[str, float] = {}
        self._objects: list = []
        self._buffers: dict = {}
        self._sorter: GLSorter | None = None

    # -- the driver's limits -------------------------------------------------------------------

    def _texture_limits(self) -> tuple[int, int]:
        """(GL_MAX_TEXTURE_SIZE, GL_MAX_ARRAY_TEXTURE_LAYERS) of the driver, 0 where unknown."""
        info = self.ctx.info
        return (int(info.get("GL_MAX_TEXTURE_SIZE", 0) or 0), int(info.get("GL_MAX_ARRAY_TEXTURE_LAYERS", 0) or 0))

    def _storage_limit(self) -> int:
        """GL_MAX_SHADER_STORAGE_BLOCK_SIZE of the driver, bytes (0 where unknown)."""
        return int(self.ctx.info.get("GL_MAX_SHADER_STORAGE_BLOCK_SIZE", 0) or 0)

    def _check_views(self) -> None:
        """Before anything is allocated: the views' memory (:func:`.common.check_view_memory`), then
        one DisplayError (hint :data:`VIEW_SIZE_HINT`) when they exceed the driver's texture size or
        array layers."""
        check_view_memory(self.n_views, self.width, self.height)
        largest, layers = self._texture_limits()
        width, height, n_views = self.width, self.height, self.n_views
        if largest and max(width, height) > largest:
            raise DisplayError(f"the OpenGL driver takes textures up to {largest} pixels, the views are "
                               f"{width}x{height}", hint=VIEW_SIZE_HINT)
        if layers and n_views > layers:
            raise DisplayError(f"the OpenGL driver takes texture arrays of up to {layers} layers, "
                               f"{n_views} views were asked for", hint=VIEW_SIZE_HINT)

    # -- GL objects ----------------------------------------------------------------------------

    @contextlib.contextmanager
    def _allocating(self, renderer: str, hint: str):
        """Around making the GL objects: on any error everything made is released; a moderngl.Error
        (a shader or object the driver refused) becomes one DisplayError line "the OpenGL driver
        refused the ``renderer`` renderer's shaders: <its error line>" with ``hint``."""
        try:
            yield
        except Exception as exc:
            self.release()
            if type(exc).__name__ != "Error":  # moderngl.Error
                raise
            raise DisplayError(f"the OpenGL driver refused the {renderer} renderer's shaders: {driver_refusal(exc)}",
                               hint=hint) from None

    def _keep(self, obj):
        """``obj`` (a GL object), kept to be released by :meth:`release`."""
        self._objects.append(obj)
        return obj

    def _buffer(self, name: str, nbytes: int):
        """The buffer ``name`` of at least ``nbytes`` (reallocated, larger, when it is smaller; then
        :meth:`_buffer_grown` is called)."""
        buf = self._buffers.get(name)
        if buf is None or buf.size < nbytes:
            if buf is not None:
                buf.release()
            buf = self._buffers[name] = self.ctx.buffer(reserve=max(nbytes, 16))
            self._buffer_grown()
        return buf

    def _buffer_grown(self) -> None:
        """Called when :meth:`_buffer` has reallocated a buffer (nothing here)."""

    def _make_projection(self) -> None:
        """The projection program (sized to the views), the depth sorter, and the CAMS and CMDS
        buffers of :mod:`.gl_shaders`."""
        ctx = self.ctx
        self._project = self._keep(ctx.compute_shader(sh.PROJECT))
        self._project["size"].value = (float(self.width), float(self.height))
        self._sorter = GLSorter(ctx)
        self._cams = self._keep(ctx.buffer(reserve=self.n_views * 6 * 16))
        self._cmds = self._keep(ctx.buffer(reserve=self.n_views * 20))

    # -- rendering -----------------------------------------------------------------------------

    def _begin(self, gaussians: Gaussians, viewmats, Ks, background, stages: Iterable[str]):
        """The checks at the start of ``render`` (see :func:`.cpu.render_cpu` for the arguments; N
        must be ``n_views``): (g numpy, viewmats, Ks, background, stage), ``stage(name)`` adding
        the time since the last stage ended to ``stage_ms[name]`` when ``profile`` is set (its
        entries, ``stages``, reset to 0)."""
        viewmats, Ks, background = check_render_inputs(gaussians, viewmats, Ks, self.width, self.height, background)
        if viewmats.shape[0] != self.n_views:
            raise InputError(f"{viewmats.shape[0]} views, this renderer draws {self.n_views}", source="viewmats")
        g = gaussians.to_numpy()
        check_finite_gaussians(g)
        ctx = self.ctx
        self.stage_ms = {name: 0.0 for name in stages}
        clock = [time.perf_counter()]

        def stage(name: str) -> None:
            """With ``profile``: the time since the last stage ended, added to ``name``'s."""
            if self.profile:
                ctx.finish()
                now = time.perf_counter()
                self.stage_ms[name] += 1e3 * (now - clock[0])
                clock[0] = now

        return g, viewmats, Ks, background, stage

    def _batch(self, count: int, stride: int) -> int:
        """Views per batch: as many as keep the per-view records (``count`` Gaussians) within the
        driver's storage block size (all N without Gaussians or a known limit).  DisplayError when
        even the Gaussians (``stride`` floats each), or one view's records, do not fit."""
        limit = self._storage_limit()
        per_view = count * RECORD_FIELDS * 4
        if limit and count and (count * stride * 4 > limit or per_view > limit):
            raise DisplayError(f"{count} Gaussians exceed the OpenGL driver's shader storage block size "
                               f"({byte_size(limit)})", hint="render fewer Gaussians or use the cpu renderer")
        return self.n_views if not (limit and count) else max(1, min(self.n_views, limit // per_view))

    def _run_projection(self, g: Gaussians, stride: int, first: int, views: int, buffers) -> None:
        """Project ``g`` (``stride`` floats a Gaussian in GAUSS) for views [first, first + views):
        ``buffers`` (GAUSS, SPLATS, KEYS, VALS) bound with CAMS and CMDS, then a memory barrier."""
        gauss, splats, keys, vals = buffers
        for binding, buf in ((sh.GAUSS, gauss), (sh.CAMS, self._cams), (sh.SPLATS, splats), (sh.KEYS, keys),
                             (sh.VALS, vals), (sh.CMDS, self._cmds)):
            buf.bind_to_storage_buffer(binding)
        project = self._project
        project["count"].value = g.count
        project["stride"].value = stride
        project["degree"].value = g.sh_degree
        project["first_view"].value = first
        project.run(-(-g.count // sh.GROUP), views)
        self.ctx.memory_barrier()

    def read(self) -> np.ndarray:
        """(N, height, width, 4) float32: the views of the last ``render``, as render_cpu returns."""
        out = np.empty((self.n_views, self.height, self.width, 4), dtype=np.float32)
        self.views.read_into(out)
        return out

    def release(self) -> None:
        """Free this renderer's GL objects (not the context)."""
        for buf in self._buffers.values():
            buf.release()
        self._buffers = {}
        if self._sorter is not None:
            self._sorter.release()
            self._sorter = None
        for obj in reversed(self._objects):
            obj.release()
        self._objects = []


class RendererCache:
    """The registry's form of an OpenGL renderer: ``make(ctx, n_views, width, height)`` per
    (N, width, height), the last ``size`` kept, in one headless context of the process (OpenGL 3.3
    or newer, made on first use; ``hint`` completes the error where there is none)."""

    def __init__(self, make: Callable, hint: str, size: int = 2):
        self._make = make
        self._hint = hint
        self._size = size
        self._renderers: collections.OrderedDict = collections.OrderedDict()
        self._lock = threading.Lock()
        self.contexts: list = []  # the one offscreen context, once made

    def render(self, gaussians: Gaussians, viewmats, Ks, width: int, height: int, background=None) -> np.ndarray:
        """As :func:`.cpu.render_cpu` (same arguments and result), with the context made current."""
        viewmats, Ks, background = check_render_inputs(gaussians, viewmats, Ks, width, height, background)
        key = (viewmats.shape[0], int(width), int(height))
        with self._lock:
            if not self.contexts:
                self.contexts.append(headless_context(require=330, hint=self._hint))
            with self.contexts[0]:
                renderer = self._renderers.pop(key, None)
                if renderer is None:
                    renderer = self._make(self.contexts[0], *key)
                self._renderers[key] = renderer
                while len(self._renderers) > self._size:
                    self._renderers.popitem(last=False)[1].release()
                renderer.render(gaussians, viewmats, Ks, background)
                return renderer.read()

    def unavailable(self, device=None) -> str | None:
        """Why no renderer can run here (no OpenGL 3.3 context), or None (one probe per process)."""
        return headless_unavailable(self._hint)
