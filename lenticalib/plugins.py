"""Backends by name: built-in "module:function" strings plus third-party entry points, imported lazily.

The encoder and renderer registries (:mod:`lenticalib.render.encoders`,
:mod:`lenticalib.render.renderers`) are built on these two functions.
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


def load(entries: Mapping[str, str], name: str, what: str, source: str) -> Callable:
    """The function registered as ``name`` in ``entries``.

    InputError (naming ``source``) for an unknown name; BackendUnavailableError when its module
    fails to import (a module's own BackendUnavailableError, with its one-line reason, passes).
    """
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
