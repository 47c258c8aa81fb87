"""The avatar pipeline, frame by frame: drive -> render -> compose (encode) -> present, timed per stage.

One :class:`AvatarPipeline` holds what is fixed for a session -- the avatar, the panel profile,
the N virtual cameras (ordered for the profile's view direction), the renderer and the encoder
-- and :meth:`AvatarPipeline.frame` makes one panel raster from one control vector:

    drive    the avatar's driver turns the controls into posed Gaussians (static avatars: nothing);
             ``play`` adds the time the controls source took to give them (a student driver's
             prediction from the camera, :mod:`.student.live`)
    render   the renderer draws all N views, RGBA, composited over the background
    compose  views -> 8-bit -> the panel raster by the profile's routing (the encoder)

``present`` (putting the raster on the panel) is the caller's, timed in the same table.  Stage
times are wall-clock milliseconds; on a GPU each stage ends with a synchronisation so the
times add up (CUDA events would not change the sum).  :class:`StageTimes` keeps them and prints
the table the LentiAvatar paper reports (its Table 3).

Devices: the ``cpu`` renderer and the numpy encoders keep everything on the host; ``gsplat``
and the ``torch`` encoder keep views and raster on the GPU until the raster goes to the
presenter (one 25 MB download per frame at 4K; CUDA-OpenGL interop would remove it, see
docs/presenting.md).  The ``gl`` renderer keeps Gaussians, views and, with the ``gl`` encoder,
the raster in one OpenGL context (:mod:`.gl_pipeline`): :meth:`AvatarPipeline.use_context` puts
it in a presenter's context, and the raster is drawn straight into its framebuffer
(``frame(..., raster_to_host=False)`` then :meth:`AvatarPipeline.draw_raster`); its render and
compose times come from GL timer queries.
"""

from __future__ import annotations

import dataclasses
import statistics
import time

import numpy as np

from ...core.colour import srgb_decode, srgb_encode
from ...core.errors import InputError
from ...core.files.imageio import read_image
from ...core.profile import PanelProfile
from ...core.retarget import Retargeter
from ...core.view_defaults import view_size_hint
from ...core.view_direction import direction_warning
from ..cameras.view_cameras import ViewCameras, empty_views_warning, order_for_direction
from ..compose.host_views import desaturate_edges, prepare_views

STAGES = ("drive", "render", "compose", "present")


@dataclasses.dataclass
class StageTimes:
    """Per-stage milliseconds of every frame (``times[stage]`` lists), and each frame's total."""

    times: dict = dataclasses.field(default_factory=lambda: {s: [] for s in STAGES})
    totals: list = dataclasses.field(default_factory=list)

    def add(self, **stages: float) -> None:
        for name, ms in stages.items():
            self.times[name].append(ms)
        self.totals.append(sum(stages.values()))

    @property
    def frames(self) -> int:
        return len(self.totals)

    def table(self, title: str = "") -> str:
        """Median, mean and 95th percentile per stage ("-" for a stage that did not run), the total and
        the frame rate, as text."""
        lines = [title] if title else []
        lines.append(f"{'stage':<10}{'median ms':>11}{'mean ms':>10}{'p95 ms':>9}")
        for name in STAGES + ("total",):
            values = self.totals if name == "total" else self.times[name]
            if not values:
                if self.totals:  # a stage that did not run (play --headless presents nothing)
                    lines.append(f"{name:<10}{'-':>11}{'-':>10}{'-':>9}")
                continue
            p95 = float(np.percentile(values, 95))
            lines.append(f"{name:<10}{statistics.median(values):>11.2f}{statistics.fmean(values):>10.2f}{p95:>9.2f}")
        if self.totals:
            lines.append(f"{'fps':<10}{1e3 / statistics.median(self.totals):>11.2f}   ({self.frames} frame{'' if self.frames == 1 else 's'}, "
                         "from the median total)")
        return "\n".join(lines)


def parse_background(text: str | None, view_size: tuple[int, int] | None = None) -> np.ndarray | None:
    """``"R,G,B"`` (0..1 or 0..255) -> float32 (3,) in 0..1; an image file -> float32 (H_v, W_v, 3)
    in 0..1 (sRGB values as stored, resized to ``view_size`` (W, H) by area averaging); None ->
    None (black, i.e. premultiplied colour)."""
    if text is None:
        return None
    from pathlib import Path

    if "," not in text and Path(text).suffix:
        import cv2

        image = read_image(text)
        scale = 65535.0 if image.dtype == np.uint16 else (255.0 if image.dtype == np.uint8 else 1.0)
        image = np.clip(image.astype(np.float32) / np.float32(scale), 0.0, 1.0)
        if view_size is not None and (image.shape[1], image.shape[0]) != tuple(view_size):
            image = cv2.resize(image, tuple(int(v) for v in view_size), interpolation=cv2.INTER_AREA)
        return np.ascontiguousarray(image, dtype=np.float32)
    try:
        values = [float(v) for v in text.split(",")]
    except ValueError:
        values = []
    if len(values) != 3 or not all(np.isfinite(values)) or min(values) < 0 or max(values) > 255:
        raise InputError(f"{text!r} is not R,G,B or an image file", source="background",
                         hint="e.g. 0.1,0.1,0.12 or 26,26,30, or backdrop.png")
    arr = np.array(values, dtype=np.float32)
    return arr / 255.0 if arr.max() > 1.0 else arr


class AvatarPipeline:
    """drive -> render -> compose for one avatar on one panel; see the module docstring.

    ``cameras`` come ordered for ``view_direction = +1`` (as the camera models make them) and
    are reordered for the profile; a profile that does not say its direction renders as +1
    with ``warning`` set (the caller prints it), as it prints ``notes``: the views that show nothing
    of the avatar's neutral pose (:func:`~.cameras.empty_views_warning`, decided once, here) and the
    fallbacks taken.  A renderer or encoder that cannot run here
    (BackendUnavailableError) and a ``device`` torch cannot use (InputError) are refused here.
    """

    def __init__(self, avatar, profile: PanelProfile, cameras: ViewCameras, *, renderer: str = "cpu",
                 encoder: str = "fast", device: str = "cpu", background: np.ndarray | None = None,
                 edge_desaturation: float = 0.0, compensator=None):
        from ..encoders import get_encoder
        from ..encoders.common import ASPECT_TOLERANCE
        from ..renderers import get_renderer

        if cameras.n_views != profile.views:
            raise InputError(f"{cameras.n_views} cameras for a profile of {profile.views} views", source="cameras",
                             hint="render as many views as the profile has")
        self.avatar, self.profile = avatar, profile
        self.warning = direction_warning(profile)
        self.cameras = order_for_direction(cameras, profile.view_direction or 1)
        empty = empty_views_warning(self.cameras, avatar.pose(None))  # once, from the neutral pose's centres
        self.notes: list[str] = [empty] if empty else []  # lines for the caller: empty views, fallbacks taken
        self.render_fn = get_renderer(renderer, device=device)  # refused here if it cannot run on this machine
        self.renderer, self.encoder, self.device = renderer, encoder, device
        self.on_gpu = renderer == "gsplat"
        self.on_gl = renderer in ("gl", "gl-compute")  # render (and with the gl encoder, encode) in one OpenGL context
        self._gl = None  # its GLFrame, made by use_context or on the first frame
        self.edge_desaturation = float(edge_desaturation)
        self.compensator = compensator  # crosstalk pre-compensation (render.compensation), part of compose
        self._torch_encoder = None
        self._host_rasters, self._host_next = [], 0  # page-locked rasters for the GPU's (see _to_host)
        self._retargeter = None  # built on the first set_eye (a tracked viewer)
        view_aspect, panel_aspect = cameras.width / cameras.height, profile.width / profile.height
        if abs(view_aspect / panel_aspect - 1.0) > ASPECT_TOLERANCE:  # checked now, not after the first render
            raise InputError(f"views of {cameras.width}x{cameras.height} (aspect {view_aspect:.3f}) do not fit the "
                             f"{profile.width}x{profile.height} panel (aspect {panel_aspect:.3f})", source="view_size",
                             hint=view_size_hint(profile, (cameras.width, cameras.height)))
        if self.on_gpu and encoder != "torch":
            raise InputError("the gsplat renderer keeps the views on the GPU: use the torch encoder",
                             source="encoder", hint="`encoder` torch")
        self.encode_fn = get_encoder(encoder, device=device)  # (on the GPU the TorchEncoder below is used)
        if device != "cpu":  # the drive runs there too
            from ..gpu.torch_devices import device_unavailable

            reason = device_unavailable(device)
            if reason is not None:
                raise InputError(reason, source="device", hint="use `device` cpu")
        # the per-session constants, once, where the renderer wants them
        self._mats = (self.cameras.viewmats.astype(np.float32), self.cameras.K.astype(np.float32))
        self._background = background
        if self.on_gpu:
            import torch

            self._mats = tuple(torch.as_tensor(m, device=device) for m in self._mats)
            if background is not None:
                self._background = torch.as_tensor(background, device=device)

    @property
    def keeps_raster_on_gpu(self) -> bool:
        """True when the raster is made on a GPU and can reach a presenter without the host: drawn
        in OpenGL (:attr:`draws_on_gpu`) or a CUDA tensor for ``Presenter.show_device`` (gsplat);
        :meth:`frame` with ``raster_to_host=False`` then :meth:`present`."""
        return self.draws_on_gpu or self.on_gpu

    @property
    def draws_on_gpu(self) -> bool:
        """True when the raster is made in OpenGL (gl renderer and gl encoder): :meth:`frame` with
        ``raster_to_host=False`` and :meth:`draw_raster` put it on a presenter with no round trip."""
        return self.on_gl and self.encoder == "gl"

    def use_context(self, ctx) -> None:
        """Build the OpenGL objects of the gl renderer in ``ctx`` (a presenter's, current), so that
        the raster can be drawn into its framebuffer; without this call the first frame makes a
        headless context of its own.  Nothing for the other renderers."""
        if self.on_gl and self._gl is None:
            self._gl = self._make_gl(ctx)

    def _make_gl(self, ctx=None):
        from .gl_frame import GLFrame

        frame = GLFrame(self.profile, self.cameras, ctx=ctx, background=self._background,
                        edge_desaturation=self.edge_desaturation, compensator=self.compensator,
                        prefer="compute" if self.renderer == "gl-compute" else None)
        for note in frame.notes:
            self.notes.append(note)
        return frame

    def frame(self, controls: np.ndarray | None, raster_to_host: bool = True) -> tuple[np.ndarray | None, object, dict]:
        """(raster uint8 (height, width, 3) on the host, views, {"drive", "render", "compose"}
        milliseconds).  Views: uint8 (N, H_v, W_v, 3) numpy, a torch tensor (gsplat) or a
        :class:`~.gl_pipeline.FrameViews` (gl: read back when indexed; :func:`.host_views.views_on_host`).
        ``raster_to_host=False``: the raster stays on the GPU: with the gl renderer and encoder
        None is returned for it and :meth:`draw_raster` draws it (its time is added to compose);
        with gsplat it is the torch encoder's uint8 tensor on the CUDA device (:meth:`present`)."""
        t0 = time.perf_counter()
        gaussians = self.avatar.pose(controls, self.device, as_torch=self.on_gpu)
        self._sync()
        t1 = time.perf_counter()
        if self.on_gl:
            return self._gl_frame(gaussians, raster_to_host, 1e3 * (t1 - t0))
        viewmats, ks = self._mats
        bg = self._background
        image_bg = bg is not None and bg.ndim == 3
        rgba = self.render_fn(gaussians, viewmats, ks, self.cameras.width, self.cameras.height,
                              background=None if image_bg else bg)
        self._sync()
        t2 = time.perf_counter()
        if self.on_gpu:
            if image_bg:  # premultiplied colour over the image (the render's own tensor): rgb += (1 - alpha) * image
                rgba[..., :3] += (1.0 - rgba[..., 3:4]) * bg[None]
            rgb = desaturate_edges(rgba, self.edge_desaturation) if self.edge_desaturation > 0 else rgba[..., :3]
            import torch

            rgb = rgb.clamp(0, 1)
            if self.compensator is not None:  # in linear light, on the device
                rgb = srgb_encode(self.compensator.apply_torch(srgb_decode(rgb)))
            views = (rgb * 255.0 + 0.5).to(dtype=torch.uint8).contiguous()
            raster = self._gpu_encoder().encode(views)
            if raster_to_host:
                raster = self._to_host(raster)
            self._sync()  # the encoder's kernels are compose, not the presenter's copy
        else:
            views = prepare_views(rgba, bg, self.edge_desaturation, self.compensator, background_rendered=not image_bg)
            raster = self.encode_fn(views, self.profile)
        t3 = time.perf_counter()
        return raster, views, {"drive": 1e3 * (t1 - t0), "render": 1e3 * (t2 - t1), "compose": 1e3 * (t3 - t2)}

    def _gl_frame(self, gaussians, raster_to_host: bool, drive_ms: float):
        """:meth:`frame` for the gl renderer: stage times from GL timer queries (see gl_pipeline)."""
        if self._gl is None:
            self._gl = self._make_gl()
        stages = {"drive": drive_ms, **self._gl.run(gaussians)}
        views = self._gl.latest_views()
        if self.encoder != "gl":  # the views to the host, the raster by a host encoder
            start = time.perf_counter()
            raster = self.encode_fn(views.to_host(), self.profile)
            stages["compose"] += 1e3 * (time.perf_counter() - start)
        elif raster_to_host:
            raster, ms = self._gl.raster()
            stages["compose"] += ms
        else:
            raster = None
        return raster, views, stages

    def present(self, presenter, raster, stages: dict) -> None:
        """Put the raster of the last :meth:`frame` on ``presenter``, timed into ``stages``
        ("present"): a host array through ``show``, a CUDA tensor through ``show_device`` (copied
        on the GPU), None (gl renderer and encoder, ``raster_to_host=False``) by drawing it
        (:meth:`present_drawn`)."""
        if raster is None:
            self.present_drawn(presenter, stages)
            return
        start = time.perf_counter()
        if isinstance(raster, np.ndarray):
            presenter.show(raster)
        else:
            presenter.show_device(raster)
        stages["present"] = 1e3 * (time.perf_counter() - start)

    def present_drawn(self, presenter, stages: dict) -> None:
        """Put the last frame's raster (made with ``raster_to_host=False``) on ``presenter`` by
        drawing it into its framebuffer (:meth:`lenticalib.render.present.base.Presenter.show_drawn`),
        timed into ``stages``: the draw (GPU time) is added to ``compose``, the rest of the call is
        ``present``."""
        start = time.perf_counter()
        draws = []
        presenter.show_drawn(lambda framebuffer: draws.append(self.draw_raster(framebuffer)))
        drawn = sum(draws)
        stages["compose"] += drawn
        stages["present"] = max(1e3 * (time.perf_counter() - start) - drawn, 0.0)

    def draw_raster(self, framebuffer) -> float:
        """Draw the last frame's raster into ``framebuffer`` of the context given to
        :meth:`use_context` (a presenter's); returns the draw's GPU milliseconds (timer query), a
        part of compose."""
        return self._gl.draw(framebuffer)

    def close(self) -> None:
        """Free the OpenGL objects of the gl renderer (nothing for the others)."""
        if self._gl is not None:
            self._gl.release()
            self._gl = None

    def set_eye(self, eye) -> bool:
        """Route the next frames for a tracked viewer's eye ``(x, y, D)`` mm (panel-centred: x right,
        y down, D in front of the panel surface): the session profile retargeted
        (:class:`lenticalib.core.retarget.Retargeter`; needs its physical block).  Returns True when the
        routing changed by more than the retargeter's tolerance (0.01 view), when the encoder's
        per-profile tables are rebuilt on the next frame; False when the current routing stands.
        """
        if self._retargeter is None:
            self._retargeter = Retargeter(self.profile)
        new = self._retargeter.profile_for(eye)
        if new is self.profile:
            return False
        self.profile = new
        self._torch_encoder = None
        if self._gl is not None:
            self._gl.set_profile(new)
        return True

    def _gpu_encoder(self):
        if self._torch_encoder is None:
            from ..encoders.torch_encoder import TorchEncoder

            self._torch_encoder = TorchEncoder(self.profile, (self.cameras.height, self.cameras.width),
                                               device=self.device)
        return self._torch_encoder

    def _to_host(self, raster):
        """uint8 numpy (height, width, 3) of the torch raster made on the GPU, copied through
        page-locked host memory (an H100 took 2.7 ms to copy a 4K raster to pageable memory).  Two
        such buffers are used in turn: the array returned is overwritten two frames later (every
        caller is done with it after one; copy it to keep it longer)."""
        import torch

        if raster.device.type != "cuda":
            return raster.numpy()
        if not self._host_rasters or self._host_rasters[0].shape != raster.shape:
            self._host_rasters = [torch.empty(raster.shape, dtype=raster.dtype, pin_memory=True) for _ in range(2)]
        host = self._host_rasters[self._host_next]
        self._host_next = 1 - self._host_next
        host.copy_(raster, non_blocking=True)
        torch.cuda.current_stream(raster.device).synchronize()
        return host.numpy()

    def _sync(self) -> None:
        if self.on_gpu:
            import torch

            torch.cuda.synchronize()
