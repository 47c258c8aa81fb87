"""``render_avatar``: the avatar pipeline offline, to panel rasters (PNG, or a lossless video) and the views.

``output``: ``OUT.png`` (or ``.tif``, ``.npy``) for one frame, a folder for several
(``DIR/frame-00000.png`` ...) or ``OUT.mkv`` for a lossless video (FFV1 through OpenCV's bundled
FFmpeg: every pixel as rendered, so the raster survives), at ``fps`` steps of the controls'
time.  A lossy image or another video suffix (``.jpg``, ``.mp4`` ...) is refused: it would blur
the raster's subpixels (and is never taken for a folder name).  ``views_out`` also receives the
N views of every frame, 8-bit, in view order -- exactly what was encoded --
(``VDIR/frame-00000/view-00.png`` ...) and ``VDIR/cameras.json``.

Output paths are checked before the avatar is loaded (:mod:`lenticalib.core.files.outputs`); a folder is
written complete or not at all, and an existing folder is replaced only when it holds nothing
but what is written there (``RASTER_CONTENTS``, ``VIEWS_CONTENTS``).

Errors name the argument at fault by its parameter name (``source="frames"``, ``"fps"``,
``"output"``; ``views_out`` in hints); a command-line front end maps them to its flags.
"""

from __future__ import annotations

import contextlib
import dataclasses
import os
from pathlib import Path
from typing import Callable


from ...core.files.atomic import PendingFile
from ...core.errors import InputError
from ...core.files.imageio import IMAGE_SUFFIXES, WRITE_FORMATS, cv2_quiet, write_image
from ...core.files.outputs import Inputs, check_output_file, check_output_folder, staged_folder
from ...core.profile import PanelProfile
from .session import AvatarOptions, AvatarSession, open_avatar_session
from ..controls.sources import control_scheme

RASTER_CONTENTS = ("frame-[0-9][0-9][0-9][0-9][0-9]*.png",)
VIEWS_CONTENTS = ("cameras.json", "frame-[0-9][0-9][0-9][0-9][0-9]*",
                  "frame-[0-9][0-9][0-9][0-9][0-9]*/view-[0-9][0-9]*.png")
VIDEO_SUFFIXES = (".mkv", ".mp4", ".avi", ".mov", ".webm", ".m4v", ".mpg", ".mpeg", ".wmv", ".gif")


@dataclasses.dataclass
class RenderRun:
    """What :func:`render_avatar` wrote: ``output`` (and ``views_out``), ``frames``, ``kind``
    ('image', 'video' or 'folder'), the ``session`` (pipeline, avatar), ``times`` (a
    :class:`~.loop.StageTimes` of every frame)."""

    output: Path
    views_out: Path | None
    frames: int
    kind: str
    session: AvatarSession
    times: object


def avatar_inputs(avatar: str | os.PathLike, profile: PanelProfile | str | os.PathLike,
                  options: AvatarOptions | None) -> list:
    """The files a render of ``avatar`` for ``profile`` with ``options`` reads: the avatar, the
    profile's file, the controls file (or a ``student:`` source's student and video), the
    background image, the crosstalk file; what the outputs may not be (:mod:`lenticalib.core.files.outputs`)."""
    o = options or AvatarOptions()
    files = [avatar, None if isinstance(profile, PanelProfile) else profile,
             o.background if o.background and "," not in o.background else None,
             o.compensation.crosstalk_file if o.compensation is not None else None]
    scheme = control_scheme(o.controls)
    if scheme == "student":
        from ..student.live import parse_student_spec

        student, source = parse_student_spec(o.controls)
        files += [student, source.get("video")]
    elif scheme == "file":
        files.append(o.controls)
    return files


def check_render_outputs(output: str | os.PathLike, frames: int, views_out: str | os.PathLike | None, *,
                         inputs: Inputs) -> str:
    """Refuse, before any work, outputs that cannot or must not be written (none of them one of the
    ``inputs``, :func:`avatar_inputs`); return the kind of output: 'image' (one raster file), 'video'
    (.mkv) or 'folder'."""
    output = str(output)
    suffix = os.path.splitext(output)[1].lower()
    single, video = suffix in WRITE_FORMATS, suffix == ".mkv"
    if (suffix in IMAGE_SUFFIXES or suffix in VIDEO_SUFFIXES) and not (single or video):
        raise InputError(f"render does not write {suffix} files: a lossy format blurs the raster's subpixels",
                         source=output,
                         hint="name it .png (one frame) or .mkv (a lossless video), or give a folder for PNG frames")
    if single and frames != 1:
        raise InputError(f"{frames} frames cannot go into one {suffix[1:].upper()}", source="output",
                         hint="give a folder for a sequence, or a .mkv video")
    if single or video:
        check_output_file(output, "video" if video else "raster", "out.mkv" if video else "out.png", inputs=inputs)
    else:
        check_output_folder(output, "frames folder", RASTER_CONTENTS, inputs=inputs)
    if views_out is not None:
        check_output_folder(views_out, "views folder", VIEWS_CONTENTS, inputs=inputs)
        out, views = (os.path.realpath(p) for p in (output, views_out))
        if out == views or views.startswith(out + os.sep) or out.startswith(views + os.sep):
            raise InputError("is, or is inside, the `output` path", source=str(views_out),
                             hint="give the views a folder of their own, beside the output")
    return "image" if single else "video" if video else "folder"


def render_avatar(avatar: str | os.PathLike, profile: PanelProfile | str | os.PathLike, output: str | os.PathLike,
                  *, options: AvatarOptions | None = None, frames: int = 1, fps: float = 30.0,
                  views_out: str | os.PathLike | None = None, step: Callable[[], None] | None = None) -> RenderRun:
    """Render ``frames`` frames of ``avatar`` for ``profile`` into ``output`` (module docstring),
    the controls sampled every 1/``fps`` seconds; the views too into ``views_out``; ``step()``
    called after each frame is written (a progress display).  Returns :class:`RenderRun`; every
    user error comes before the avatar is loaded or the first frame."""
    from .avatar_pipeline import StageTimes

    if frames < 1:
        raise InputError(f"{frames} frames", source="frames", hint="give at least 1")
    if not 0 < fps <= 1000:
        raise InputError(f"{fps} frames per second", source="fps", hint="use 0 < fps <= 1000")
    inputs = avatar_inputs(avatar, profile, options)
    kind = check_render_outputs(output, frames, views_out, inputs=inputs)
    session = open_avatar_session(avatar, profile, options)
    times = StageTimes()
    targets = [("raster", output, "frames folder", RASTER_CONTENTS)] if kind == "folder" else []
    if views_out is not None:
        targets.append(("views", views_out, "views folder", VIEWS_CONTENTS))
    writer = _VideoFile(str(output), fps) if kind == "video" else None
    try:
        _render_frames(session, output, frames, fps, times, targets, writer, kind == "image", inputs, step)
    except BaseException:
        if writer is not None:
            writer.discard()
        raise
    finally:
        session.pipeline.close()
    session.close()
    return RenderRun(Path(output), None if views_out is None else Path(views_out), frames, kind, session, times)


def _render_frames(session, output, frames, fps, times, targets, writer, single, inputs, step) -> None:
    from ..compose.host_views import views_on_host

    pipeline = session.pipeline
    with contextlib.ExitStack() as stack:
        folders = {name: Path(stack.enter_context(staged_folder(path, what, contents, inputs=inputs)))
                   for name, path, what, contents in targets}
        for k in range(frames):
            raster, views, stages = pipeline.frame(session.controls_at(k / fps))
            times.add(**stages)  # nothing presented: the table's present row reads "-", as play --headless
            if single:
                write_image(output, raster)
            elif writer is not None:
                writer.write(raster)
            else:
                write_image(folders["raster"] / f"frame-{k:05d}.png", raster)
            if "views" in folders:
                views = views_on_host(views)
                frame_dir = folders["views"] / f"frame-{k:05d}"
                frame_dir.mkdir()
                for i, view in enumerate(views):
                    write_image(frame_dir / f"view-{i:02d}.png", view)
            if step is not None:
                step()
        if "views" in folders:
            pipeline.cameras.write_json(folders["views"] / "cameras.json")
        if writer is not None:
            writer.finish()


class _VideoFile:
    """A lossless FFV1 video written beside ``path`` and moved into place by :meth:`finish`
    (an interrupted render leaves no partial video, and an earlier one stays)."""

    def __init__(self, path: str, fps: float):
        self._cv2 = cv2_quiet()
        self.path = path
        self._pending = PendingFile(path, "video", suffix=".mkv")  # the replaced file's mode, umask's for a new one
        self.temp = str(self._pending.path)
        self.fps = fps
        self._writer = None

    def write(self, raster) -> None:
        if self._writer is None:
            fourcc = self._cv2.VideoWriter_fourcc(*"FFV1")
            self._writer = self._cv2.VideoWriter(self.temp, fourcc, self.fps, (raster.shape[1], raster.shape[0]))
            if not self._writer.isOpened():
                self.discard()
                raise InputError("OpenCV cannot write FFV1 video here", source=self.path,
                                 hint="write PNG frames to a folder instead")
        self._writer.write(raster[:, :, ::-1].copy())

    def finish(self) -> None:
        if self._writer is not None:
            self._writer.release()
            self._writer = None
        self._pending.commit()

    def discard(self) -> None:
        if self._writer is not None:
            self._writer.release()
            self._writer = None
        self._pending.discard()
