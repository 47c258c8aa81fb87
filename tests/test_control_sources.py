"""Control sources by spec: the registry picks the source a spec names, and nothing else."""

from __future__ import annotations

import pytest

from lenticalib.render.avatar.rig import DEFAULT_LAYOUT
from lenticalib.render.controls import sources
from lenticalib.render.controls.sources import CONTROL_SOURCES, control_scheme, open_controls

OPENED = []


def open_tracker(spec, layout, names=None):
    """A plug-in control source for the test: records what it was opened with."""
    OPENED.append((spec, layout.dim))
    return "tracker source"


@pytest.mark.parametrize("spec, scheme", [
    ("demo", "demo"), ("-", "stdin"), ("stdin", "stdin"), ("udp://127.0.0.1:9000", "udp"),
    ("student:s.pt?camera=0", "student"), ("poses.csv", "file"), ("demo:poses.csv", "file"),
    ("stdin:x.jsonl", "file"), ("udp:x.csv", "file"), ("file:x.csv", "file"), ("unknown:x.csv", "file"),
    ("C:/captures/x.csv", "file")])
def test_each_spec_has_one_scheme(spec, scheme):
    assert control_scheme(spec) == scheme


def test_a_plugin_source_is_opened_by_its_name(monkeypatch):
    monkeypatch.setattr(sources.CONTROL_SOURCES, "entries",
                        lambda: {**CONTROL_SOURCES.builtin, "tracker": "tests.test_control_sources:open_tracker"})
    OPENED.clear()
    assert control_scheme("tracker:192.168.1.7") == "tracker"
    assert open_controls("tracker:192.168.1.7", DEFAULT_LAYOUT) == "tracker source"
    assert OPENED == [("tracker:192.168.1.7", DEFAULT_LAYOUT.dim)]
