"""OpenGL encoder: the panel raster drawn by a fragment shader, the views and tables on the GPU.

    enc = GLEncoder(profile, (H_v, W_v))     # own offscreen context (EGL where there is no X server)
    enc = GLEncoder(profile, (H_v, W_v), ctx=presenter.ctx)   # or a context already open
    enc.upload_views(views)                  # (N, H_v, W_v, 3) uint8 -> the texture array enc.views
    enc.draw(framebuffer)                    # the raster into any framebuffer of that context
    raster = enc.encode(views)               # upload, draw offscreen, read back (H, W, 3) uint8

What lives on the GPU, uploaded once per profile and view size (OpenGL 3.3 core, textures):

* ``view_map``: RGB8UI ``(W, H)``, the view each output channel shows, from the canonical
  :func:`lenticalib.core.routing.view_map` (ties, subpixel layouts and reversed views included),
  ``DARK`` where no view lights it;
* ``column_taps``: RGB32F ``(W, 3)``, per output pixel and channel the left and right source column
  and the right column's weight (:func:`lenticalib.render.compose.sampling.column_sampling` at the
  channel's slot); ``row_taps``: RGB32F ``(H, 1)``, the same for rows (image flips included);
* ``views``: an RGB8 texture array of N layers ``(W_v, H_v)``, rewritten each frame
  (:meth:`GLEncoder.upload_views`), or rendered into by a GL renderer in the same context.

The fragment shader (one invocation per panel pixel, ``texelFetch`` only: no sampler filtering)
reads the pixel's three views, the four bilinear taps of each channel from its view's layer, and
blends them in float32 as the reference does in float64 (``top = a (1 - fx) + b fx``, likewise the
bottom, then ``top (1 - fy) + bottom fy``, rounded half up to a level), so routing equals the
reference's and values are within one level (tested).  It writes into any framebuffer of the
context: an offscreen one here, the presenter's window in the live loop.
"""

from __future__ import annotations

import collections
import contextlib
import threading

import numpy as np

from ...core.errors import DisplayError, ImageError
from ...core.profile import PanelProfile
from ...core.routing import view_map
from ..gpu.gl_context import VIEWPORT_TRIANGLE, headless_context, headless_unavailable, offscreen_context
from ..compose.sampling import column_sampling, row_sampling
from .common import output_like

_HINT = "or use another encoder (fast)"
DARK = 255  # view-map value of a channel no view lights (profiles have at most 254 views)

_FRAGMENT = """
#version 330 core
uniform usampler2D view_map;     // (W, H): the view of each output channel, 255 where dark
uniform sampler2D column_taps;   // (W, 3): channel c's (left column, right column, right weight)
uniform sampler2D row_taps;      // (H, 1): (top row, bottom row, bottom weight)
uniform sampler2DArray views;    // (W_v, H_v, N): the views, row 0 the top of the image
uniform int height;
out vec4 colour;
void main() {
    // gl_FragCoord is at the pixel centre, origin bottom-left; raster row 0 is the top row
    ivec2 p = ivec2(gl_FragCoord.xy);
    int y = height - 1 - p.y;
    uvec3 shown = texelFetch(view_map, ivec2(p.x, y), 0).rgb;
    vec3 r = texelFetch(row_taps, ivec2(y, 0), 0).rgb;
    vec3 result = vec3(0.0);
    for (int c = 0; c < 3; ++c) {
        if (shown[c] == 255u) continue;
        vec3 t = texelFetch(column_taps, ivec2(p.x, c), 0).rgb;
        int layer = int(shown[c]);
        float a = texelFetch(views, ivec3(int(t.x), int(r.x), layer), 0)[c];
        float b = texelFetch(views, ivec3(int(t.y), int(r.x), layer), 0)[c];
        float d = texelFetch(views, ivec3(int(t.x), int(r.y), layer), 0)[c];
        float e = texelFetch(views, ivec3(int(t.y), int(r.y), layer), 0)[c];
        float top = a * (1.0 - t.z) + b * t.z;
        float bottom = d * (1.0 - t.z) + e * t.z;
        result[c] = floor((top * (1.0 - r.z) + bottom * r.z) * 255.0 + 0.5) / 255.0;
    }
    colour = vec4(result, 1.0);
}
"""


def _panel_view_map(profile: PanelProfile) -> np.ndarray:
    """uint8 ``(H, W, 3)``: the view of every output channel (``DARK`` where none)."""
    xs = (3 * np.arange(profile.width)[:, None] + np.asarray(profile.rho)[None, :]).reshape(-1)
    out = np.empty((profile.height, profile.width, 3), dtype=np.uint8)
    for start in range(0, profile.height, 128):  # bounded int16 temporaries
        chosen = view_map(profile, slice(start, start + 128))[:, xs]
        out[start:start + 128] = np.where(chosen < 0, DARK, chosen).reshape(-1, profile.width, 3)
    return out


def _taps(sampling, index: np.ndarray) -> np.ndarray:
    """float32 ``(..., 3)``: (lo, hi, weight of hi) of ``sampling`` at ``index``."""
    return np.stack([sampling.lo[index], sampling.hi[index], sampling.weight[index]], axis=-1).astype(np.float32)


class GLEncoder:
    """The encoder's textures and shader in one moderngl context (see the module docstring).

    ``profile``; ``view_size`` ``(H_v, W_v)``; ``ctx`` a moderngl context to live in (None: an
    offscreen one of its own: :func:`headless_context`, or ``backend`` as
    :func:`lenticalib.render.gpu.gl_context.offscreen_context`).
    DisplayError (one line) when there is no OpenGL 3.3 or the panel or the view stack exceeds
    the driver's texture limits."""

    def __init__(self, profile: PanelProfile, view_size: tuple[int, int], ctx=None, backend: str | None = None):
        self.profile = profile
        self.view_size = (int(view_size[0]), int(view_size[1]))
        hv, wv = self.view_size
        self._own_ctx = ctx is None
        if ctx is None:
            ctx = headless_context(hint=_HINT) if backend is None else offscreen_context(backend, hint=_HINT)
        self.ctx = ctx
        try:
            self._enter()
            self._check_limits()
            ctx = self.ctx
            self._view_map = ctx.texture((profile.width, profile.height), 3, _panel_view_map(profile).tobytes(),
                                         dtype="u1", alignment=1)
            xs = 3 * np.arange(profile.width)[None, :] + np.asarray(profile.rho)[:, None]  # (3, W) slot of (c, x)
            self._column_taps = ctx.texture((profile.width, 3), 3, _taps(column_sampling(profile, wv), xs).tobytes(),
                                            dtype="f4")
            self._row_taps = ctx.texture((profile.height, 1), 3,
                                         _taps(row_sampling(profile, hv), np.arange(profile.height)).tobytes(), dtype="f4")
            self.views = None  # the RGB8 texture array of upload_views, made on the first upload
            self._stage = None  # the GPU views stage of encode(..., compensator), made on first use
            for texture in (self._view_map, self._column_taps, self._row_taps):
                texture.filter = (ctx.NEAREST, ctx.NEAREST)
            self._program = ctx.program(vertex_shader=VIEWPORT_TRIANGLE, fragment_shader=_FRAGMENT)
            for unit, name in enumerate(("view_map", "column_taps", "row_taps", "views")):
                self._program[name].value = unit
            self._program["height"].value = profile.height
            self._quad = ctx.vertex_array(self._program, [])
            self._fbo = None
        except Exception:
            self._leave()
            self.release()
            raise
        self._leave()

    def _current(self):
        """The encoder's own context made current for a block (other contexts stay as they are:
        several encoders live side by side); a context given by the caller is the caller's."""
        return self.ctx if self._own_ctx else contextlib.nullcontext()

    def _enter(self) -> None:
        self._stack = contextlib.ExitStack()
        self._stack.enter_context(self._current())

    def _leave(self) -> None:
        stack = getattr(self, "_stack", None)
        if stack is not None:
            self._stack = None
            stack.close()

    def _check_limits(self) -> None:
        info = self.ctx.info
        largest = int(info.get("GL_MAX_TEXTURE_SIZE", 0) or 0)
        layers = int(info.get("GL_MAX_ARRAY_TEXTURE_LAYERS", 0) or 0)
        hv, wv = self.view_size
        p = self.profile
        if largest and max(p.width, p.height, wv, hv) > largest:
            raise DisplayError(f"the OpenGL driver takes textures up to {largest} pixels, the panel is "
                               f"{p.width}x{p.height} and the views {wv}x{hv}",
                               hint="use the fast encoder (CPU) for this panel")
        if layers and p.views > layers:
            raise DisplayError(f"the OpenGL driver takes texture arrays of up to {layers} layers, the profile has "
                               f"{p.views} views", hint="use the fast encoder (CPU)")

    def upload_views(self, views: np.ndarray) -> None:
        """Write ``views`` (N, H_v, W_v, 3) uint8 C-contiguous into the texture array :attr:`views`."""
        with self._current():
            if self.views is None:
                hv, wv = self.view_size
                self.views = self.ctx.texture_array((wv, hv, self.profile.views), 3, dtype="f1", alignment=1)
                self.views.filter = (self.ctx.NEAREST, self.ctx.NEAREST)
            self.views.write(np.ascontiguousarray(views))

    def draw(self, framebuffer=None, views=None) -> None:
        """Draw the raster into ``framebuffer`` (None: the offscreen one), whose size must be the
        panel's, from ``views``: a normalised 8-bit texture array of this context, N layers of
        (W_v, H_v), RGB or RGBA, texel row 0 the top of the image (a GPU views stage's,
        :attr:`lenticalib.render.compose.gl_views.GLViewStage.views`); None: the uploaded :attr:`views`."""
        views = self.views if views is None else views
        if views is None:
            raise DisplayError("no views to encode yet", hint="upload views first")
        with self._current():
            if framebuffer is None:
                if self._fbo is None:
                    self._fbo = self.ctx.simple_framebuffer((self.profile.width, self.profile.height), components=4)
                framebuffer = self._fbo
            framebuffer.use()
            self.ctx.viewport = (0, 0, self.profile.width, self.profile.height)
            for unit, texture in enumerate((self._view_map, self._column_taps, self._row_taps, views)):
                texture.use(unit)
            self._quad.render(mode=self.ctx.TRIANGLES, vertices=3)

    def read(self, out: np.ndarray | None = None) -> np.ndarray:
        """The offscreen raster (H, W, 3) uint8, row 0 at the top (into ``out`` when given)."""
        p = self.profile
        with self._current():
            data = np.frombuffer(self._fbo.read(components=3, alignment=1), dtype=np.uint8)
        raster = data.reshape(p.height, p.width, 3)[::-1]
        if out is None:
            return raster.copy()
        np.copyto(out, raster)
        return out

    def encode(self, views: np.ndarray, out: np.ndarray | None = None, compensator=None) -> np.ndarray:
        """Upload ``views``, draw offscreen and read the raster back.  With ``compensator`` (a
        :class:`lenticalib.render.compose.compensation.Compensator`) the views are pre-compensated on the GPU
        first (:class:`lenticalib.render.compose.gl_views.GLViewStage`; needs OpenGL 4.3: DisplayError
        otherwise), within one level of :meth:`Compensator.apply`."""
        if compensator is None:
            self.upload_views(views)
            self.draw()
            return self.read(out)
        from ..compose.gl_views import GLViewStage

        n, hv, wv, _ = views.shape
        with self._current():
            if self._stage is None or self._stage.compensator is not compensator:
                if self._stage is not None:
                    self._stage.release()
                    self._stage = None
                self._stage = GLViewStage(self.ctx, n, wv, hv, compensator=compensator)
            rgba = np.empty((n, hv, wv, 4), dtype=np.float32)  # codes / 255: the stage recovers them exactly
            np.multiply(views, np.float32(1.0 / 255.0), out=rgba[..., :3])
            rgba[..., 3] = 1.0
            source = self.ctx.texture_array((wv, hv, n), 4, rgba.tobytes(), dtype="f4")
            try:
                self._stage.run(source)
            finally:
                source.release()
        self.draw(views=self._stage.views)
        return self.read(out)

    def release(self) -> None:
        """Free the GPU objects (and the context when it is the encoder's own)."""
        if getattr(self, "ctx", None) is None:
            return
        with self._current():
            if getattr(self, "_stage", None) is not None:
                self._stage.release()
                self._stage = None
            for name in ("_quad", "_program", "_fbo", "views", "_row_taps", "_column_taps", "_view_map"):
                obj = getattr(self, name, None)
                if obj is not None:
                    obj.release()
                    setattr(self, name, None)
        if self._own_ctx:
            self.ctx.release()
        self.ctx = None


_CACHE: collections.OrderedDict = collections.OrderedDict()
_CACHE_LOCK = threading.Lock()
_CACHE_SIZE = 2
_SHARED: list = []  # the one offscreen context of the registry's encoders (contexts do not mix well)


def encode_gl(views: np.ndarray, profile: PanelProfile, out: np.ndarray | None = None, *,
              compensator=None) -> np.ndarray:
    """The registry's form: numpy views ``(N, H_v, W_v, 3)`` uint8 in, the raster out, through
    :class:`GLEncoder` objects kept per (profile, view size) in a small cache, all in one offscreen
    context of the process (made current for the call, the caller's current context restored).
    ``compensator``: pre-compensated on the GPU first (:meth:`GLEncoder.encode`)."""
    if views.dtype != np.uint8:
        raise ImageError(f"the gl encoder takes 8-bit views, these are {views.dtype}", source="views",
                         hint="use the fast encoder for 16-bit and float views")
    key = (profile, views.shape[1], views.shape[2])
    with _CACHE_LOCK:
        if not _SHARED:
            _SHARED.append(headless_context(hint=_HINT))
        with _SHARED[0]:
            encoder = _CACHE.pop(key, None)
            if encoder is None:
                encoder = GLEncoder(profile, views.shape[1:3], ctx=_SHARED[0])
            _CACHE[key] = encoder
            while len(_CACHE) > _CACHE_SIZE:
                _CACHE.popitem(last=False)[1].release()
            return encoder.encode(views, output_like(views, profile, out), compensator=compensator)


def _unavailable(device=None) -> str | None:
    """Why the gl encoder cannot run here (no OpenGL 3.3 context), or None (one probe per process)."""
    return headless_unavailable(_HINT)


encode_gl.unavailable = _unavailable
encode_gl.compensates = True  # pre-compensation on the GPU (lenticalib.render.encoders.encode)
