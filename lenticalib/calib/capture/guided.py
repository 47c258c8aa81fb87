"""``guided_capture``: the whole of ``lenticalib capture`` as one library call.

It decides what a camera kind implies (the virtual panel's camera shows offscreen and needs no
settling; a real one waits 0.5 s for the panel), checks every option against the kind before any
hardware is touched, and opens in the order that keeps a failure cheap: the camera constructed
(its spec checked), the presenter made, the camera opened, then the presenter opened (a camera
that will not open fails before the panel goes full screen).  Where the virtual panel's camera
was given no display and this machine has no OpenGL, it shows without graphics instead.

The presenter comes from the caller (``open_presenter(display, size)``, the render layer's
:func:`~lenticalib.render.present.displays.open_presenter`): calib never imports render.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Callable

from ...core.errors import DisplayError, InputError
from ...core.pattern_sets import read_pattern_folder
from .acquire import CaptureReport, capture_set, wait_for_key
from .cameras import make_camera

SIM_DEFAULTS = {"display": "offscreen", "settle": 0.0}  # the virtual panel: no window, no settling
REAL_DEFAULTS = {"display": None, "settle": 0.5}  # None: the monitor whose mode is the panel's size
SIM_ONLY = {"layout": "a real panel's layout is what it is; drop `layout`",
            "subsamples": "a real camera takes one photo per pattern; drop `subsamples`"}


def guided_capture(directory: str | os.PathLike, camera: str, open_presenter: Callable, *,
                   display: str | None = None, settle: float | None = None, retakes: int = 2,
                   restart: bool = False, timeout: float = 600.0, resolution: tuple[int, int] | None = None,
                   conditions: str = "standard", subsamples: int | None = None, layout: str | None = None,
                   on_start: Callable[[int, list[str]], Callable[[str], None] | None] | None = None,
                   notify: Callable[[str], None] | None = None,
                   note: Callable[[str], None] | None = None) -> CaptureReport:
    """Show every pattern of the folder ``directory`` on the panel and photograph it with the
    capture camera ``camera`` (a spec such as ``gphoto2``, ``opencv:0``, ``sim:7``).

    ``display``/``settle``: None takes the camera kind's default (:data:`SIM_DEFAULTS`,
    :data:`REAL_DEFAULTS`); ``settle`` seconds 0..60; ``retakes`` 0..20; ``timeout``: seconds a
    manual camera with a folder waits for each photo; ``resolution``, ``conditions``,
    ``subsamples``, ``layout``: the virtual panel's camera only.  ``on_start(count, settings)`` is
    called once everything is open, with the number of patterns and the camera's settings lines,
    and may return the per-pattern progress callable; ``notify(message)`` gets each rejected photo,
    ``note(message)`` what the run decided by itself (the fallback to no graphics).  Every bad option is an InputError naming it, raised before
    anything is opened.
    """
    if settle is not None and not 0 <= settle <= 60:
        raise InputError(f"{settle} seconds is out of range", source="settle", hint="use 0..60")
    if not 0 <= retakes <= 20:
        raise InputError(f"{retakes} is out of range", source="retakes", hint="use 0..20")
    directory = Path(directory)
    pattern_set = read_pattern_folder(directory)
    size = (pattern_set.width, pattern_set.height)
    kind = camera.split(":", 1)[0]
    defaults = SIM_DEFAULTS if kind == "sim" else REAL_DEFAULTS
    shown_on = display if display is not None else defaults["display"]
    settle = settle if settle is not None else defaults["settle"]
    options: dict = {"timeout": timeout}
    if kind == "sim":
        options.update(resolution=resolution, conditions=conditions, folder=directory)
        options.update({k: v for k, v in (("layout", layout), ("subsamples", subsamples)) if v is not None})
    else:
        for name, value in (("layout", layout), ("subsamples", subsamples)):
            if value is not None:
                raise InputError("applies only to `camera` sim", source=name, hint=SIM_ONLY[name])
    presenter = None
    if kind == "manual" and ":" not in camera:
        options["wait_for_user"] = lambda name: wait_for_key(presenter, name)
    capture_camera = make_camera(camera, **options)  # the spec and options checked; no hardware touched yet
    presenter = open_presenter(shown_on, size)
    capture_camera.open()
    with capture_camera:
        try:
            presenter.open()
        except DisplayError as exc:
            if display is not None or kind != "sim":
                raise
            if note is not None:  # no OpenGL here: the virtual panel needs none
                note(f"{exc.message}; showing without graphics (`display` none)")
            presenter = open_presenter("none", size)
            presenter.open()
        try:
            progress = on_start(len(pattern_set.patterns), list(capture_camera.settings())) if on_start else None
            return capture_set(directory, presenter, capture_camera, settle=settle, retakes=retakes,
                               restart=restart, progress=progress, notify=notify)
        finally:
            presenter.close()
