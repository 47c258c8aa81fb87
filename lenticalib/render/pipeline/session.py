"""The avatar pipeline set up from plain options: what ``lenticalib play`` and ``render`` run.

:func:`open_avatar_session` checks everything a user can get wrong before the first frame, in
this order: the renderer, encoder and camera model (a name that is unknown or a backend that
cannot run on this machine is refused before anything is loaded), the profile, the view size (given, or
the panel's default, :mod:`lenticalib.core.view_defaults`: its memory and its aspect against the panel's),
the pre-compensation, the background, the avatar file and its driver, the controls (files are read in
full), the cameras.

Errors name the argument at fault by its parameter name (``source="edge_desaturation"``,
``"controls"`` ...); a command-line front end maps them to its flags.
"""

from __future__ import annotations

import dataclasses
import os

from ...core.errors import InputError
from ...core.identity import forced_note
from ...core.profile import PanelProfile, load_profile
from ...core.view_defaults import default_camera_arc, default_view_size, view_size_hint
from .encode_file import CompensationOptions


@dataclasses.dataclass(frozen=True)
class AvatarOptions:
    """How to drive, render and encode an avatar for a panel.

    ``controls``: 'demo', a file (.npz, .csv, .jsonl), '-' (JSON lines on stdin) or
    udp://HOST:PORT; ``driver``: 'rig' or module:callable; ``renderer`` (default cpu),
    ``encoder`` (default torch with gsplat, gl with gl, fast otherwise), ``device`` (default cuda with
    gsplat, cpu otherwise); ``camera_model`` 'arc', 'shear' or a plug-in's, with ``radius`` (avatar units),
    ``fov_deg``, ``yaw_range_deg`` and ``target`` (the look-at point (X, Y, Z) in the avatar's frame and
    units, metres for the demo avatar; None: the centre of the avatar's robust box, lifted to eye level,
    :mod:`.camera_models`); ``view_size`` (W, H) pixels; ``background``: 'R,G,B' or an
    image file; ``compensation``; ``edge_desaturation`` 0..1.

    ``view_size`` and ``yaw_range_deg`` left None follow the panel
    (:mod:`lenticalib.core.view_defaults`): views as tall as a tile of the quilt Looking Glass
    renders for the unit's model (420x560 on a Portrait), else about 960x540 at the panel's
    aspect; the arc the calibration's ``viewCone`` (or the physical block's cone), else 50 degrees.
    """

    controls: str = "demo"
    driver: str | None = None
    renderer: str | None = None
    encoder: str | None = None
    device: str | None = None
    camera_model: str = "arc"
    radius: float | None = None
    fov_deg: float = 20.0
    yaw_range_deg: float | None = None
    view_size: tuple[int, int] | None = None
    background: str | None = None
    compensation: CompensationOptions | None = None
    edge_desaturation: float = 0.0
    target: tuple[float, float, float] | None = None


@dataclasses.dataclass
class AvatarSession:
    """An :class:`~.loop.AvatarPipeline` ready for its first frame, its controls source (None for a
    static avatar) and the loaded avatar.  :meth:`controls_at` gives the control vector at a time;
    :meth:`close` closes the controls."""

    pipeline: object
    controls: object | None
    avatar: object

    @property
    def warning(self) -> str | None:
        return self.pipeline.warning

    def controls_at(self, seconds: float):
        return self.controls.latest(seconds)[1] if self.controls is not None else None

    def close(self) -> None:
        if self.controls is not None:
            self.controls.close()


def open_avatar_session(avatar: str | os.PathLike, profile: PanelProfile | str | os.PathLike,
                        options: AvatarOptions | None = None) -> AvatarSession:
    """Load ``avatar`` (a 3DGS .ply or a rig .npz) for ``profile`` (a profile or its JSON file) as
    ``options`` say; every user error is an InputError (or BackendUnavailableError) before any frame."""
    from ..avatar.sources import load_avatar
    from ..cameras.models import CAMERA_MODELS, make_cameras
    from ..controls.sources import open_controls
    from ..encoders import get_encoder
    from .avatar_pipeline import AvatarPipeline, parse_background
    from ..renderers import get_renderer
    from ..renderers.common import check_view_memory

    o = options or AvatarOptions()
    renderer = o.renderer or "cpu"
    encoder = o.encoder or {"gsplat": "torch", "gl": "gl", "gl-compute": "gl"}.get(renderer, "fast")
    device = o.device or ("cuda" if renderer == "gsplat" else "cpu")
    get_renderer(renderer, device=device)  # one that cannot run here is refused before anything is loaded
    get_encoder(encoder, device=device)
    CAMERA_MODELS.load(o.camera_model, "camera_model")
    if not isinstance(profile, PanelProfile):
        profile = load_profile(profile, "`profile`")
    view_size = default_view_size(profile) if o.view_size is None else o.view_size
    yaw_range_deg = default_camera_arc(profile) if o.yaw_range_deg is None else o.yaw_range_deg
    size = view_size if isinstance(view_size, (tuple, list)) and len(view_size) == 2 else (0, 0)
    check_view_memory(profile.views, *size)  # before anything of that size is made
    check_view_aspect(profile, size)  # before the avatar is read
    if not 0.0 <= o.edge_desaturation <= 1.0:
        raise InputError(f"{o.edge_desaturation} is out of range", source="edge_desaturation", hint="use 0..1")
    compensator = (o.compensation or CompensationOptions()).compensator(profile)
    background = parse_background(o.background, view_size)
    loaded = load_avatar(avatar, o.driver)
    controls = None
    if loaded.kind == "animated":
        controls = open_controls(o.controls, loaded.layout)
    elif o.controls != "demo":
        raise InputError("a static avatar (.ply) takes no controls", source="controls",
                         hint="leave the controls out, or give an animated avatar (a rig .npz)")
    camera_options = {"fov_deg": o.fov_deg, "yaw_range_deg": yaw_range_deg, "view_size": view_size}
    if o.radius is not None:
        camera_options["radius"] = o.radius
    cameras = make_cameras(o.camera_model, loaded.pose(None), profile.views, target=o.target, **camera_options)
    pipeline = AvatarPipeline(loaded, profile, cameras, renderer=renderer, encoder=encoder, device=device,
                              background=background, edge_desaturation=o.edge_desaturation,
                              compensator=compensator)
    if compensator is not None and compensator.origin.get("forced"):
        pipeline.notes.append(forced_note(compensator.origin, compensator.origin["crosstalk_file"]))
    return AvatarSession(pipeline, controls, loaded)


def check_view_aspect(profile: PanelProfile, view_size) -> None:
    """One InputError naming ``view_size`` when views of that (W, H) are not at the panel's aspect
    (the encoders' 1 %); its hint names sizes that fit this panel (:func:`view_size_hint`)."""
    from ..encoders.common import ASPECT_TOLERANCE

    w, h = view_size
    if w < 1 or h < 1 or abs((w / h) / (profile.width / profile.height) - 1.0) <= ASPECT_TOLERANCE:
        return  # (a size that is no size is the cameras' to refuse)
    raise InputError(f"views of {w}x{h} (aspect {w / h:.3f}) do not fit the {profile.width}x{profile.height} "
                     f"panel (aspect {profile.width / profile.height:.3f})", source="view_size",
                     hint=view_size_hint(profile, (w, h)))
