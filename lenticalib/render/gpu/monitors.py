"""The monitors a raster can be shown on: listing them (glfw) and choosing one.

Frames: monitor positions and modes in screen pixels of the virtual desktop (top-left origin).
"""

from __future__ import annotations

import dataclasses
import os
import sys

from ...core.errors import DisplayError


@dataclasses.dataclass(frozen=True)
class Monitor:
    """One monitor as the window system reports it.

    ``index``: position in the window system's list (0 = primary); ``x, y``: its top-left on
    the virtual desktop (screen pixels); ``width, height``: its current video mode (pixels);
    ``refresh_hz``; ``scale``: the desktop's content scale (1.0 = none); ``bits``: red, green,
    blue bits of the mode.
    """

    index: int
    name: str
    x: int
    y: int
    width: int
    height: int
    refresh_hz: int = 60
    scale: tuple[float, float] = (1.0, 1.0)
    bits: tuple[int, int, int] = (8, 8, 8)

    def describe(self) -> str:
        scale = "" if self.scale == (1.0, 1.0) else f", desktop scale {self.scale[0]:g}x{self.scale[1]:g}"
        return (f"{self.index}: {self.name} {self.width}x{self.height} @ {self.refresh_hz} Hz at "
                f"({self.x}, {self.y}), {self.bits[0]}-bit{scale}")


def glfw_module():
    try:
        import glfw
    except ImportError as exc:  # a dependency: should not happen in an installed lenticalib
        raise DisplayError(f"glfw is not available ({exc})", hint="pip install glfw") from None
    return glfw


def init_glfw():
    glfw = glfw_module()
    if not os.environ.get("DISPLAY") and not os.environ.get("WAYLAND_DISPLAY") and os.name == "posix" \
            and not is_macos():
        raise DisplayError("there is no display to show on (neither DISPLAY nor WAYLAND_DISPLAY is set)",
                           hint="run on the computer the panel is connected to, or start a virtual one "
                                "(Xvfb) and set DISPLAY")
    glfw.set_error_callback(None)
    if not glfw.init():
        raise DisplayError(f"the window system did not start (DISPLAY={os.environ.get('DISPLAY', '')!r})",
                           hint="check that the display is reachable (xset q) and that you may use it")
    return glfw


def is_macos() -> bool:
    return sys.platform == "darwin"


def list_monitors() -> list[Monitor]:
    """The monitors of the current display, primary first; DisplayError if there is no display."""
    glfw = init_glfw()
    out = []
    for index, handle in enumerate(glfw.get_monitors() or []):
        mode = glfw.get_video_mode(handle)
        x, y = glfw.get_monitor_pos(handle)
        name = glfw.get_monitor_name(handle)
        name = name.decode("utf-8", "replace") if isinstance(name, bytes) else str(name)
        out.append(Monitor(index, name, int(x), int(y), int(mode.size.width), int(mode.size.height),
                           int(mode.refresh_rate), tuple(float(s) for s in glfw.get_monitor_content_scale(handle)),
                           (int(mode.bits.red), int(mode.bits.green), int(mode.bits.blue))))
    if not out:
        raise DisplayError("the display reports no monitors", hint="connect the panel and switch it on")
    return out


def choose_monitor(monitors: list[Monitor], spec: str | None = None,
                   size: tuple[int, int] | None = None) -> Monitor:
    """The monitor ``spec`` names, or the one whose mode is ``size`` (width, height).

    ``spec``: an index ("1"), a position ("@3840,0": the monitor whose top-left is there), or
    a name (case-insensitive, a unique part of it is enough).  Without ``spec``, the one monitor
    whose current mode is ``size``; with neither, the primary.  DisplayError (listing the
    monitors) when nothing or more than one matches.
    """
    listing = "; ".join(m.describe() for m in monitors)
    if not monitors:
        raise DisplayError("the display reports no monitors", hint="connect the panel and switch it on")
    if spec is not None:
        spec = spec.strip()
        if spec.isdigit():
            matches = [m for m in monitors if m.index == int(spec)]
        elif spec.startswith("@"):
            try:
                x, y = (int(v) for v in spec[1:].split(","))
            except ValueError:
                raise DisplayError(f"position {spec!r} is not @X,Y", source="display",
                                   hint="e.g. `display` @3840,0") from None
            matches = [m for m in monitors if (m.x, m.y) == (x, y)]
        else:
            exact = [m for m in monitors if m.name.lower() == spec.lower()]
            matches = exact or [m for m in monitors if spec.lower() in m.name.lower()]
        if len(matches) != 1:
            what = "no monitor matches" if not matches else f"{len(matches)} monitors match"
            raise DisplayError(f"{what} {spec!r}; the monitors are: {listing}", source="display",
                               hint="give an index, @X,Y or a unique part of a name (lenticalib show --list-displays)")
        return matches[0]
    if size is not None:
        matches = [m for m in monitors if (m.width, m.height) == tuple(size)]
        if len(matches) == 1:
            return matches[0]
        if not matches:
            raise DisplayError(f"no monitor shows {size[0]}x{size[1]} (the raster's size); the monitors are: "
                               f"{listing}", source="display",
                               hint="set the panel to its native mode, or name the monitor with `display`")
        raise DisplayError(f"{len(matches)} monitors show {size[0]}x{size[1]}; the monitors are: {listing}",
                           source="display", hint="name the panel's monitor with `display`")
    return monitors[0]
