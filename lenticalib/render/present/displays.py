"""Presenters by display spec: one registry from a spec's kind to the presenter that serves it.

    display spec                kind        presenter
    None, INDEX, @X,Y, NAME     window      :class:`~.window.WindowPresenter`: full screen on a monitor
                                            (the one whose mode is the raster's size, by default)
    "offscreen[:BACKEND]"       offscreen   :class:`~.offscreen.OffscreenPresenter`: an OpenGL framebuffer,
                                            no window (EGL first; BACKEND names one)
    "none"                      none        :class:`~.offscreen.MemoryPresenter`: no graphics at all
    "NAME[:...]"                NAME        a plug-in registered under ``lenticalib.presenters``

Each entry of :data:`PRESENTERS` is a ``"module:function"`` string (the one plug-in loader,
:class:`~lenticalib.core.plugins.Registry`), imported only when its kind is asked for, with the
signature ``open(display, size, *, monitors=None, vsync=True) -> Presenter`` (not yet opened):
``display`` the whole spec, ``size`` the raster's ``(width, height)`` in pixels or None.
"""

from __future__ import annotations

from ...core.errors import DisplayError
from ...core.plugins import Registry
from .base import Presenter

ENTRY_POINT_GROUP = "lenticalib.presenters"
PRESENTERS = Registry("display", {
    "window": "lenticalib.render.present.window:window_presenter",
    "offscreen": "lenticalib.render.present.offscreen:offscreen_presenter",
    "none": "lenticalib.render.present.offscreen:memory_presenter",
}, ENTRY_POINT_GROUP, install={"window": "glfw and moderngl", "offscreen": "moderngl"}, unknown_error=DisplayError)


def display_kind(display: str | None) -> str:
    """The registry name that serves ``display`` (the table in the module docstring)."""
    if display is None:
        return "window"
    kind = display.partition(":")[0]
    return kind if kind != "window" and kind.isidentifier() and kind in PRESENTERS else "window"


def open_presenter(display: str | None = None, size: tuple[int, int] | None = None,
                   monitors=None, vsync: bool = True) -> Presenter:
    """A presenter (not yet opened) for ``display`` (the table in the module docstring) showing
    rasters of ``size`` ``(width, height)``; ``monitors`` injected for tests."""
    return PRESENTERS.load(display_kind(display), "display")(display, size, monitors=monitors, vsync=vsync)
