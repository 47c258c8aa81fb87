"""Control sources by spec: one registry from a spec's scheme to the source that serves it.

Every source answers ``latest(now)`` with ``(t, controls)``: a timestamp in seconds and a (D,)
float32 numpy vector laid out as the rig's :class:`~lenticalib.render.avatar.rig.ControlLayout`
says; ``close()`` ends it and ``summary()`` gives one line for the end of a session or None.

    spec                  scheme    source
    "demo"                demo      :class:`~.streams.DemoControls`, the built-in motion: a slow
                                    head turn, talking, blinks
    "-" or "stdin"        stdin     :class:`~.streams.StreamControls`: JSON lines on standard input
    "udp://HOST:PORT"     udp       :class:`~.streams.StreamControls`: JSON lines in UDP datagrams
    "student:PATH?camera=K|video=FILE"
                          student   :class:`~lenticalib.render.student.live.StudentControls`: a
                                    student driver predicting from a camera or a video, live
    "NAME:..."            NAME      a plug-in source registered under the entry-point group
                                    ``lenticalib.control_sources``
    anything else         file      :class:`~.files.FileControls` over a control file (``.npz``,
                                    ``.csv``, ``.jsonl``: :mod:`.files`)

Each entry of :data:`CONTROL_SOURCES` is a ``"module:function"`` string (the one plug-in loader,
:class:`~lenticalib.core.plugins.Registry`), imported only when its scheme is asked for (the
student's torch only for a student), with the signature
``open_source(spec, layout, names) -> source``: ``spec`` the whole spec, ``layout`` the rig's
control layout, ``names`` the rig's component names or None.
"""

from __future__ import annotations

from typing import Sequence

from ...core.plugins import Registry
from ..avatar.rig import DEFAULT_LAYOUT, ControlLayout

ENTRY_POINT_GROUP = "lenticalib.control_sources"
CONTROL_SOURCES = Registry("control source", {
    "demo": "lenticalib.render.controls.streams:open_demo_source",
    "stdin": "lenticalib.render.controls.streams:open_stdin_source",
    "udp": "lenticalib.render.controls.streams:open_udp_source",
    "student": "lenticalib.render.student.live:open_student_source",
    "file": "lenticalib.render.controls.files:open_file_source",
}, ENTRY_POINT_GROUP)


EXACT_SPECS = {"demo": "demo", "-": "stdin", "stdin": "stdin"}  # built-in specs that take no argument
BUILTIN_PREFIXES = {"udp://": "udp", "student:": "student"}  # built-in specs with an argument


def control_scheme(spec: str) -> str:
    """The registry name that serves ``spec`` (the table in the module docstring): a built-in spec
    as written, ``NAME:...`` for a plug-in ``NAME``, anything else a control file's path."""
    if spec in EXACT_SPECS:
        return EXACT_SPECS[spec]
    for prefix, scheme in BUILTIN_PREFIXES.items():
        if spec.startswith(prefix):
            return scheme
    scheme, colon, _ = spec.partition(":")
    plugin = colon and scheme.isidentifier() and scheme not in CONTROL_SOURCES.builtin
    return scheme if plugin and scheme in CONTROL_SOURCES else "file"


def open_controls(spec: str, layout: ControlLayout = DEFAULT_LAYOUT, names: Sequence[str] | None = None):
    """A control source for ``spec`` (the table in the module docstring), opened."""
    return CONTROL_SOURCES.load(control_scheme(spec), "controls")(spec, layout, names)
