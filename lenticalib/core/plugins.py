"""Backends by name: built-in "module:function" strings plus third-party entry points, imported lazily.

The encoder and renderer registries (:mod:`lenticalib.render.encoders`,
:mod:`lenticalib.render.renderers`) are built on these functions.

A backend whose module imports but which cannot run on this machine (no CUDA GPU, say) says so
through an ``unavailable`` attribute on its function: ``unavailable(device) -> str | None``, a
one-line reason, or None when it can run here (``device`` is the torch device asked for, or
None).  :func:`load` asks it, and refuses such a backend in one line that names the ones that
can run here, before the caller loads anything else.  It is asked only for the backend named
(and, on refusal, the others), so an expensive check (importing torch) costs nothing otherwise.
"""

from __future__ import annotations

import importlib
from importlib import metadata
from typing import Callable, Mapping

from .errors import BackendUnavailableError, InputError


def registry(builtin: Mapping[str, str], group: str) -> dict[str, str]:
    """``builtin`` plus the ``group`` entry points (a built-in name cannot be taken over)."""
    entries = dict(builtin)
    try:
        for ep in metadata.entry_points(group=group):
            entries.setdefault(ep.name, ep.value)
    except Exception:  # a broken third-party distribution must not break the built-ins
        pass
    return entries


def load(entries: Mapping[str, str], name: str, what: str, source: str, *, device: str | None = None) -> Callable:
    """The function registered as ``name`` in ``entries``, able to run here (on ``device``).

    InputError (naming ``source``) for an unknown name; BackendUnavailableError when its module
    fails to import (a module's own BackendUnavailableError, with its one-line reason, passes) or
    when its ``unavailable(device)`` gives a reason (module docstring); the hint names the
    backends that can run here.
    """
    func = _import(entries, name, what, source)
    reason = unavailable(func, device)
    if reason is not None:
        others = runnable(entries, device, exclude=name)
        hint = f"{what}s that can run here: {', '.join(others)}" if others else f"no {what} can run here"
        raise BackendUnavailableError(f"{what} {name!r} cannot run here: {reason}", source=source, hint=hint)
    return func


def unavailable(func: Callable, device: str | None = None) -> str | None:
    """Why the backend ``func`` cannot run here on ``device`` (one line), or None (module docstring)."""
    check = getattr(func, "unavailable", None)
    return None if check is None else check(device)


def runnable(entries: Mapping[str, str], device: str | None = None, exclude: str | None = None) -> list[str]:
    """Sorted names in ``entries`` whose module imports and that can run here on ``device``."""
    names = []
    for name in sorted(entries):
        if name == exclude:
            continue
        try:
            if unavailable(_import(entries, name, "backend", "backend"), device) is None:
                names.append(name)
        except Exception:  # noqa: BLE001  (a broken backend is simply not one that can run)
            continue
    return names


def _import(entries: Mapping[str, str], name: str, what: str, source: str) -> Callable:
    if name not in entries:
        raise InputError(f"unknown {what} {name!r}", source=source,
                         hint="choose one of " + ", ".join(sorted(entries)))
    module_name, _, attr = entries[name].partition(":")
    try:
        module = importlib.import_module(module_name)
    except BackendUnavailableError:
        raise
    except ImportError as exc:
        raise BackendUnavailableError(f"{what} {name!r} is not available: {exc}", source=source,
                                      hint="install its dependencies") from None
    return getattr(module, attr)
