"""The avatar frame on the GPU: render, views stage and encode in one OpenGL context, no round trips.

:class:`GLFrame` holds, in one moderngl context (a presenter's window or offscreen context, or a
headless one of its own), the GL renderer (:func:`~.renderers.gl_compute.gl_renderer_for`: the
compute renderer, or the triangles of :class:`~.renderers.gl_renderer.GLSplatRenderer`; the
Gaussians uploaded once per frame, N float RGBA layers), the views stage
(:class:`~.gl_views.GLViewStage`: background, edge desaturation, 8-bit codes and crosstalk
pre-compensation into N 8-bit layers) and the GL encoder (:class:`~.encoders.gl_encoder.GLEncoder`:
the raster drawn from those layers into any framebuffer of the context).  Nothing goes through
host memory unless asked: :meth:`GLFrame.raster` reads the raster back (``render``, ``play
--headless``), :meth:`GLFrame.view` / :meth:`GLFrame.views` the views (``--views-out``, the
preview window); on a panel the encoder draws straight into the window
(:meth:`lenticalib.render.present.base.Presenter.show_drawn`).

Stage times come from GL timer queries (``GL_TIME_ELAPSED``: the GPU's time for the commands
between begin and end; :meth:`GLFrame._timed`): ``render`` (upload, projection, sort, splatting)
and ``compose`` (views stage and encoder draw); a read-back of the raster is added to ``compose``
as wall time.

Fallbacks, each said in one line (:attr:`GLFrame.notes`): a driver without OpenGL 4.3 (macOS
stops at 4.1) sorts on the CPU (the renderer's) and runs the views stage on the host (the
rendered layers read back, the host path of :class:`~.loop.AvatarPipeline`, the views uploaded).
"""

from __future__ import annotations

import time

import numpy as np

from ...core.profile import PanelProfile
from ..cameras.view_cameras import ViewCameras
from ..compose.host_views import prepare_views

_HINT = "or use the cpu renderer and the fast encoder"


class GLFrame:
    """Render -> views -> raster for ``profile`` with ``cameras`` (already ordered for the
    profile), in ``ctx`` (None: a headless context of its own, released by :meth:`release`).

    ``background``: None, (3,) or (H_v, W_v, 3) float in 0..1; ``edge_desaturation`` 0..1;
    ``compensator`` or None; ``prefer``: the renderer's path, None, "compute" or "triangles"
    (:func:`~.renderers.gl_compute.gl_renderer_for`; :attr:`renderer_kind` says which runs,
    "gl-compute" or "gl triangles").  DisplayError (one line, naming what is missing and the fallback)
    when there is no OpenGL 3.3 context or the driver's textures are too small.
    """

    def __init__(self, profile: PanelProfile, cameras: ViewCameras, *, ctx=None, background=None,
                 edge_desaturation: float = 0.0, compensator=None, prefer: str | None = None):
        from ..encoders.gl_encoder import GLEncoder
        from ..gpu.gl_context import headless_context
        from ..compose.gl_views import GLViewStage
        from ..renderers.gl_compute import gl_renderer_for

        self._own_ctx = ctx is None
        self.ctx = headless_context(hint=_HINT) if ctx is None else ctx
        self.profile, self.cameras = profile, cameras
        self.background = background
        self.edge_desaturation = float(edge_desaturation)
        self.compensator = compensator
        self.notes: list[str] = []
        self.renderer = self.stage = self.encoder = None
        self._mats = (np.asarray(cameras.viewmats, np.float64), np.asarray(cameras.K, np.float64))
        with self._current():
            try:
                n, w, h = profile.views, cameras.width, cameras.height
                self.renderer, self.renderer_kind, reason = gl_renderer_for(self.ctx, n, w, h, prefer)
                for note in (reason, self.renderer.fallback_reason):
                    if note:
                        self.notes.append(note)
                if self.ctx.version_code >= 430:
                    self.stage = GLViewStage(self.ctx, n, w, h, background=background,
                                             edge_desaturation=edge_desaturation, compensator=compensator)
                else:
                    self.notes.append("the views stage runs on the host: the driver has no OpenGL 4.3 compute shaders")
                self.encoder = GLEncoder(profile, (h, w), ctx=self.ctx)
                self._queries = {name: self.ctx.query(time=True) for name in ("render", "compose")}
            except BaseException:
                self._release_objects()
                raise
        self._host_views: np.ndarray | None = None

    def _current(self):
        import contextlib

        return self.ctx if self._own_ctx else contextlib.nullcontext()

    # -- a frame ------------------------------------------------------------------------------
    def run(self, gaussians) -> dict:
        """Render ``gaussians`` (posed, activated) into the views and prepare them for the encoder;
        returns {"render": ms, "compose": ms} (timer queries; compose without the encoder's draw,
        which :meth:`draw` adds to ``self.last_draw_ms``)."""
        viewmats, ks = self._mats
        with self._current():
            bg = self.background if self.stage is None and self._colour_background() else None
            render_ms = self._timed("render", lambda: self.renderer.render(gaussians, viewmats, ks, background=bg))
            start = time.perf_counter()
            self._host_views = None
            if self.stage is not None:
                compose_ms = self._timed("compose", lambda: self.stage.run(self.renderer.views))
            else:  # no compute shaders: the host path, then one upload
                self._host_views = prepare_views(self.renderer.read(), self.background, self.edge_desaturation,
                                                 self.compensator, background_rendered=self._colour_background())
                self.encoder.upload_views(self._host_views)
                compose_ms = 1e3 * (time.perf_counter() - start)
        return {"render": render_ms, "compose": compose_ms}

    def _colour_background(self) -> bool:
        return self.background is not None and np.ndim(self.background) == 1

    def _views_texture(self):
        return self.stage.views if self.stage is not None else None

    def draw(self, framebuffer=None) -> float:
        """Draw the raster of the last :meth:`run` into ``framebuffer`` (None: the encoder's offscreen
        one); returns the draw's GPU milliseconds (timer query)."""
        with self._current():
            return self._timed("compose", lambda: self.encoder.draw(framebuffer, views=self._views_texture()))

    def _timed(self, name: str, work) -> float:
        """Run ``work`` (GL commands) inside timer query ``name``; its GPU milliseconds.  The query
        ends after ``ctx.finish()``, which adds no GPU time but makes every driver record it (Mesa's
        llvmpipe reports no valid time for commands still queued).  Where the driver still gives no
        valid time (all ones: moderngl reads 32 bits, so also beyond 4.29 s), the wall time."""
        query = self._queries[name]
        start = time.perf_counter()
        with query:
            work()
            self.ctx.finish()
        wall_ms = 1e3 * (time.perf_counter() - start)
        elapsed = query.elapsed
        return wall_ms if elapsed in (0, 0xFFFFFFFF) else elapsed / 1e6

    def raster(self, out: np.ndarray | None = None) -> tuple[np.ndarray, float]:
        """(the raster (H, W, 3) uint8 on the host, milliseconds: draw (GPU) + read-back (wall))."""
        draw_ms = self.draw()
        start = time.perf_counter()
        with self._current():
            raster = self.encoder.read(out)
        return raster, draw_ms + 1e3 * (time.perf_counter() - start)

    def views(self) -> np.ndarray:
        """The views of the last frame as encoded: (N, H_v, W_v, 3) uint8 (read back)."""
        if self._host_views is not None:
            return self._host_views
        with self._current():
            return self.stage.read()

    def latest_views(self) -> "FrameViews":
        """The views of the last frame, read back only when asked (see :class:`FrameViews`)."""
        return FrameViews(self)

    def view(self, index: int) -> np.ndarray:
        """View ``index`` of the last frame as encoded: (H_v, W_v, 3) uint8 (one layer read back)."""
        if self._host_views is not None:
            return self._host_views[index]
        w, h = self.cameras.width, self.cameras.height
        with self._current():
            data = self.stage.views.read(alignment=1)  # moderngl reads whole arrays; a view is one layer of it
        return np.frombuffer(data, np.uint8).reshape(-1, h, w, 4)[index, ..., :3].copy()

    def set_profile(self, profile: PanelProfile) -> None:
        """Route by ``profile`` from the next draw on (a retargeted profile: same panel and views)."""
        from ..encoders.gl_encoder import GLEncoder

        if profile is self.profile:
            return
        with self._current():
            encoder = GLEncoder(profile, (self.cameras.height, self.cameras.width), ctx=self.ctx)
            if self._host_views is not None:
                encoder.upload_views(self._host_views)
            self.encoder.release()
            self.encoder = encoder
        self.profile = profile

    def _release_objects(self) -> None:
        for name in ("encoder", "stage", "renderer"):
            obj = getattr(self, name, None)
            if obj is not None:
                obj.release()
                setattr(self, name, None)
        self._queries = {}  # moderngl's queries have no release; they go with the context

    def release(self) -> None:
        """Free the GL objects (and the context when it is this frame's own)."""
        if self.ctx is None:
            return
        with self._current():
            self._release_objects()
        if self._own_ctx:
            self.ctx.release()
        self.ctx = None



class FrameViews:
    """The views of a :class:`GLFrame`'s last frame, read back on demand: ``views[i]`` one view
    (H_v, W_v, 3) uint8, :meth:`to_host` all of them (N, H_v, W_v, 3); ``len`` N."""

    def __init__(self, frame: GLFrame):
        self._frame = frame

    def __len__(self) -> int:
        return self._frame.profile.views

    def __getitem__(self, index: int) -> np.ndarray:
        return self._frame.view(index)

    def to_host(self) -> np.ndarray:
        return self._frame.views()
