"""Presenters with no window: an offscreen OpenGL framebuffer, and no graphics at all.

:class:`OffscreenPresenter` (``--display offscreen[:BACKEND]``) draws into a framebuffer object
of an EGL or standalone context, through the same pixel-exact path as the window
(:class:`~.base.Presenter`): the benchmark on a headless GPU machine, and the
virtual panel.  :class:`MemoryPresenter` (``--display none``) keeps each raster as sent: the
virtual panel on a machine without OpenGL.  :func:`~.displays.open_presenter`
picks one by display spec; both are in :data:`~.displays.PRESENTERS`.
"""

from __future__ import annotations

import time

import numpy as np

from ...core.errors import DisplayError
from ..gpu.gl_context import offscreen_context, unbind_egl
from ...core.sizes import check_raster
from .base import RASTER_HINT, FrameTiming, Presenter


class OffscreenPresenter(Presenter):
    """A framebuffer object in a context with no window (EGL on a headless GPU, or GLX/WGL
    standalone): for benchmarks and the virtual panel.  ``size``: (width, height).  ``keep``:
    every frame presented is read back into :attr:`presented` (tests: what reached the panel)."""

    kind = "offscreen"

    def __init__(self, size: tuple[int, int], backend: str | None = None, vsync: bool = False, keep: bool = False):
        super().__init__(vsync)
        self.size = (int(size[0]), int(size[1]))
        self.backend = backend
        self._fbo = None
        self.presented: list[np.ndarray] | None = [] if keep else None  # with keep: (H, W, 3) uint8 per frame

    def show(self, raster: np.ndarray, source: str | None = None) -> FrameTiming:
        timing = super().show(raster, source)
        self._keep()
        return timing

    def show_drawn(self, draw) -> FrameTiming:
        timing = super().show_drawn(draw)
        self._keep()
        return timing

    def _keep(self) -> None:
        if self.presented is not None:
            self.presented.append(self.read_back())

    def open(self) -> None:
        self.ctx = offscreen_context(self.backend, hint="or use `display` none")
        colour = self.ctx.renderbuffer(self.size, 4, dtype="f1")
        self._fbo = self.ctx.framebuffer(color_attachments=[colour])
        self._setup_gl()

    def _target(self):
        return self._fbo

    def close(self) -> None:
        if self._fbo is not None:
            for attachment in self._fbo.color_attachments:
                attachment.release()
            self._fbo.release()
            self._fbo = None
        super().close()
        unbind_egl()  # an EGL context left current would keep a later window (GLX) from becoming current

    def read_back(self) -> np.ndarray:
        data = self._fbo.read(components=3, alignment=1)
        return np.frombuffer(data, dtype=np.uint8).reshape(self.size[1], self.size[0], 3)[::-1].copy()


class MemoryPresenter(Presenter):
    """No graphics at all: the raster is kept as sent.  For the virtual panel on a machine with
    no OpenGL; ``read_back`` returns the raster itself (nothing could alter it)."""

    kind = "none"

    def __init__(self, size: tuple[int, int]):
        super().__init__(vsync=False)
        self.size = (int(size[0]), int(size[1]))

    def open(self) -> None:
        pass

    def close(self) -> None:
        pass

    def show(self, raster: np.ndarray, source: str | None = None) -> FrameTiming:
        check_raster(raster, self.size[0], self.size[1], source, "the display", RASTER_HINT, max_bits=8)
        start = time.perf_counter()
        self._shown = np.array(raster, copy=True)
        timing = FrameTiming(1e3 * (time.perf_counter() - start), 0.0)
        self.timings.append(timing)
        return timing

    def show_drawn(self, draw) -> FrameTiming:
        raise DisplayError("the `none` display has no OpenGL framebuffer to draw into",
                           hint="use the offscreen display or a window with a GPU encoder")

    def read_back(self) -> np.ndarray:
        if self._shown is None:
            raise DisplayError("nothing has been shown yet")
        return self._shown.copy()


def offscreen_presenter(display: str, size: tuple[int, int] | None = None, **_) -> OffscreenPresenter:
    """The ``offscreen`` display of ``size``: "offscreen", or "offscreen:BACKEND" naming the context's backend."""
    if size is None:
        raise DisplayError("a display of kind 'offscreen' needs a raster size", source="display")
    return OffscreenPresenter(size, backend=display.split(":", 1)[1] if ":" in display else None)


def memory_presenter(display: str, size: tuple[int, int] | None = None, **_) -> MemoryPresenter:
    """The ``none`` display of ``size``: no graphics, the last raster kept in memory."""
    if size is None:
        raise DisplayError("a display of kind 'none' needs a raster size", source="display")
    return MemoryPresenter(size)
