"""Helpers of the OpenGL renderer tests (test_gl_renderer: the ``gl`` triangles; test_gl_compute_renderer:
the ``gl-compute`` tiles): the test context, one render into a fresh renderer, the PSNR bar every renderer
is held to against ``cpu``, stand-ins for drivers that lack OpenGL 4.3 or vertex storage buffers, and a
child process on Mesa told to offer only OpenGL 4.1.
"""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap

import numpy as np
import pytest

from lenticalib.core.errors import InputError
from lenticalib.render.gpu.gl_context import headless_context
from lenticalib.render.renderers import render
from lenticalib.render.renderers.cpu import render_cpu

from .test_renderer_cpu import CAMERAS, H, SCENES, W, _psnr, random_scene

MIN_PSNR = 60.0


def gl_test_context():
    """Yield a headless OpenGL 4.3 context and release it after (the body of a module-scoped fixture)."""
    context = headless_context(require=430)
    yield context
    context.release()


def render_with(ctx, make, gaussians, viewmats, ks, background=None, after=None) -> np.ndarray:
    """(N, H, W, 4) float32: one render of ``gaussians`` by a fresh renderer ``make()`` in ``ctx``
    (released after; ``after(renderer)`` called before the read-back, e.g. to read its counters)."""
    with ctx:
        renderer = make()
        try:
            renderer.render(gaussians, viewmats, ks, background)
            if after is not None:
                after(renderer)
            return renderer.read()
        finally:
            renderer.release()


def assert_close(got, expected, min_psnr=MIN_PSNR):
    """Same shape, float32, and every view's RGB and alpha at least ``min_psnr`` dB from ``expected``."""
    assert got.shape == expected.shape and got.dtype == np.float32
    for view in range(len(got)):
        assert _psnr(got[view, ..., :3], expected[view, ..., :3]) >= min_psnr, f"view {view} RGB"
        assert _psnr(got[view, ..., 3], expected[view, ..., 3]) >= min_psnr, f"view {view} alpha"


def scene_against_cpu(name: str, renderer: str) -> tuple[np.ndarray, np.ndarray]:
    """(got, expected): the test scene ``name`` (test_renderer_cpu's SCENES) through the registry's
    ``renderer`` and through ``cpu``, on a background (none for "near"; "layered" in views of 50x37,
    partial tiles), asserted close (:func:`assert_close`)."""
    gaussians = SCENES[name]()
    background = (0.1, 0.2, 0.3) if name != "near" else None
    width, height = (W, H) if name != "layered" else (50, 37)
    expected = render_cpu(gaussians, *CAMERAS, width, height, background=background)
    assert expected[..., 3].max() > 0.5
    got = render(gaussians, *CAMERAS, width, height, renderer=renderer, background=background)
    assert_close(got, expected)
    return got, expected


def assert_refuses_other_view_counts(renderer) -> None:
    """``renderer``, made for 2 views, refuses the 4 of CAMERAS: one InputError naming ``viewmats``."""
    with pytest.raises(InputError, match="4 views, this renderer draws 2") as err:
        renderer.render(random_scene(0, n=5), *CAMERAS)
    assert err.value.source == "viewmats"


class OpenGL41:
    """The test context as a driver without compute shaders would report it (macOS stops at 4.1)."""

    version_code = 410

    def __init__(self, ctx):
        object.__setattr__(self, "_ctx", ctx)

    def __getattr__(self, name):
        return getattr(self._ctx, name)

    def __setattr__(self, name, value):  # blend_func and the like: the real context's state
        setattr(self._ctx, name, value)


class NoVertexStorage(OpenGL41):
    """An OpenGL 4.5 context whose driver allows no storage buffers in vertex shaders (4.3 permits it)."""

    version_code = 450

    @property
    def info(self):
        return dict(self._ctx.info, GL_MAX_VERTEX_SHADER_STORAGE_BLOCKS=0)


def run_under_opengl_41(script: str) -> subprocess.CompletedProcess:
    """Run ``script`` in a child Python on Mesa's llvmpipe told to offer OpenGL 4.1 (macOS's last: no
    compute shaders in that process at all), with numpy as ``np``, this checkout importable, test_renderer_cpu's
    CAMERAS, H, W and random_scene imported, and warnings logged to stderr; asserts it exits 0."""
    header = f"""
import logging, sys
import numpy as np
sys.path.insert(0, {str(os.getcwd())!r})
from tests.test_renderer_cpu import CAMERAS, H, W, random_scene
logging.basicConfig(level=logging.WARNING, format="%(message)s")
"""
    env = dict(os.environ, MESA_GL_VERSION_OVERRIDE="4.1", MESA_GLSL_VERSION_OVERRIDE="410",
               LIBGL_ALWAYS_SOFTWARE="1")  # Mesa's llvmpipe, also where a GPU driver is installed
    mesa_egl = "/usr/share/glvnd/egl_vendor.d/50_mesa.json"
    if os.path.exists(mesa_egl):
        env["__EGL_VENDOR_LIBRARY_FILENAMES"] = mesa_egl
    done = subprocess.run([sys.executable, "-c", header + textwrap.dedent(script)], env=env, capture_output=True,
                          text=True, timeout=120)
    assert done.returncode == 0, done.stderr[-2000:]
    return done
