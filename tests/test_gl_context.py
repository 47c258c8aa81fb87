"""The OpenGL contexts ask a driver for the newest version first (a driver may give exactly what is asked)."""

import moderngl
import pytest

from lenticalib.core.errors import DisplayError
from lenticalib.render.gpu import gl_context


def test_versions_are_asked_newest_first_and_the_minimum_last():
    assert gl_context.versions_to_try(330) == [460, 450, 430, 330]
    assert gl_context.versions_to_try(430) == [460, 450, 430]
    assert gl_context.versions_to_try(460) == [460]


def test_offscreen_context_takes_the_newest_version_the_driver_gives(monkeypatch):
    # a driver like NVIDIA's EGL: it gives exactly the version asked for, and has no 4.6 here
    asked = []

    def create_context(require, **kwargs):
        asked.append(require)
        if require > 450:
            raise Exception("eglCreateContext failed (0x3009)")
        return ("context", require)

    monkeypatch.setattr(moderngl, "create_context", create_context)
    assert gl_context.offscreen_context("egl") == ("context", 450)
    assert asked == [460, 450]


def test_no_context_at_all_ends_in_one_line_naming_the_minimum(monkeypatch):
    def create_context(require, **kwargs):
        raise Exception("eglInitialize failed\n(0x3001)")

    monkeypatch.setattr(moderngl, "create_context", create_context)
    with pytest.raises(DisplayError, match=r"no offscreen OpenGL 3\.3 context \(egl backend: \(0x3001\)\)"):
        gl_context.offscreen_context("egl")


def test_mesa_gives_compute_shaders_headless():
    ctx = gl_context.headless_context()
    try:
        assert ctx.version_code >= 430
    finally:
        ctx.release()
