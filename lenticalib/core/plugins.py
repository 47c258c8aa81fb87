"""Backends by name: the one loader behind every registry of the package.

Each registry is a :class:`Registry`: a table of built-in ``"module:attribute"`` strings plus the
entry points of one group, imported lazily (building a registry or listing its names imports no
backend).  Third parties add backends through the group; a built-in name cannot be taken over.

    registry          entry-point group               value                  built-ins in
    encoders          lenticalib.encoders             module:function        lenticalib.render.encoders
    renderers         lenticalib.renderers            module:function        lenticalib.render.renderers
    transports        lenticalib.transports           module:Class           lenticalib.device.transports
    Looking Glass     lenticalib.looking_glass_units  module:Class           lenticalib.device.looking_glass
    capture cameras   lenticalib.capture_cameras      module:Class           lenticalib.calib.capture.cameras
    camera models     lenticalib.camera_models        module:function        lenticalib.render.cameras.models
    avatar drivers    lenticalib.avatar_drivers       module:callable        lenticalib.render.avatar.drivers
    pattern sets      lenticalib.pattern_sets         module:function        lenticalib.core.pattern_sets

What each backend must be (its signature, optional attributes such as a transport's
``list_devices``) is said by the module that owns the registry.

A backend whose module imports but which cannot run on this machine (no CUDA GPU, say) says so
through an ``unavailable`` attribute: ``unavailable(device) -> str | None``, a one-line reason, or
None when it can run here (``device`` is the torch device asked for, or None).
:meth:`Registry.load` asks it, and refuses such a backend in one line that names the ones that
can run here, before the caller loads anything else.  It is asked only for the backend named
(and, on refusal, the others), so an expensive check (importing torch) costs nothing otherwise.

Every failure is one line: an unknown name names the choices; a module that fails to import
names the library to install (the registry's ``install`` hints) or the import error's first line.
"""

from __future__ import annotations

import importlib
from importlib import metadata
from typing import Any, Callable, Iterator, Mapping

from .errors import BackendUnavailableError, InputError, LenticalibError


class Registry(Mapping[str, Any]):
    """Backends of one kind by name: ``builtin`` ``{name: "module:attribute"}`` plus the ``group``
    entry points (None: built-ins only), read each time they are asked for (loading a built-in
    by name reads none: it cannot be taken over).

    ``what`` is the kind's word in messages ("encoder", "transport"); ``install`` maps a name to the
    library its module needs (the hint when it fails to import); ``unknown_error`` is the error
    class for an unknown name and ``choices`` its hint, ``{names}`` the comma-separated names.

    As a read-only mapping it iterates the names (built-ins in table order, then plug-ins), and
    ``registry[name]`` imports the backend (KeyError for an unknown name).
    """

    def __init__(self, what: str, builtin: Mapping[str, str], group: str | None, *,
                 install: Mapping[str, str] | None = None, unknown_error: type[LenticalibError] = InputError,
                 choices: str = "choose one of {names}"):
        self.what = what
        self.builtin = dict(builtin)
        self.group = group
        self.install = dict(install or {})
        self.unknown_error = unknown_error
        self.choices = choices

    def entries(self) -> dict[str, str]:
        """``{name: "module:attribute"}``: the built-ins, then the entry points of the group."""
        entries = dict(self.builtin)
        if self.group is None:
            return entries
        try:
            for ep in metadata.entry_points(group=self.group):
                entries.setdefault(ep.name, ep.value)
        except Exception:  # noqa: BLE001  (a broken third-party distribution must not break the built-ins)
            pass
        return entries

    def names(self) -> list[str]:
        """Sorted names of every registered backend."""
        return sorted(self.entries())

    def __iter__(self) -> Iterator[str]:
        return iter(self.entries())

    def __len__(self) -> int:
        return len(self.entries())

    def __contains__(self, name: object) -> bool:
        return isinstance(name, str) and name in self.entries()

    def __getitem__(self, name: str) -> Any:
        entries = self.entries()
        if name not in entries:
            raise KeyError(name)
        return self._import(entries, name, self.what)

    def check(self, name: str, source: str) -> str:
        """``name`` if it is registered; the registry's unknown-name error naming ``source`` otherwise."""
        return self._check(self.entries(), name, source)

    def _check(self, entries: Mapping[str, str], name: str, source: str) -> str:
        if not isinstance(name, str) or name not in entries:
            raise self.unknown_error(f"unknown {self.what} {name!r}", source=source,
                                     hint=self.choices.format(names=", ".join(sorted(entries))))
        return name

    def load(self, name: str, source: str, *, device: str | None = None) -> Any:
        """The backend registered as ``name``, able to run here (on ``device``).

        The unknown-name error (naming ``source``) for a name not registered;
        BackendUnavailableError when its module fails to import (a module's own
        BackendUnavailableError, with its one-line reason, passes) or when its
        ``unavailable(device)`` gives a reason; the hint names the backends that can run here.
        """
        # a built-in name cannot be taken over, so it needs no entry points (they cost milliseconds,
        # which a per-frame caller such as ``encode`` would pay every frame); read them once otherwise
        entries = self.builtin if isinstance(name, str) and name in self.builtin else self.entries()
        backend = self._import(entries, self._check(entries, name, source), source)
        reason = unavailable(backend, device)
        if reason is not None:
            others = self.runnable(device, exclude=name)
            hint = f"{self.what}s that can run here: {', '.join(others)}" if others else f"no {self.what} can run here"
            raise BackendUnavailableError(f"{self.what} {name!r} cannot run here: {reason}", source=source, hint=hint)
        return backend

    def runnable(self, device: str | None = None, exclude: str | None = None) -> list[str]:
        """Sorted names whose module imports and that can run here on ``device``."""
        entries = self.entries()
        names = []
        for name in sorted(entries):
            if name == exclude:
                continue
            try:
                if unavailable(self._import(entries, name, self.what), device) is None:
                    names.append(name)
            except Exception:  # noqa: BLE001  (a broken backend is simply not one that can run)
                continue
        return names

    def _import(self, entries: Mapping[str, str], name: str, source: str) -> Any:
        lib = self.install.get(name)
        hint = f"install {lib} (pip install {lib})" if lib else "install its dependencies"
        return import_target(entries[name], f"{self.what} {name!r}", source, hint=hint)


def import_target(target: str, what: str, source: str, *, hint: str | None = "install its dependencies") -> Any:
    """The object ``target`` (``"module:attribute"``, the attribute may be dotted, ``"module"`` the
    module itself) names, imported now.

    ``what`` names it in messages ("encoder 'fast'").  BackendUnavailableError naming ``source``
    when the module fails to import (a module's own BackendUnavailableError passes; ``hint`` for a
    missing module, the first line of any other error); InputError when the attribute is missing.
    """
    module_name, _, attr = target.partition(":")
    module_name, attr = module_name.strip(), attr.strip()
    try:
        module = importlib.import_module(module_name)
    except BackendUnavailableError:
        raise
    except ModuleNotFoundError as exc:
        raise BackendUnavailableError(f"{what} is not available: no module named {exc.name or module_name!r}",
                                      source=source, hint=hint) from None
    except ImportError as exc:
        raise BackendUnavailableError(f"{what} is not available: {_first_line(exc)}", source=source,
                                      hint=hint) from None
    except Exception as exc:  # noqa: BLE001  (a plug-in's own import-time failure, reported on one line)
        first = _first_line(exc)
        raise BackendUnavailableError(f"{what} failed to import: {type(exc).__name__}{': ' + first if first else ''}",
                                      source=source) from None
    obj: Any = module
    for part in attr.split(".") if attr else ():
        if not hasattr(obj, part):
            raise InputError(f"module {module_name!r} has no attribute {attr!r}", source=source,
                             hint="check the name after the colon")
        obj = getattr(obj, part)
    return obj


def _first_line(exc: BaseException) -> str:
    text = str(exc).strip()
    return text.splitlines()[0] if text else ""


# -- the functions the registries were first built on (thin wrappers over Registry) -------------

def registry(builtin: Mapping[str, str], group: str) -> dict[str, str]:
    """``builtin`` plus the ``group`` entry points (a built-in name cannot be taken over)."""
    return Registry("backend", builtin, group).entries()


def load(entries: Mapping[str, str], name: str, what: str, source: str, *, device: str | None = None) -> Callable:
    """The backend registered as ``name`` in ``entries``, able to run here (:meth:`Registry.load`)."""
    return Registry(what, entries, None).load(name, source, device=device)


def unavailable(func: Callable, device: str | None = None) -> str | None:
    """Why the backend ``func`` cannot run here on ``device`` (one line), or None (module docstring)."""
    check = getattr(func, "unavailable", None)
    return None if check is None else check(device)


def runnable(entries: Mapping[str, str], device: str | None = None, exclude: str | None = None) -> list[str]:
    """Sorted names in ``entries`` whose module imports and that can run here on ``device``."""
    return Registry("backend", entries, None).runnable(device, exclude)
