"""The presenters' base: :class:`Presenter` (one OpenGL program drawing a raster texel for pixel),
:class:`FrameTiming`, :data:`RASTER_HINT` (rasters are checked by :func:`lenticalib.core.sizes.check_raster`,
``max_bits`` the framebuffer's); the backends are in :mod:`.present` (``window``, and
:func:`~.present.open_presenter`) and :mod:`.present_offscreen` (``offscreen``, ``none``).

Frames: rasters are (height, width, 3) arrays, row 0 at the top of the panel, RGB order; uint8, or
uint16 where the framebuffer has at least 10 bits per channel; times in milliseconds.
"""

from __future__ import annotations

import dataclasses
import time
from collections import deque

import numpy as np

from ...core.errors import DisplayError
from ...core.sizes import check_raster
from ..gpu.gl_context import VIEWPORT_TRIANGLE

GL_DITHER = 0x0BD0
MAX_TIMINGS = 100_000  # frame timings a presenter keeps (the latest; half an hour at 60 fps)
GL_FRAMEBUFFER_SRGB = 0x8DB9
RASTER_HINT = ("rasters are never scaled: encode for this panel's size, or show it on the monitor of that size "
               "(`display`)")  # what to do with a raster the display's size refuses

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
        check_raster(raster, self.size[0], self.size[1], source, "the display", RASTER_HINT, max_bits=self.bits)
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
            from ..gpu.cuda_gl import DeviceUploads

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
