"""``lenticalib render``: the avatar pipeline offline, to PNG panel rasters or a lossless video (and the views).

``-o OUT.png`` (or ``.tif``, ``.npy``) for one frame, ``-o DIR`` for ``--frames N``
(``DIR/frame-00000.png`` ...) or ``-o OUT.mkv`` for a lossless video (FFV1 through OpenCV's
bundled FFmpeg: every pixel as rendered, so the raster survives), at ``--fps`` steps of the
controls' time.  A lossy image or another video suffix (``.jpg``, ``.mp4`` ...) is refused: it
would blur the raster's subpixels (and is never taken for a folder name).  ``--views-out VDIR``
also writes the N views of every frame, 8-bit, in view order -- exactly what was encoded --
(``VDIR/frame-00000/view-00.png`` ...) and ``VDIR/cameras.json``.

Output paths are checked before the avatar is loaded (:mod:`lenticalib.core.outputs`); a folder is
written complete or not at all, and an existing folder is replaced only when it holds nothing
but what render writes there (``RASTER_CONTENTS``, ``VIEWS_CONTENTS``).
"""

from __future__ import annotations

import argparse

RASTER_CONTENTS = ("frame-[0-9][0-9][0-9][0-9][0-9]*.png",)
VIEWS_CONTENTS = ("cameras.json", "frame-[0-9][0-9][0-9][0-9][0-9]*",
                  "frame-[0-9][0-9][0-9][0-9][0-9]*/view-[0-9][0-9]*.png")
VIDEO_SUFFIXES = (".mkv", ".mp4", ".avi", ".mov", ".webm", ".m4v", ".mpg", ".mpeg", ".wmv", ".gif")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    from ._avatar import add_avatar_arguments

    add_avatar_arguments(parser)
    parser.add_argument("-o", "--output", required=True, metavar="OUT",
                        help="OUT.png (one frame), OUT.mkv (lossless FFV1 video) or a folder of PNGs")
    parser.add_argument("--frames", type=int, default=1, metavar="N", help="frames to render (default 1)")
    parser.add_argument("--fps", type=float, default=30.0, help="frame rate of the controls' time (default 30)")
    parser.add_argument("--views-out", metavar="VDIR", help="also write the N views and cameras.json here")
    parser.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    from ..core.errors import InputError
    from ..render.loop import StageTimes
    from ._avatar import build_pipeline

    if args.frames < 1:
        raise InputError(f"{args.frames} frames", source="--frames", hint="give at least 1")
    if not 0 < args.fps <= 1000:
        raise InputError(f"{args.fps} frames per second", source="--fps", hint="use 0 < fps <= 1000")
    single, video = _check_outputs(args)
    pipeline, controls, avatar = build_pipeline(args)
    if pipeline.warning:
        import sys

        print(f"lenticalib: warning: {pipeline.warning}", file=sys.stderr)
    times = StageTimes()
    targets = [("raster", args.output, "frames folder", RASTER_CONTENTS)] if not (single or video) else []
    writer = _VideoFile(args.output, args.fps) if video else None
    if args.views_out:
        targets.append(("views", args.views_out, "views folder", VIEWS_CONTENTS))
    try:
        _render_frames(args, pipeline, controls, times, targets, writer, single)
    except BaseException:
        if writer is not None:
            writer.discard()
        raise
    if controls is not None:
        controls.close()
    what = args.output if single else f"{args.frames} frame(s) in {args.output}"
    if writer is not None:
        what = f"{args.frames} frame(s), lossless, in {args.output}"
    print(f"wrote {what}" + (f" and the views in {args.views_out}" if args.views_out else ""))
    print(times.table(f"lenticalib render: {avatar.source}, {pipeline.profile.views} views "
                      f"{pipeline.cameras.width}x{pipeline.cameras.height}, renderer {pipeline.renderer}, "
                      f"encoder {pipeline.encoder}"))
    return 0


def _check_outputs(args: argparse.Namespace) -> tuple[bool, bool]:
    """Refuse, before any work, outputs render cannot or must not write; return (one image, video)."""
    import os

    from ..core.errors import InputError
    from ..core.imageio import IMAGE_SUFFIXES, WRITE_FORMATS
    from ..core.outputs import check_output_file, check_output_folder

    suffix = os.path.splitext(args.output)[1].lower()
    single, video = suffix in WRITE_FORMATS, suffix == ".mkv"
    if (suffix in IMAGE_SUFFIXES or suffix in VIDEO_SUFFIXES) and not (single or video):
        raise InputError(f"render does not write {suffix} files: a lossy format blurs the raster's subpixels",
                         source=args.output,
                         hint="name it .png (one frame) or .mkv (a lossless video), or give a folder for PNG frames")
    if single and args.frames != 1:
        raise InputError(f"{args.frames} frames cannot go into one {suffix[1:].upper()}", source="--output",
                         hint="give a folder for a sequence, or a .mkv video")
    if single or video:
        check_output_file(args.output, "video" if video else "raster", "out.mkv" if video else "out.png")
    else:
        check_output_folder(args.output, "frames folder", RASTER_CONTENTS)
    if args.views_out:
        check_output_folder(args.views_out, "views folder", VIEWS_CONTENTS)
        out, views = (os.path.realpath(p) for p in (args.output, args.views_out))
        if out == views or views.startswith(out + os.sep) or out.startswith(views + os.sep):
            raise InputError("is, or is inside, the --output path", source=args.views_out,
                             hint="give the views a folder of their own, beside the output")
    return single, video


def _render_frames(args, pipeline, controls, times, targets, writer, single) -> None:
    import numpy as np

    from ..core.imageio import write_image
    from ..core.outputs import staged_folder

    with _staged(targets, staged_folder) as folders:
        for k in range(args.frames):
            vector = controls.latest(k / args.fps)[1] if controls is not None else None
            raster, views, stages = pipeline.frame(vector)
            stages["present"] = 0.0
            times.add(**stages)
            if single:
                write_image(args.output, raster)
            elif writer is not None:
                writer.write(raster)
            else:
                write_image(folders["raster"] / f"frame-{k:05d}.png", raster)
            if "views" in folders:
                views = views if isinstance(views, np.ndarray) else views.cpu().numpy()
                frame_dir = folders["views"] / f"frame-{k:05d}"
                frame_dir.mkdir()
                for i, view in enumerate(views):
                    write_image(frame_dir / f"view-{i:02d}.png", view)
        if "views" in folders:
            pipeline.cameras.write_json(folders["views"] / "cameras.json")
        if writer is not None:
            writer.finish()


class _staged:
    """Enter several :func:`staged_folder` contexts at once: {name: folder being written}."""

    def __init__(self, targets, staged_folder):
        import contextlib

        self._stack = contextlib.ExitStack()
        self._targets = targets
        self._staged_folder = staged_folder

    def __enter__(self):
        from pathlib import Path

        stack = self._stack.__enter__()
        return {name: Path(stack.enter_context(self._staged_folder(path, what, contents)))
                for name, path, what, contents in self._targets}

    def __exit__(self, *exc):
        return self._stack.__exit__(*exc)


class _VideoFile:
    """A lossless FFV1 video written beside ``path`` and moved into place by :meth:`finish`
    (an interrupted render leaves no partial video, and an earlier one stays)."""

    def __init__(self, path: str, fps: float):
        from ..core.atomic import PendingFile
        from ..core.imageio import cv2_quiet

        self._cv2 = cv2_quiet()
        self.path = path
        self._pending = PendingFile(path, "video", suffix=".mkv")  # the replaced file's mode, umask's for a new one
        self.temp = str(self._pending.path)
        self.fps = fps
        self._writer = None

    def write(self, raster) -> None:
        from ..core.errors import InputError

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
