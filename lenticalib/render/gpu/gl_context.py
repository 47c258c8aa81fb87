"""OpenGL contexts with no window, shared by the offscreen presenter and the GL encoder and renderer.

:func:`offscreen_context` opens a moderngl context of at least a given OpenGL version on a named
backend, asking for the newest of ``PREFERRED_VERSIONS`` first: a driver may give exactly the
version asked for (NVIDIA's EGL gives a 3.3 context when 3.3 is asked for, so the gl renderer lost
its compute shaders on an H100), where Mesa gives its newest anyway.  :func:`headless_context`
prefers EGL (a GPU driver's, or Mesa's llvmpipe, which needs no X server) and leaves no EGL
context current afterwards (:func:`unbind_egl`), so that a window opened later in the same
process (GLX through glfw) can still be made current.
"""

from __future__ import annotations

import os

from ...core.errors import DisplayError
from .monitors import is_macos

# A vertex shader drawing one triangle that covers the viewport (3 vertices, no vertex buffer):
# every full-screen pass (the presenter's raster, the gl encoder) draws with it.
VIEWPORT_TRIANGLE = """
#version 330 core
void main() {
    vec2 p = vec2(float((gl_VertexID << 1) & 2), float(gl_VertexID & 2));
    gl_Position = vec4(p * 2.0 - 1.0, 0.0, 1.0);
}
"""
# OpenGL versions asked for first, newest first (4.3: compute shaders, which the gl renderer's
# projection and sort need); the caller's minimum is asked for last.
PREFERRED_VERSIONS = (460, 450, 430)


def versions_to_try(require: int) -> list[int]:
    """OpenGL version codes to ask a driver for, in order: the preferred ones above ``require``, then ``require``."""
    return [v for v in PREFERRED_VERSIONS if v > require] + [require]


def load_llvm_users_first() -> None:
    """Import triton (torch's kernel compiler, installed with CUDA builds of torch) before the
    first OpenGL context of the process, where it is installed.  Mesa's llvmpipe loads its LLVM
    with symbols visible to later libraries; triton bundles another LLVM, and importing it after a
    context exists (which torch does on its own, e.g. for operations it decomposes) crashes the
    process with a segmentation fault.  In this order both work.  Costs about 0.15 s, once."""
    import importlib
    import importlib.util
    import sys

    if "triton" in sys.modules or importlib.util.find_spec("triton") is None:
        return
    try:
        importlib.import_module("triton")
    except Exception:  # a broken triton is torch's business, not the presenter's
        pass


def offscreen_context(backend: str | None = None, require: int = 330, hint: str | None = None):
    """A moderngl context with no window: ``backend`` (``"egl"``, or None: EGL where there is no X
    server -- a GPU driver's, or Mesa's surfaceless llvmpipe -- else the platform's default),
    OpenGL ``require`` (330 = 3.3) or newer (:func:`versions_to_try`).  DisplayError (one line,
    naming the backend and what to install; ``hint`` appended) when there is none."""
    import moderngl

    if backend is None and os.name == "posix" and not is_macos() and not os.environ.get("DISPLAY"):
        backend = "egl"
    load_llvm_users_first()
    kwargs = {"standalone": True}
    if backend:
        kwargs["backend"] = backend
    for version in versions_to_try(require):
        try:
            return moderngl.create_context(require=version, **kwargs)
        except Exception as exc:  # moderngl raises plain Exceptions for context failures
            failure = exc
    text = str(failure).strip()
    raise DisplayError(f"no offscreen OpenGL {require // 100}.{require // 10 % 10} context ({backend or 'default'} "
                       f"backend: {text.splitlines()[-1] if text else repr(failure)})",
                       hint="install Mesa (libegl1, libgl1-mesa-dri) or a GPU driver"
                            + (f"; {hint}" if hint else "")) from None


def headless_context(require: int = 330, hint: str | None = None):
    """An offscreen context of OpenGL ``require`` or newer that needs no window system: EGL first,
    so that it does not depend on an X server that may go away; else the platform's default.
    DisplayError (one line) when there is none.  No context is left current: use it inside
    ``with ctx:``."""
    if os.name == "posix" and not is_macos():
        try:
            ctx = offscreen_context("egl", require, hint)
        except DisplayError:
            pass
        else:
            unbind_egl()
            return ctx
    return offscreen_context(None, require, hint)


def unbind_egl() -> None:
    """Leave no EGL context current on this thread (creating one makes it current).  A thread with
    a current EGL context cannot make a GLX context current afterwards (X error BadAccess, which
    ends the process), so a window opened later in the same process would fail.  Users of an
    offscreen context make it current around their own calls (``with ctx:``), which restores this
    state."""
    import ctypes

    try:
        lib = ctypes.CDLL("libEGL.so.1")
    except OSError:
        return
    lib.eglGetCurrentDisplay.restype = ctypes.c_void_p
    lib.eglMakeCurrent.argtypes = [ctypes.c_void_p] * 4
    display = lib.eglGetCurrentDisplay()
    if display:
        lib.eglMakeCurrent(display, None, None, None)


_PROBE: list = []  # the outcome of the one probe of this process: [None] or [DisplayError]


def headless_unavailable(hint: str) -> str | None:
    """Why no headless OpenGL 3.3 context can be made here (one line, ``hint`` appended: the other
    backend to use), or None.  One context is made and released for the whole process, however
    many backends ask (the gl renderer and the gl encoder both do, before a session starts)."""
    if not _PROBE:
        try:
            headless_context().release()
            _PROBE.append(None)
        except DisplayError as exc:
            _PROBE.append(exc)
    exc = _PROBE[0]
    if exc is None:
        return None
    return str(DisplayError(exc.message, source=exc.source, hint="; ".join(h for h in (exc.hint, hint) if h)))
