"""The identity of a panel profile, and the rule that results of different panels are not combined.

A panel's *identity* is a digest of its routing constants: views, slant, period, offset, reference
view, width, height, subpixel order, subpixel layout, reversed views and image flips (everything
:meth:`~lenticalib.core.profile.PanelProfile.routing_key` holds; not its name, provenance,
uncertainties or view direction).  Two profiles with the same identity route every subpixel the
same way; a profile saved and loaded again keeps its identity.  It reads ``p-`` and 16 hex digits.

Results record the identity of what they were made from (``docs/identity.md``): a crosstalk file
its ``profile_id`` (and the profile's constants), a profile fitted from a virtual panel's photos
its ``virtual_panel``, a crosstalk pattern folder the ``made_from`` of its profile.  A command that
combines two results calls :func:`check_same_panel`: a mismatch is one :class:`InputError` line,
unless the user forces it, and then the returned record says ``"forced": true`` for the output's
provenance.
"""

from __future__ import annotations

import hashlib
import json
import os
from pathlib import Path
from typing import Any, Mapping

from .errors import InputError
from .files.fields import is_finite_number
from .profile import profile_from_dict

IDENTITY_PREFIX = "p-"
_INT_KEYS = ("views", "width", "height")
_FLOAT_KEYS = ("slant", "period", "offset", "reference_view")
_FLAG_KEYS = ("views_reversed", "flip_image_x", "flip_image_y")
SIMULATION_RECORD = "simulation.json"  # what the virtual camera writes into a capture folder (lenticalib.sim.capture)


def routing_identity(constants: Mapping[str, Any]) -> str:
    """The identity (``p-`` + 16 hex digits) of the routing constants in ``constants``: a profile's
    JSON form (:meth:`~lenticalib.core.profile.PanelProfile.to_dict`) or a record of its constants
    (``subpixel_layout`` in its JSON form; absent flags count as false, an absent order as RGB).
    KeyError/TypeError/ValueError for a mapping without the constants (callers check them first)."""
    body = {k: int(constants[k]) for k in _INT_KEYS}
    body.update({k: float(constants[k]) for k in _FLOAT_KEYS})
    body["subpixel_order"] = str(constants.get("subpixel_order") or "RGB")
    body["subpixel_layout"] = constants.get("subpixel_layout")
    body.update({k: bool(constants.get(k, False)) for k in _FLAG_KEYS})
    text = json.dumps(body, sort_keys=True, separators=(",", ":"))
    return IDENTITY_PREFIX + hashlib.sha256(text.encode()).hexdigest()[:16]


def profile_identity(profile) -> str:
    """The identity of a :class:`~lenticalib.core.profile.PanelProfile` (module docstring)."""
    return routing_identity(profile.to_dict())


def identity_of_record(constants: Any, source: str, field: str = "profile") -> str:
    """The identity of the constants a result records under ``field`` (a profile's JSON form, checked
    as a profile is); InputError naming ``source`` and the field when they are not a valid profile."""
    profile = profile_from_dict(constants if isinstance(constants, dict) else None, source=f"{source} ({field})")
    return profile_identity(profile)


def check_same_panel(recorded: str | None, profile, *, what: str, source: str, force: bool = False,
                     hint: str | None = None) -> dict[str, Any]:
    """Refuse to combine a result made for the panel ``recorded`` (an identity, None: the result does
    not say) with ``profile`` of another panel.

    ARGUMENTS
    recorded   the identity the result ``source`` records (None: unknown, accepted)
    profile    the :class:`~lenticalib.core.profile.PanelProfile` it is combined with
    what       how the message names the result, e.g. "was measured for"
    force      accept a mismatch (the returned record says so)
    hint       what to do instead (default: make the result again for this profile); "or `force`" is added

    RETURNED VALUE
    dict for the output's provenance: ``made_for`` (the recorded identity or None), ``used_with``
    (``profile``'s identity), ``match`` (True, False or None when unknown), ``forced`` (True when a
    mismatch was accepted because of ``force``).

    Raises InputError naming ``source``, in one line, on a mismatch without ``force``.
    """
    actual = profile_identity(profile)
    match = None if recorded is None else recorded == actual
    if match is False and not force:
        raise InputError(f"{what} panel {recorded}, the profile is panel {actual} (another panel or another fit)",
                         source=source, hint=(hint or "make it again with this profile") + ", or `force` to use "
                         "it anyway")
    return {"made_for": recorded, "used_with": actual, "match": match, "forced": match is False}


def forced_note(record: Mapping[str, Any], source: str) -> str | None:
    """One line for a result combined by force (:func:`check_same_panel`'s record), else None."""
    if not record.get("forced"):
        return None
    return f"{source} was made for panel {record['made_for']}, used with panel {record['used_with']} as forced"


def virtual_panel_record(directory: str | os.PathLike) -> dict[str, Any] | None:
    """What the capture folder ``directory`` records of the virtual panel it photographed, or None
    for photos the virtual camera did not take (no ``simulation.json``, or one that is not
    complete or names no truth).

    RETURNED VALUE
    dict: ``seed`` (int), ``truth_id`` (identity of the ideal profile, ``truth.json``), ``truth``
    (its constants as recorded), ``capture_folder`` (absolute path), ``optics_digest`` (16 hex
    digits of the SHA-256 of the scene's panel optics: the panel whatever the camera position).
    Enough to photograph the same virtual panel again (:mod:`lenticalib.sim.capture_backend`)."""
    from .files.documents import FORMATS, read_document

    path = Path(directory) / SIMULATION_RECORD
    if not path.is_file():
        return None
    try:
        record = read_document(path, FORMATS["lenticalib.simulation-run"])
    except InputError:
        return None
    seed, truth = record.get("seed"), record.get("truth")
    if record.get("status") != "complete" or not isinstance(seed, int) or not isinstance(truth, dict):
        return None
    try:
        truth_id = routing_identity(truth)
    except (KeyError, TypeError, ValueError):
        return None
    constants = {k: v for k, v in truth.items() if k != "file"}
    optics = record.get("scene", {}).get("optics") if isinstance(record.get("scene"), dict) else None
    digest = hashlib.sha256(json.dumps(optics, sort_keys=True).encode()).hexdigest()[:16]
    return {"seed": seed, "truth_id": truth_id, "truth": constants,
            "capture_folder": str(Path(directory).resolve()), "optics_digest": digest}


def check_same_virtual_panel(first: str | os.PathLike, second: str | os.PathLike, source: str,
                             hint: str) -> None:
    """Refuse two capture folders that photographed different virtual panels (their
    ``simulation.json`` records different panel optics); photos of a real panel (no record) and
    the same panel from another camera position pass.  InputError naming ``source`` (``second``)."""
    a, b = virtual_panel_record(first), virtual_panel_record(second)
    if a is not None and b is not None and a["optics_digest"] != b["optics_digest"]:
        raise InputError(f"holds photos of virtual panel seed {b['seed']}, {first} of virtual panel seed {a['seed']}: "
                         "another panel", source=source, hint=hint)


def recorded_virtual_panel(provenance: Any, source: str) -> dict[str, Any] | None:
    """The virtual panel a profile's ``provenance`` names, checked: the ``virtual_panel`` a fit of
    virtual photos records, or the ``seed`` of a simulation's truth (``method`` "simulation");
    None when it names none.  InputError naming ``source`` for a record that is not one."""
    if not isinstance(provenance, Mapping):
        return None
    record = provenance.get("virtual_panel")
    if record is None and provenance.get("method") == "simulation" and "seed" in provenance:
        record = {"seed": provenance["seed"]}
    if record is None:
        return None
    seed = record.get("seed") if isinstance(record, Mapping) else None
    if not isinstance(seed, int) or isinstance(seed, bool) or not 0 <= seed < 2 ** 63:
        raise InputError("field 'virtual_panel' is not a record of a virtual panel (a 'seed' 0..2^63-1)",
                         source=source, hint="write the patterns again from a profile 'lenticalib fit' wrote")
    truth = record.get("truth")
    if truth is not None and not isinstance(truth, Mapping):
        raise InputError("field 'virtual_panel.truth' must be an object of profile constants", source=source)
    return dict(record)


def is_identity(value: Any) -> bool:
    """Whether ``value`` reads like an identity (``p-`` + 16 hex digits)."""
    return (isinstance(value, str) and len(value) == 18 and value.startswith(IDENTITY_PREFIX)
            and all(c in "0123456789abcdef" for c in value[2:]))


def describe_truth(truth: Mapping[str, Any]) -> str:
    """``period 14.86, slant -0.1234, RGB`` for a line naming a virtual panel (``truth``: its constants)."""
    parts = []
    for key, label, digits in (("period", "period", 2), ("slant", "slant", 4)):
        if is_finite_number(truth.get(key)):
            parts.append(f"{label} {float(truth[key]):.{digits}f}")
    layout = "cells" if truth.get("subpixel_layout") else truth.get("subpixel_order")
    if layout:
        parts.append(str(layout))
    return ", ".join(parts)
