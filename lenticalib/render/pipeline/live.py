"""``play_avatar``: the live loop drive -> render -> encode -> present, with per-stage timings.

Output: ``"panel"`` (full screen, pixel-exact, through the presenter; the monitor whose mode is
the profile's size unless ``display`` names one), ``"preview"`` (a normal window showing the
centre view, for a desk without a panel) or ``"headless"`` (no output: timing only; no present
stage).  Esc, q or closing the window stops; ``frames`` stops after that many, Ctrl-C too: on the
main thread the first Ctrl-C only asks the loop to stop after the current frame (an interrupt
raised inside a compiled kernel comes out as a SystemError, not a KeyboardInterrupt), a second
one interrupts at once.

Errors name the argument at fault by its parameter name (``source="frames"``); a command-line
front end maps them to its flags.
"""

from __future__ import annotations

import contextlib
import dataclasses
import os
import signal
import threading
import time
from typing import Callable

import numpy as np

from ...core.errors import InputError
from ...core.profile import PanelProfile
from .session import AvatarOptions, AvatarSession, open_avatar_session

OUTPUTS = ("panel", "preview", "headless")


@contextlib.contextmanager
def stop_on_interrupt():
    """Yields an Event set by the first Ctrl-C (SIGINT) while the block runs, on the main thread;
    a second Ctrl-C raises KeyboardInterrupt as usual.  Elsewhere (no signals) an Event never set."""
    requested = threading.Event()
    if threading.current_thread() is not threading.main_thread():
        yield requested
        return

    def on_interrupt(signum, frame):
        if requested.is_set():
            raise KeyboardInterrupt
        requested.set()

    previous = signal.signal(signal.SIGINT, on_interrupt)
    try:
        yield requested
    finally:
        signal.signal(signal.SIGINT, previous)


@dataclasses.dataclass
class PlayRun:
    """What :func:`play_avatar` did: the ``session`` (pipeline, avatar), ``times`` (a
    :class:`~.loop.StageTimes`), ``presenter_kind`` and ``controls_summary`` (the lines received
    and bad of live controls, or None)."""

    session: AvatarSession
    times: object
    presenter_kind: str
    controls_summary: str | None


def play_avatar(avatar: str | os.PathLike, profile: PanelProfile | str | os.PathLike, *,
                options: AvatarOptions | None = None, output: str = "panel", display: str | None = None,
                frames: int | None = None, on_warning: Callable[[str], None] | None = None,
                on_stats: Callable[[dict], None] | None = None) -> PlayRun:
    """Play ``avatar`` on ``profile``'s panel until Esc/q, Ctrl-C or ``frames`` frames (module
    docstring).  ``on_warning`` gets the pipeline's warning and notes (before the first frame: the
    profile's direction, the views that show nothing of the avatar; after it: fallbacks taken), ``on_stats``
    the stage times (ms, by stage) of a frame about once a second.  Returns :class:`PlayRun`."""
    from ..compose.host_views import views_on_host
    from .avatar_pipeline import StageTimes
    from ..present.displays import open_presenter
    from ..present.window import WindowPresenter
    from ..present.offscreen import MemoryPresenter

    if frames is not None and frames < 1:
        raise InputError(f"{frames} frames", source="frames", hint="give at least 1")
    if output not in OUTPUTS:
        raise InputError(f"unknown output {output!r}", source="output", hint=f"use one of {', '.join(OUTPUTS)}")
    session = open_avatar_session(avatar, profile, options)
    pipeline = session.pipeline
    profile, cameras = pipeline.profile, pipeline.cameras
    early = ([pipeline.warning] if pipeline.warning else []) + pipeline.notes  # the profile's, the empty views'
    for warning in early if on_warning is not None else ():
        on_warning(warning)
    if output == "headless":
        presenter = MemoryPresenter((profile.width, profile.height))
    elif output == "preview":
        presenter = WindowPresenter(None, windowed=(cameras.width, cameras.height))
    else:
        presenter = open_presenter(display, (profile.width, profile.height))
    centre = profile.views // 2
    times = StageTimes()
    start = last_report = time.perf_counter()
    with presenter, stop_on_interrupt() as interrupted:
        try:
            if presenter.ctx is not None:  # the gl renderer renders in the presenter's context
                pipeline.use_context(presenter.ctx)
            on_gpu = output == "panel" and pipeline.keeps_raster_on_gpu
            told = len(pipeline.notes)  # those said before the first frame
            while (frames is None or times.frames < frames) and not interrupted.is_set():
                t_controls = time.perf_counter()
                controls = session.controls_at(t_controls - start)  # a student driver predicts here
                controls_ms = 1e3 * (time.perf_counter() - t_controls)
                raster, views, stages = pipeline.frame(controls, raster_to_host=not on_gpu)
                stages["drive"] += controls_ms
                take = getattr(session.controls, "take_warnings", None)
                for warning in (take() if take is not None else ()):
                    if on_warning is not None:
                        on_warning(warning)
                t0 = time.perf_counter()
                if output == "preview":
                    view = views[centre]
                    presenter.show(view if isinstance(view, np.ndarray) else views_on_host(view[None])[0])
                    stages["present"] = 1e3 * (time.perf_counter() - t0)
                elif output != "headless":  # headless presents nothing: no present stage
                    pipeline.present(presenter, raster, stages)
                notes = pipeline.notes + presenter.notes
                for note in notes[told:]:  # fallbacks, said once (made on the first frame)
                    if on_warning is not None:
                        on_warning(note)
                told = len(notes)
                times.add(**stages)
                if any(k in ("escape", "q") for k in presenter.keys()):
                    break
                if on_stats is not None and time.perf_counter() - last_report >= 1.0:
                    last_report = time.perf_counter()
                    on_stats(dict(stages))
        except KeyboardInterrupt:
            pass
        finally:
            pipeline.close()  # its OpenGL objects, while the presenter's context is still open
            session.close()
    summary = session.controls.summary() if session.controls is not None else None
    return PlayRun(session, times, presenter.kind, summary or None)
