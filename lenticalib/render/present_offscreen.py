"""Presenters with no window: an offscreen OpenGL framebuffer, and no graphics at all.

:class:`OffscreenPresenter` (``--display offscreen[:BACKEND]``) draws into a framebuffer object
of an EGL or standalone context, through the same pixel-exact path as the window
(:class:`lenticalib.render.present.Presenter`): the benchmark on a headless GPU machine, and the
virtual panel.  :class:`MemoryPresenter` (``--display none``) keeps each raster as sent: the
virtual panel on a machine without OpenGL.  :func:`lenticalib.render.present.open_presenter`
picks one by display spec; both are in ``lenticalib.render.present.PRESENTERS``.
"""

from __future__ import annotations

import os
import time

import numpy as np

from ..core.errors import DisplayError
from .monitors import is_macos
from .present import FrameTiming, Presenter, check_raster


class OffscreenPresenter(Presenter):
    """A framebuffer object in a context with no window (EGL on a headless GPU, or GLX/WGL
    standalone): for benchmarks and the virtual panel.  ``size``: (width, height)."""

    kind = "offscreen"

    def __init__(self, size: tuple[int, int], backend: str | None = None, vsync: bool = False):
        super().__init__(vsync)
        self.size = (int(size[0]), int(size[1]))
        self.backend = backend
        self._fbo = None

    def open(self) -> None:
        import moderngl

        backend = self.backend
        if backend is None and os.name == "posix" and not is_macos() and not os.environ.get("DISPLAY"):
            backend = "egl"  # no X server: EGL (a GPU driver's, or Mesa's surfaceless llvmpipe)
        kwargs = {"standalone": True, "require": 330}
        if backend:
            kwargs["backend"] = backend
        try:
            self.ctx = moderngl.create_context(**kwargs)
        except Exception as exc:
            raise DisplayError(f"no offscreen OpenGL 3.3 context ({backend or 'default'} backend: "
                               f"{str(exc).strip().splitlines()[-1] if str(exc).strip() else exc!r})",
                               hint="install Mesa (libegl1, libgl1-mesa-dri) or a GPU driver; or use "
                                    "`display` none") from None
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
        check_raster(raster, self.size, 8, source)
        start = time.perf_counter()
        self._shown = np.array(raster, copy=True)
        timing = FrameTiming(1e3 * (time.perf_counter() - start), 0.0)
        self.timings.append(timing)
        return timing

    def read_back(self) -> np.ndarray:
        if self._shown is None:
            raise DisplayError("nothing has been shown yet")
        return self._shown.copy()
