"""The crosstalk patterns: view bands swept across the panel, drawn from a fitted profile.

Frames and units: panel raster pixels ``(x, y)``, subpixel index ``x_s = 3 x + rho(c)`` (with a
subpixel layout slot ``c`` of a pixel is channel ``c``); view coordinates ``w`` in views
(``docs/optics.md``, :func:`lenticalib.core.routing.view_coordinate`: a layout's slot shift and
reversed views included): subpixel ``(x_s, y)`` shows view ``floor(w(x_s, y)) mod N``, the view
:func:`~lenticalib.core.routing.view_map` gives it, and, with a calibrated profile, the camera of
the fit sits at ``w = N/2``.  Positions on the panel are the slots' continuous indices
``x_s + e`` (``e`` the slot shift of a subpixel layout, 0 on a stripe panel).

A *band* pattern lights (every colour, full white) the subpixels whose ``w`` lies within half a
view of a centre ``b`` that moves slowly across the panel:

    b(x) = N/2 + shift + N (x + 0.5) / (3 sweep)        (views; sweep in pixels; x = x_s + e)

so the camera, which sees ``w = N/2`` everywhere, sees at panel column ``x`` a one-view band
centred ``delta = b - N/2`` views away from it: one photo samples the whole view cone across the
panel (a slow spatial sweep: ``sweep / N`` pixels per view, ``LENSES_PER_VIEW`` lenses), and ``BAND_PATTERNS``
photos with shifts ``k N / BAND_PATTERNS`` put every part of the panel at every offset.  The two
*half* patterns light the half of the views around ``b`` and the other half: their light adds
up to white's at every camera pixel whatever the camera's tone curve does to each, which is what
measures the tone curve (:mod:`.tone`).  The three *level* patterns light every subpixel of one
panel row in 8, 4 and 2 (all views): to the camera, which cannot resolve single rows of the panel
well, a grey of exactly 1/8, 1/4 and 1/2 of white's light (above black) however the panel's own
tone response runs, which pins the camera's tone curve between black and white.  ``black`` and
``white`` are the references.  Every
pattern carries the calibration patterns' registration frame (the same even frame on all four
sides), so shake is measured and undone as in the fit.

The manifest ``patterns.json`` (format ``lenticalib.crosstalk-patterns``) records the profile the
bands were drawn from; the measurement uses exactly that profile.  When that profile was fitted
from photos of the virtual panel (or is a simulation's truth), the manifest also records which
virtual panel (``virtual_panel``), so ``capture --camera sim`` photographs that one
(``docs/identity.md``).
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import math
from typing import Any

import numpy as np

from ...core.colour import srgb_encode8
from ...core.files.documents import FORMATS, check_envelope
from ...core.errors import InputError
from ...core.identity import recorded_virtual_panel
from ...core.pattern_sets import manifest_matches
from ...core.profile import PanelProfile, profile_from_dict
from ...core.routing import slot_shift_rows, view_coordinate
from .calibration_patterns import FRAME_LEVEL, frame_width

DOCUMENT = FORMATS["lenticalib.crosstalk-patterns"]
FORMAT_NAME, FORMAT_VERSION = DOCUMENT.name, DOCUMENT.version
BAND_PATTERNS = 10
LEVEL_ROW_PERIODS = (8, 4, 2)  # the level patterns light one panel row in this many: 1/8, 1/4, 1/2 of white
SWEEP_FRACTION = 0.5  # sweep period, at least this share of the panel width ...
LENSES_PER_VIEW = 16  # ... and long enough that one view spans this many lenses (Delta_r / 3 pixels each) ...
MAX_SWEEP_FRACTION = 1.6  # ... but at most this many panel widths (every sixth of the panel still sees all offsets)
_ROWS_PER_CHUNK = 128


@dataclasses.dataclass(frozen=True)
class CrosstalkPattern:
    """One crosstalk pattern: ``kind`` "black", "white", "band", "half" or "level"; ``shift`` in views;
    ``complement``: light what the pattern would leave dark (the second half pattern);
    ``row_period``: a level pattern lights every subpixel of one panel row in this many."""

    name: str
    kind: str
    shift: float = 0.0
    complement: bool = False
    row_period: int = 0

    @property
    def fraction(self) -> float:
        """The share of white's light (above black) a level pattern sends: 1 / ``row_period``."""
        return 1.0 / self.row_period if self.row_period else math.nan

    @property
    def file(self) -> str:
        return f"{self.name}.png"

    @property
    def group(self) -> str:
        return self.kind

    def to_dict(self) -> dict[str, Any]:
        data = {"name": self.name, "file": self.file, "kind": self.kind, "shift": self.shift,
                "complement": self.complement}
        if self.kind == "level":
            data["row_period"] = self.row_period
        return data


@dataclasses.dataclass(frozen=True)
class CrosstalkPatternSet:
    """All crosstalk patterns for one fitted profile.

    ``sweep``: the sweep period in pixels (the band moves by N views over this many columns).
    """

    profile: PanelProfile
    sweep: float
    patterns: tuple[CrosstalkPattern, ...]

    @property
    def width(self) -> int:
        return self.profile.width

    @property
    def height(self) -> int:
        return self.profile.height

    @property
    def views(self) -> int:
        return self.profile.views

    @property
    def names(self) -> list[str]:
        return [p.name for p in self.patterns]

    @property
    def bands(self) -> list[CrosstalkPattern]:
        return [p for p in self.patterns if p.kind == "band"]

    def group(self, name: str) -> list[CrosstalkPattern]:
        return [p for p in self.patterns if p.group == name]

    def _profile_dict(self) -> dict[str, Any]:
        data = self.profile.to_dict()
        data.pop("provenance", None)  # the manifest's own provenance is enough; the routing is what counts
        return data

    @property
    def set_id(self) -> str:
        body = json.dumps([FORMAT_VERSION, self._profile_dict(), self.sweep, [p.to_dict() for p in self.patterns]],
                          sort_keys=True)
        return hashlib.sha256(body.encode()).hexdigest()[:16]

    def to_dict(self) -> dict[str, Any]:
        virtual_panel = recorded_virtual_panel(self.profile.provenance, "profile")
        return {**DOCUMENT.envelope(), "set_id": self.set_id,
                "width": self.width, "height": self.height, "views": self.views, "sweep_pixels": self.sweep,
                "frame_pixels": frame_width(self.height), "frame_level": FRAME_LEVEL, "encoding": "sRGB",
                "profile": self._profile_dict(), "patterns": [p.to_dict() for p in self.patterns],
                **({} if virtual_panel is None else {"virtual_panel": virtual_panel})}

    def render(self, pattern: CrosstalkPattern) -> np.ndarray:
        """The pattern as the panel shows it: uint8 RGB ``(height, width, 3)``."""
        return render_crosstalk_pattern(self, pattern)


def design_crosstalk_patterns(profile: PanelProfile, sweep: float | None = None,
                              levels: bool = True) -> CrosstalkPatternSet:
    """The crosstalk pattern set for ``profile``: black, white, ``BAND_PATTERNS`` band sweeps, two halves
    and (``levels``) the three level patterns; ``levels=False``: a set as lenticalib drew it before
    the levels (still measured, with the tone curve from the halves alone)."""
    if sweep is None:
        sweep = default_sweep(profile)
    n = profile.views
    patterns = [CrosstalkPattern("black", "black"), CrosstalkPattern("white", "white")]
    patterns += [CrosstalkPattern(f"band-{k:02d}", "band", shift=k * n / BAND_PATTERNS) for k in range(BAND_PATTERNS)]
    patterns += [CrosstalkPattern("half-0", "half"), CrosstalkPattern("half-1", "half", complement=True)]
    if levels:
        patterns += [CrosstalkPattern(f"level-1in{k}", "level", row_period=k) for k in LEVEL_ROW_PERIODS]
    return CrosstalkPatternSet(profile, float(sweep), tuple(patterns))


def default_sweep(profile: PanelProfile) -> float:
    """The default sweep period (pixels): half the panel width, or longer where one view would span
    fewer than ``LENSES_PER_VIEW`` lenses (the lens sheet samples the sweep once per lens and the
    camera blurs it over a pixel or two: a view a few lenses wide comes out measurably broadened,
    8 lenses per view by 0.05-0.08 view, 1 % of a sharp view's own share), up to
    ``MAX_SWEEP_FRACTION`` panel widths (the ten shifts then still put every sixth of the panel,
    a column of the uniformity map, at every offset)."""
    wanted = max(SWEEP_FRACTION * profile.width, LENSES_PER_VIEW * profile.views * profile.period / 3.0)
    return float(min(wanted, MAX_SWEEP_FRACTION * profile.width))


def band_centre(pattern_set: CrosstalkPatternSet, xs: np.ndarray, shift: float) -> np.ndarray:
    """Band centre ``b`` (views) at continuous subpixel indices ``xs`` for a pattern of ``shift`` views."""
    n = pattern_set.views
    return n / 2.0 + shift + n * (np.asarray(xs, np.float64) + 0.5) / (3.0 * pattern_set.sweep)


def lit_subpixels(pattern_set: CrosstalkPatternSet, pattern: CrosstalkPattern, rows: np.ndarray) -> np.ndarray:
    """bool ``(len(rows), 3 W)`` indexed ``[y, x_s]``: which subpixels the pattern lights (frame excluded)."""
    profile = pattern_set.profile
    nsub = profile.subpixels_per_row
    if pattern.kind == "black":
        return np.zeros((len(rows), nsub), dtype=bool)
    if pattern.kind == "white":
        return np.ones((len(rows), nsub), dtype=bool)
    if pattern.kind == "level":
        return np.repeat((np.asarray(rows) % pattern.row_period == 0)[:, None], nsub, axis=1)
    w = view_coordinate(profile, rows)
    return _lit(pattern_set, pattern, w - band_centre(pattern_set, _slot_positions(profile, rows), pattern.shift))


def _slot_positions(profile: PanelProfile, rows: np.ndarray) -> np.ndarray:
    """Continuous index ``x_s + e`` of every slot of ``rows``, float64 ``(len(rows), 3 W)`` (``(1, 3 W)``
    on a stripe panel, where ``e = 0``)."""
    nsub = profile.subpixels_per_row
    positions = np.arange(nsub, dtype=np.float64)[None, :]
    if profile.is_stripe:
        return positions
    return positions + slot_shift_rows(profile, rows)


def _lit(pattern_set: CrosstalkPatternSet, pattern: CrosstalkPattern, relative: np.ndarray) -> np.ndarray:
    """Whether a band or half pattern lights a subpixel of view coordinate ``w`` with ``relative = w - b``."""
    n = pattern_set.views
    if pattern.kind == "band":
        return np.mod(relative + 0.5, n) < 1.0
    lit = np.mod(relative + n / 4.0, n) < n / 2.0
    return ~lit if pattern.complement else lit


def seen_columns(pattern_set: CrosstalkPatternSet, pattern: CrosstalkPattern) -> np.ndarray:
    """bool ``(W,)``: the panel columns where the camera the profile was fitted for sees a lit subpixel.

    That camera sees view ``w = N/2`` everywhere, so a band is seen only where its centre passes
    within half a view of N/2; with a sweep longer than the panel some bands are seen nowhere, and
    their photos show only the other views' crosstalk.  Taken at each pixel's middle subpixel.
    """
    width = pattern_set.width
    if pattern.kind in ("black", "white", "level"):
        return np.full(width, pattern.kind != "black")
    centre = band_centre(pattern_set, 3 * np.arange(width) + 1, pattern.shift)
    return _lit(pattern_set, pattern, pattern_set.views / 2.0 - centre)


def render_crosstalk_pattern(pattern_set: CrosstalkPatternSet, pattern: CrosstalkPattern) -> np.ndarray:
    """uint8 RGB ``(H, W, 3)``: lit subpixels at 255, others 0, inside the registration frame."""
    profile = pattern_set.profile
    h, w = profile.height, profile.width
    image = np.zeros((h, w, 3), dtype=np.uint8)
    rho = profile.rho  # subpixel position of R, G, B
    for start in range(0, h, _ROWS_PER_CHUNK):
        rows = np.arange(start, min(h, start + _ROWS_PER_CHUNK))
        lit = lit_subpixels(pattern_set, pattern, rows)
        for channel in range(3):
            image[rows[0]:rows[-1] + 1, :, channel] = np.where(lit[:, rho[channel]::3], 255, 0)
    f = frame_width(h)
    frame = srgb_encode8(np.float64(FRAME_LEVEL))
    for part in (image[:f], image[-f:], image[:, :f], image[:, -f:]):
        part[...] = frame
    return image


def crosstalk_set_from_manifest(data: dict[str, Any], source: str) -> CrosstalkPatternSet:
    """The crosstalk pattern set a parsed ``patterns.json`` describes; InputError naming ``source``."""
    check_envelope(data, DOCUMENT, source)
    if not isinstance(data.get("profile"), dict):
        raise InputError("field 'profile' is missing", source=source,
                         hint="write the patterns again with 'lenticalib crosstalk patterns'")
    profile = profile_from_dict(data["profile"], source=f"{source} (profile)")
    if data.get("virtual_panel") is not None:  # the virtual panel the profile was fitted on, checked
        recorded_virtual_panel({"virtual_panel": data["virtual_panel"]}, source)
        profile = profile.replace(provenance={"virtual_panel": data["virtual_panel"]})
    sweep = data.get("sweep_pixels")
    if not (isinstance(sweep, (int, float)) and math.isfinite(sweep) and sweep > 0):
        raise InputError("field 'sweep_pixels' is missing or not a positive number", source=source)
    patterns = data.get("patterns")
    levels = isinstance(patterns, list) and any(isinstance(p, dict) and p.get("kind") == "level" for p in patterns)
    expected = design_crosstalk_patterns(profile, float(sweep), levels=levels)
    if not manifest_matches(data, expected):
        raise InputError("describes crosstalk patterns this lenticalib did not draw (edited, or from another "
                         "version)", source=source,
                         hint="write the patterns again with 'lenticalib crosstalk patterns' and photograph them")
    return expected
