"""Pixel-exact full-screen presentation of panel rasters: the render layer's last stage.

A panel raster routes every RGB subpixel to a view; any resampling, texture filtering, colour
management, sRGB conversion or dithering on the way to the panel destroys it.  The presenter
opens a borderless full-screen window on one monitor (glfw), uploads each raster through a
pixel-buffer object into a texture (moderngl, OpenGL 3.3 core) and draws it with
``texelFetch`` -- one texel per framebuffer pixel, no sampler, no filtering -- into a
framebuffer with sRGB conversion and dithering off.  Sizes are compared with the
*framebuffer*, not the window (desktop scaling makes them differ), and a raster of another
size is refused, never scaled.

Frames: rasters are (height, width, 3) arrays, row 0 at the top of the panel, RGB order;
uint8, or uint16 where the framebuffer has at least 10 bits per channel.

Backends (``PRESENTERS``): ``window`` (a real monitor, or Xvfb in tests), ``offscreen`` (an
EGL or standalone context with no window: the benchmark on a headless GPU machine, and the
virtual panel) and ``none`` (no graphics: the virtual panel on a machine without OpenGL).
This module holds the base :class:`Presenter`, the ``window`` one and :func:`open_presenter`;
``offscreen`` and ``none`` are in :mod:`lenticalib.render.present_offscreen`.
"""

from __future__ import annotations

import dataclasses
import time
import warnings
from collections import deque

import numpy as np

from ..core.errors import DisplayError, ImageError
from ..core.sizes import check_raster_size
from .gl_context import VIEWPORT_TRIANGLE, load_llvm_users_first, versions_to_try
from .monitors import Monitor, choose_monitor, glfw_module, init_glfw, list_monitors

GL_DITHER = 0x0BD0
MAX_TIMINGS = 100_000  # frame timings a presenter keeps (the latest; half an hour at 60 fps)
GL_FRAMEBUFFER_SRGB = 0x8DB9

_FRAGMENT = """
#version 330 core
uniform sampler2D raster;
uniform int height;
uniform bool packed_rows;  // the raster's bytes in an RGBA texture 3/4 as wide (see Presenter._texture)
out vec4 colour;
void main() {
    // gl_FragCoord is at the pixel centre, origin bottom-left; raster row 0 is the top row
    ivec2 p = ivec2(gl_FragCoord.xy);
    int y = height - 1 - p.y;
    if (packed_rows) {
        vec3 c;
        for (int k = 0; k < 3; ++k) {
            int i = 3 * p.x + k;  // the subpixel's place in the row's values
            c[k] = texelFetch(raster, ivec2(i >> 2, y), 0)[i & 3];
        }
        colour = vec4(c, 1.0);
    } else {
        colour = vec4(texelFetch(raster, ivec2(p.x, y), 0).rgb, 1.0);
    }
}
"""


@dataclasses.dataclass(frozen=True)
class FrameTiming:
    """Milliseconds spent on one frame: ``upload`` (host -> pixel buffer -> texture, finished on
    the GPU) and ``present`` (draw and buffer swap; with vsync this waits for the display)."""

    upload_ms: float
    present_ms: float


def check_raster(raster: np.ndarray, size: tuple[int, int], max_bits: int = 8, source: str | None = None) -> None:
    """ImageError (one line) unless ``raster`` is (height, width, 3) uint8 -- or uint16 when the
    framebuffer has ``max_bits`` >= 10 -- of exactly ``size`` (width, height)."""
    arr = np.asarray(raster)
    if arr.ndim != 3 or arr.shape[2] != 3:
        raise ImageError(f"is not an RGB image (shape {arr.shape})", source=source,
                         hint="show an RGB raster made by 'lenticalib encode' or 'lenticalib patterns'")
    if arr.dtype == np.uint16 and max_bits < 10:
        raise ImageError(f"is 16-bit but the display shows {max_bits} bits per channel", source=source,
                         hint="show an 8-bit raster, or set the display to 10-bit colour")
    if arr.dtype not in (np.uint8, np.uint16):
        raise ImageError(f"has sample type {arr.dtype}; the panel takes 8-bit (or 16-bit) integers", source=source)
    check_raster_size((arr.shape[1], arr.shape[0]), size, source, "the display",
                      hint="rasters are never scaled: encode for this panel's size, or show it on the monitor "
                           "of that size (`display`)")


class Presenter:
    """Shows rasters pixel-exact; use as a context manager.  Subclasses make the GL context.

    ``size``: (width, height) of the framebuffer in pixels; ``timings``: one
    :class:`FrameTiming` per shown frame (the latest :data:`MAX_TIMINGS`); ``bits``: bits per channel of the framebuffer.
    """

    kind = "abstract"

    def __init__(self, vsync: bool = True):
        self.vsync = vsync
        self.size: tuple[int, int] = (0, 0)
        self.bits = 8
        self.timings: deque[FrameTiming] = deque(maxlen=MAX_TIMINGS)  # the latest: a show may run for days
        self.ctx = None
        self._textures: dict = {}
        self._buffers: list = []
        self._next_buffer = 0
        self._program = None
        self._vao = None
        self._shown: np.ndarray | None = None
        self._redraw = None  # the draw function of the last show_drawn or show_device
        self._device_uploads = None  # cuda_gl.DeviceUploads once show_device ran; False: not possible here
        self.notes: list[str] = []  # one line per fallback taken, for the caller to print

    # -- lifecycle ---------------------------------------------------------------------------
    def __enter__(self) -> "Presenter":
        self.open()
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def open(self) -> None:
        raise NotImplementedError

    def close(self) -> None:
        if self._device_uploads:
            self._device_uploads.release()
        self._device_uploads = None
        for item in list(self._textures.values()) + self._buffers:
            item.release()
        self._textures.clear()
        self._buffers.clear()
        if self.ctx is not None:
            self.ctx.release()
            self.ctx = None

    def _setup_gl(self) -> None:
        """Program, state and double pixel buffers, once the context is current."""
        ctx = self.ctx
        ctx.disable_direct(GL_DITHER)
        ctx.disable_direct(GL_FRAMEBUFFER_SRGB)
        self._program = ctx.program(vertex_shader=VIEWPORT_TRIANGLE, fragment_shader=_FRAGMENT)
        self._program["raster"].value = 0
        self._program["height"].value = self.size[1]
        self._program["packed_rows"].value = self._packed
        self._vao = ctx.vertex_array(self._program, [])
        nbytes = self.size[0] * self.size[1] * 3 * 2  # room for 16-bit rasters
        self._buffers = [ctx.buffer(reserve=nbytes, dynamic=True) for _ in range(2)]

    def _texture(self, dtype: np.dtype):
        """The texture rasters of ``dtype`` are uploaded into.  Where the width is a multiple of 4 it
        is an RGBA texture 3/4 as wide holding the rows' values as they are (``packed_rows``: the shader
        picks each subpixel's value), since drivers convert 3-channel uploads on the CPU: a 4K
        raster took 10 ms as RGB and 2.6 ms as RGBA on Mesa (``tools/bench_present.py``)."""
        key = np.dtype(dtype).str
        if key not in self._textures:
            gl_type = "f1" if dtype == np.uint8 else "nu2"
            width, height = self.size
            if self._packed:
                tex = self.ctx.texture((width * 3 // 4, height), 4, dtype=gl_type)
            else:
                tex = self.ctx.texture(self.size, 3, dtype=gl_type)
            tex.filter = (self._nearest(), self._nearest())
            tex.repeat_x = tex.repeat_y = False
            self._textures[key] = tex
        return self._textures[key]

    @property
    def _packed(self) -> bool:
        return self.size[0] % 4 == 0

    @staticmethod
    def _nearest():
        import moderngl

        return moderngl.NEAREST

    # -- frames ------------------------------------------------------------------------------
    def show(self, raster: np.ndarray, source: str | None = None) -> FrameTiming:
        """Put ``raster`` (height, width, 3) on the panel; returns and records its timing."""
        check_raster(raster, self.size, self.bits, source)
        data = np.ascontiguousarray(raster)
        start = time.perf_counter()
        buffer = self._buffers[self._next_buffer]
        self._next_buffer = 1 - self._next_buffer
        buffer.orphan(data.nbytes)
        buffer.write(data)
        timing = self._present_buffer(buffer, data.dtype, start)
        self._shown = data
        return timing

    def show_device(self, raster, source: str | None = None) -> FrameTiming:
        """Put a raster that is a torch tensor on a CUDA GPU (uint8 (height, width, 3): the torch
        encoder's) on the panel, copied on the GPU into the pixel buffer (:mod:`.cuda_gl`) where
        the driver allows it, else through host memory (said once in ``notes``); returns and
        records its timing.  ``shown`` is None afterwards (``read_back`` gives what was drawn)."""
        if self._device_uploads is None and self.ctx is not None:
            from .cuda_gl import DeviceUploads

            try:
                self._device_uploads = DeviceUploads(self.ctx, self.size[0] * self.size[1] * 3)
            except DisplayError as exc:
                self._device_uploads = False
                self.notes.append(f"the raster goes to OpenGL through host memory ({exc})")
        import torch

        if not self._device_uploads or tuple(raster.shape) != (self.size[1], self.size[0], 3) \
                or raster.dtype != torch.uint8:  # show() checks it and says what is wrong
            return self.show(raster.cpu().numpy(), source)
        start = time.perf_counter()
        buffer = self._device_uploads.upload(raster.contiguous())
        timing = self._present_buffer(buffer, np.dtype(np.uint8), start)
        texture = self._texture(np.uint8)
        self._shown, self._redraw = None, lambda _framebuffer: self._draw(texture)  # the texture holds it
        return timing

    def _present_buffer(self, buffer, dtype: np.dtype, start: float) -> FrameTiming:
        """Upload the pixel buffer into the texture, draw and swap; the timing from ``start``."""
        texture = self._texture(dtype)
        texture.write(buffer, alignment=4 if self._packed else 1)
        self.ctx.finish()
        uploaded = time.perf_counter()
        self._draw(texture)
        self._swap()
        self.ctx.finish()
        done = time.perf_counter()
        timing = FrameTiming(1e3 * (uploaded - start), 1e3 * (done - uploaded))
        self.timings.append(timing)
        self._redraw = None
        return timing

    def show_drawn(self, draw) -> FrameTiming:
        """Put on the panel what ``draw(framebuffer)`` draws into the presenter's framebuffer in
        its context (a GPU encoder: :meth:`lenticalib.render.encoders.gl_encoder.GLEncoder.draw`),
        with no raster in host memory; returns and records its timing (upload 0: nothing sent).
        ``shown`` is None afterwards (``read_back`` gives what was drawn)."""
        start = time.perf_counter()
        draw(self._target())
        self._swap()
        self.ctx.finish()
        timing = FrameTiming(0.0, 1e3 * (time.perf_counter() - start))
        self.timings.append(timing)
        self._shown, self._redraw = None, draw
        return timing

    def _draw(self, texture) -> None:
        self._target().use()
        self.ctx.viewport = (0, 0, *self.size)
        texture.use(0)
        self._vao.render(mode=self._triangles(), vertices=3)

    @staticmethod
    def _triangles():
        import moderngl

        return moderngl.TRIANGLES

    def _target(self):
        return self.ctx.screen

    def _swap(self) -> None:
        pass

    def read_back(self) -> np.ndarray:
        """uint8 (height, width, 3): what the framebuffer shows now, row 0 at the top."""
        raise NotImplementedError

    def keys(self, timeout: float = 0.0) -> list[str]:
        """Key names pressed since the last call ("space", "right", "escape", ...), waiting up to
        ``timeout`` seconds for the first; a closed window reports "escape"."""
        if timeout > 0:
            time.sleep(timeout)
        return []

    @property
    def shown(self) -> np.ndarray | None:
        """The last raster shown (as sent)."""
        return self._shown


class WindowPresenter(Presenter):
    """A borderless full-screen window on ``monitor`` (glfw), vsync on by default; with
    ``windowed=(w, h)`` a normal window of that size instead (a preview, ``monitor`` None)."""

    kind = "window"

    def __init__(self, monitor: Monitor | None, vsync: bool = True, windowed: tuple[int, int] | None = None):
        super().__init__(vsync)
        self.monitor = monitor
        self.windowed = windowed  # (width, height): a normal window (a preview), not full screen
        self._window = None
        self._keys: deque[str] = deque()

    def open(self) -> None:
        import moderngl

        load_llvm_users_first()  # before the window's context (see gl_context)
        glfw = init_glfw()
        handle = self._monitor_handle(glfw) if self.windowed is None else glfw.get_primary_monitor()
        mode = glfw.get_video_mode(handle)
        glfw.default_window_hints()
        for hint, value in ((glfw.DECORATED, self.windowed is not None), (glfw.RESIZABLE, False), (glfw.AUTO_ICONIFY, False),
                            (glfw.FOCUS_ON_SHOW, True), (glfw.SRGB_CAPABLE, False), (glfw.SAMPLES, 0),
                            (glfw.DOUBLEBUFFER, True), (glfw.RED_BITS, mode.bits.red),
                            (glfw.GREEN_BITS, mode.bits.green), (glfw.BLUE_BITS, mode.bits.blue),
                            (glfw.REFRESH_RATE, mode.refresh_rate), (glfw.OPENGL_PROFILE, glfw.OPENGL_CORE_PROFILE),
                            (glfw.OPENGL_FORWARD_COMPAT, True), (glfw.SCALE_TO_MONITOR, False)):
            glfw.window_hint(hint, value)
        if hasattr(glfw, "COCOA_RETINA_FRAMEBUFFER"):
            glfw.window_hint(glfw.COCOA_RETINA_FRAMEBUFFER, False)
        window = None
        for version in versions_to_try(330):  # the newest the driver gives (compute shaders for the gl renderer)
            glfw.window_hint(glfw.CONTEXT_VERSION_MAJOR, version // 100)
            glfw.window_hint(glfw.CONTEXT_VERSION_MINOR, version // 10 % 10)
            with warnings.catch_warnings():  # a version the driver lacks: glfw warns, the next is tried
                warnings.simplefilter("ignore", getattr(glfw, "GLFWError", Warning))
                if self.windowed is not None:
                    window = glfw.create_window(int(self.windowed[0]), int(self.windowed[1]), "lenticalib preview",
                                                None, None)
                else:
                    window = glfw.create_window(mode.size.width, mode.size.height, "lenticalib", handle, None)
            if window:
                break
        if not window:
            where = "a preview window" if self.monitor is None else f"monitor {self.monitor.describe()}"
            raise DisplayError(f"could not open an OpenGL 3.3 window on {where}",
                               hint="update the graphics driver; under Xvfb, install Mesa (libgl1-mesa-dri)")
        self._window = window
        glfw.make_context_current(window)
        glfw.swap_interval(1 if self.vsync else 0)
        if self.windowed is None:
            glfw.set_input_mode(window, glfw.CURSOR, glfw.CURSOR_HIDDEN)
        glfw.set_key_callback(window, self._on_key)
        try:
            self.ctx = moderngl.create_context(require=330)
        except Exception as exc:  # moderngl raises plain Exceptions for context failures
            self.close()
            raise DisplayError(f"OpenGL 3.3 is not available on this display ({exc})",
                               hint="update the graphics driver") from None
        self.size = tuple(int(v) for v in glfw.get_framebuffer_size(window))
        self.bits = int(min(mode.bits.red, mode.bits.green, mode.bits.blue))
        self._setup_gl()

    def _monitor_handle(self, glfw):
        for index, handle in enumerate(glfw.get_monitors() or []):
            x, y = glfw.get_monitor_pos(handle)
            if index == self.monitor.index and (x, y) == (self.monitor.x, self.monitor.y):
                return handle
        raise DisplayError(f"monitor {self.monitor.describe()} is gone", source="display",
                           hint="list the monitors again (lenticalib show --list-displays)")

    def close(self) -> None:
        super().close()
        if self._window is not None:
            glfw = glfw_module()
            glfw.destroy_window(self._window)
            self._window = None
            glfw.terminate()

    def _swap(self) -> None:
        glfw_module().swap_buffers(self._window)

    def _on_key(self, window, key, scancode, action, mods) -> None:
        glfw = glfw_module()
        if action in (glfw.PRESS, glfw.REPEAT):
            name = _KEY_NAMES.get(key)
            if name is None:
                raw = glfw.get_key_name(key, scancode)
                name = raw.decode() if isinstance(raw, bytes) else (raw or f"key{key}")
            self._keys.append(name)

    def keys(self, timeout: float = 0.0) -> list[str]:
        glfw = glfw_module()
        if timeout > 0 and not self._keys:
            glfw.wait_events_timeout(timeout)
        glfw.poll_events()
        if glfw.window_should_close(self._window):
            self._keys.append("escape")
            glfw.set_window_should_close(self._window, False)
        out = list(self._keys)
        self._keys.clear()
        return out

    def read_back(self) -> np.ndarray:
        """What the GL pipeline makes of the last raster: it is drawn again into the back buffer
        (not swapped) and read; the front buffer is not readable on every driver.  A test that
        must see the screen itself grabs it from the window system (an X screenshot)."""
        if self._shown is not None:
            self._draw(self._texture(self._shown.dtype))
        elif self._redraw is not None:
            self._redraw(self._target())
        else:
            raise DisplayError("nothing has been shown yet")
        self.ctx.finish()
        data = self.ctx.screen.read(viewport=(0, 0, *self.size), components=3, alignment=1)
        return np.frombuffer(data, dtype=np.uint8).reshape(self.size[1], self.size[0], 3)[::-1].copy()


def _key_names() -> dict[int, str]:
    try:
        import glfw
    except ImportError:
        return {}
    return {glfw.KEY_SPACE: "space", glfw.KEY_RIGHT: "right", glfw.KEY_LEFT: "left", glfw.KEY_UP: "up",
            glfw.KEY_DOWN: "down", glfw.KEY_PAGE_UP: "page_up", glfw.KEY_PAGE_DOWN: "page_down",
            glfw.KEY_ESCAPE: "escape", glfw.KEY_ENTER: "enter", glfw.KEY_KP_ENTER: "enter",
            glfw.KEY_BACKSPACE: "backspace", glfw.KEY_Q: "q", glfw.KEY_HOME: "home", glfw.KEY_END: "end"}


_KEY_NAMES = _key_names()


def _presenters() -> dict[str, type[Presenter]]:
    from .present_offscreen import MemoryPresenter, OffscreenPresenter

    return {"window": WindowPresenter, "offscreen": OffscreenPresenter, "none": MemoryPresenter}


def __getattr__(name: str):
    # PRESENTERS names classes of present_offscreen, which imports this module: built on first use
    if name == "PRESENTERS":
        value = globals()["PRESENTERS"] = _presenters()
        return value
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def open_presenter(display: str | None = None, size: tuple[int, int] | None = None,
                   monitors: list[Monitor] | None = None, vsync: bool = True) -> Presenter:
    """A presenter (not yet opened) for ``display``: "offscreen" -> an OpenGL framebuffer of
    ``size`` with no window ("offscreen:egl" names the backend); "none" -> no graphics at all;
    anything else picks a monitor by :func:`choose_monitor` (``monitors`` injected for tests,
    else :func:`list_monitors`)."""
    kind = display.split(":")[0] if display is not None else None
    if kind in ("none", "offscreen"):
        from .present_offscreen import MemoryPresenter, OffscreenPresenter

        if size is None:
            raise DisplayError(f"a display of kind {kind!r} needs a raster size", source="display")
        if kind == "none":
            return MemoryPresenter(size)
        backend = display.split(":", 1)[1] if ":" in display else None
        return OffscreenPresenter(size, backend=backend)
    monitor = choose_monitor(monitors if monitors is not None else list_monitors(), display, size)
    return WindowPresenter(monitor, vsync=vsync)
