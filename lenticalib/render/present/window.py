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

Backends (``PRESENTERS``, :mod:`.displays`): ``window`` (a real monitor, or Xvfb in tests), ``offscreen`` (an
EGL or standalone context with no window: the benchmark on a headless GPU machine, and the
virtual panel) and ``none`` (no graphics: the virtual panel on a machine without OpenGL).
This module holds the ``window`` one; the base :class:`~.base.Presenter` is in :mod:`.base`,
``offscreen`` and ``none`` in :mod:`.offscreen`, the registry and :func:`~.displays.open_presenter`
in :mod:`.displays`.
"""

from __future__ import annotations

import warnings
from collections import deque

import numpy as np

from ...core.errors import DisplayError
from ..gpu.gl_context import load_llvm_users_first, versions_to_try
from ..gpu.monitors import Monitor, choose_monitor, glfw_module, init_glfw, list_monitors
from .base import Presenter


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


def window_presenter(display: str | None, size: tuple[int, int] | None = None, *,
                     monitors: list[Monitor] | None = None, vsync: bool = True) -> WindowPresenter:
    """The ``window`` display: a full-screen window on the monitor ``display`` names, chosen by
    :func:`~lenticalib.render.gpu.monitors.choose_monitor` (``monitors`` injected for tests, else
    the ones glfw lists; None: the one whose mode is ``size``)."""
    monitor = choose_monitor(monitors if monitors is not None else list_monitors(), display, size)
    return WindowPresenter(monitor, vsync=vsync)
