"""The panel's view direction (``PanelProfile.view_direction``): said for people, parsed,
warned about, and recorded with how it was found.

+1: the view index grows as a viewer in front of the panel moves right; -1: it falls; None:
unknown.  A wrong direction shows the avatar with inverted depth (pseudoscopic), so a renderer
warns (:func:`direction_warning`) when the profile does not say.
"""

from __future__ import annotations

import datetime as _dt
import sys
from pathlib import Path
from typing import Any

from .errors import ProfileError
from .profile import VIEW_DIRECTIONS, PanelProfile


def describe_direction(direction: int | None) -> str:
    """``view_direction`` for people: ``"+1 (...)"``, ``"-1 (...)"`` or ``"unknown"``."""
    if direction == 1:
        return "+1 (the view index grows as the viewer moves right)"
    if direction == -1:
        return "-1 (the view index falls as the viewer moves right)"
    return "unknown"


def parse_direction(text: str, source: str = "DIRECTION") -> int | None:
    """``"+1"``/``"1"`` -> 1, ``"-1"`` -> -1, ``"unknown"`` -> None; ProfileError naming ``source`` otherwise."""
    value = {"+1": 1, "1": 1, "-1": -1, "unknown": None}.get(str(text).strip().lower(), 0)
    if value == 0:
        raise ProfileError(f"must be +1, -1 or unknown, got {text!r}", source=source,
                           hint="+1 when a viewer moving right sees RIGHT on 'lenticalib patterns --direction', "
                                "-1 when they see LEFT")
    return value


def direction_warning(profile: PanelProfile) -> str | None:
    """The one-line warning a renderer prints for a profile whose ``view_direction`` is unknown.

    RETURNED VALUE
    None when ``profile.view_direction`` is +1 or -1; otherwise one line (no prefix, no newline)
    saying the risk (inverted depth) and the two ways to find the direction.
    """
    if profile.view_direction in VIEW_DIRECTIONS:
        return None
    what = f"{profile.name!r}: " if profile.name else ""
    return (f"{what}the profile does not say which way its views run: if they run right to left, "
            "depth looks inverted (run 'lenticalib patterns --direction --profile P -o DIR', show "
            "DIR/direction.png and set it with 'lenticalib profile set-direction P +1|-1', "
            "or fit with 'lenticalib fit DIR --moved-right DIR2')")


def with_direction(profile: PanelProfile, direction: int | None, method: str, **evidence) -> PanelProfile:
    """A copy of ``profile`` with ``view_direction = direction`` and a note of how it was found.

    The note goes into ``provenance["view_direction"]``: ``value``, ``method`` (e.g. "set by
    hand", "moved-right"), ``set`` (UTC, ISO 8601), ``lenticalib_version``, ``command`` and
    ``evidence`` (free-form, JSON-ready).  The rest of the provenance is kept.
    """
    from .. import __version__

    note: dict[str, Any] = {
        "value": direction, "method": method,
        "set": _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds"),
        "lenticalib_version": __version__,
        "command": " ".join([Path(sys.argv[0]).name] + sys.argv[1:]) if sys.argv and sys.argv[0] else None,
    }
    if evidence:
        note["evidence"] = dict(evidence)
    provenance = dict(profile.provenance or {})
    provenance["view_direction"] = note
    return profile.replace(view_direction=direction, provenance=provenance)
