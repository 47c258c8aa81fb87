"""The virtual panel as the camera: a full show -> photograph -> fit run without hardware.

A capture camera backend (``--camera sim``), registered by name in :mod:`lenticalib.calib.capture.cameras`.

Spec: ``sim`` or ``sim:SEED``.  Options: ``seed`` (default the spec's, else the folder's, else 1), ``resolution``
camera (w, h) in pixels or ``"WxH"`` (default :data:`lenticalib.sim.scene.DEFAULT_RESOLUTION`, as for
``lenticalib simulate``; the fit needs at least 1 megapixel),
``conditions`` ("standard" or "hard", see :data:`lenticalib.sim.scene.CONDITIONS`),
``subsamples`` (rays per pixel side, default 3), ``layout`` (the panel's subpixel layout: RGB, BGR, a
name of :data:`lenticalib.sim.layouts.NAMED_LAYOUTS` or a JSON layout file; default the seed's stripe),
``folder`` (the pattern folder it will photograph: the virtual panel is then chosen, checked and
named by :meth:`settings` when the camera opens, before any pattern is shown).  ``timeout`` is
accepted like every kind's and has nothing to bound: the virtual camera never waits.

Which virtual panel (:func:`choose_virtual_panel`, ``docs/identity.md``): for calibration patterns,
the seed given, else that of the folder's earlier photos (its ``simulation.json``, with their
layout: an interrupted ``sim:3`` capture resumes on panel 3), else seed 1.  For patterns drawn from a profile (crosstalk patterns), the virtual panel that profile
was fitted on, as its fit recorded it (the calibration folder's ``simulation.json``, carried in the
profile's provenance and the patterns' manifest): ``sim`` photographs that panel, with its subpixel
layout, and checks that it is the one the fit photographed (the same truth); ``sim:SEED`` of another
seed is refused, and so is ``sim`` for a profile that names no virtual panel (the camera cannot tell
which panel to photograph).

Each :meth:`capture` photographs the raster the panel shows (``shown``) with the simulator
(:func:`lenticalib.sim.capture.photograph_pattern`: the same bytes ``lenticalib simulate``
writes for that scene, pattern name and raster).  The scene, panel and camera, is drawn by
:func:`lenticalib.sim.scene.random_scene` from the seed for the panel size of the first shown
raster, which must match the pattern set's ``patterns.json`` in the capture set folder
``DIR = destination.parent.parent``.  After every photo (and on :meth:`close`) the camera writes
``DIR/truth.json`` and ``DIR/simulation.json`` as ``simulate`` does, listing the photos of the set's
patterns taken so far (a photo under another name, such as the capture's repeat of its first
pattern ``NAME.repeat``, is taken with that name's own noise and not listed); the status is
"complete" once every pattern of the set has been photographed, "in progress" before.

Resuming: when ``DIR/simulation.json`` already describes the *same* scene (same seed, resolution,
conditions and subsamples, same pattern set), its entries whose photos are still in place are
kept, so a capture that goes on where it stopped ends "complete".  Photos of another scene are
never listed: a folder mixing two scenes stays "in progress" until every pattern is photographed
again.  What else is in ``DIR/captures`` is the caller's business.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np

from ..calib.capture.cameras.base import CaptureCamera
from ..calib.capture.cameras.files import write_photo
from ..calib.patterns.capture_sets import MIN_PHOTO_PIXELS
from ..core.files.documents import FORMATS, read_document
from ..core.errors import CameraError, InputError
from ..core.pattern_sets import MANIFEST_NAME, read_pattern_folder
from ..core.sizes import MIN_CAMERA_SIDE, check_raster, parse_size
from ..core.identity import describe_truth, profile_identity, recorded_virtual_panel
from ..core.layout import layout_from_dict
from .layouts import resolve_layout
from .scene import DEFAULT_RESOLUTION

DEFAULT_SEED = 1
DEFAULT_SUBSAMPLES = 3


@dataclasses.dataclass(frozen=True)
class VirtualPanel:
    """The virtual panel a capture photographs: ``seed``, ``why`` it is that one (for the line naming
    it), and the ``record`` of the fit it must match (:func:`~lenticalib.core.identity.recorded_virtual_panel`:
    its ``truth`` constants and ``truth_id``), or None when nothing is recorded."""

    seed: int
    why: str
    record: dict | None = None


def choose_virtual_panel(pattern_set, seed: int | None, source: str, earlier: dict | None = None) -> VirtualPanel:
    """The virtual panel to photograph ``pattern_set`` on (module docstring); ``seed``: the one the
    spec or options give, or None; ``earlier``: the folder's own ``simulation.json`` of this pattern
    set (an earlier or interrupted capture), or None.  InputError naming ``source`` (the manifest)
    when the seed contradicts the panel the patterns' profile was fitted on, or when none is given
    and the profile names none."""
    profile = getattr(pattern_set, "profile", None)
    if profile is None:  # calibration patterns: the folder's own panel, if it has photos of one
        if seed is None and earlier is not None:
            return VirtualPanel(earlier["seed"], "the panel of this folder's earlier photos, its simulation.json",
                                {"seed": earlier["seed"], "truth": earlier.get("truth")})
        return VirtualPanel(DEFAULT_SEED if seed is None else seed, "the default" if seed is None else "as given")
    record = recorded_virtual_panel(profile.provenance, source)
    if record is None:
        if seed is None:
            raise InputError("the patterns' profile names no virtual panel (a real panel's, or written by hand): "
                             "the virtual camera cannot tell which panel to photograph", source=source,
                             hint="give the seed of the virtual panel the profile is from, sim:SEED")
        return VirtualPanel(seed, "as given; the patterns' profile names no virtual panel")
    if seed is not None and seed != record["seed"]:
        raise InputError(f"the patterns were drawn from a profile of virtual panel seed {record['seed']}; sim:{seed} "
                         "would photograph another panel", source=source,
                         hint=f"photograph the panel the profile is from: sim or sim:{record['seed']}")
    where = record.get("capture_folder")
    return VirtualPanel(record["seed"], "the panel the patterns' profile was fitted on"
                        + (f", photographed in {where}" if where else ""), record)


def parse_resolution(value) -> tuple[int, int]:
    """``(w, h)`` or ``"WxH"`` -> (w, h) camera pixels, each :data:`~lenticalib.core.sizes.MIN_CAMERA_SIDE`..
    :data:`~lenticalib.core.sizes.MAX_SIDE`; InputError naming the camera otherwise."""
    return parse_size(value, "camera sim", MIN_CAMERA_SIDE, example="4000x3000")


class SimCamera(CaptureCamera):
    """A simulated camera in front of a simulated panel (see the module docstring)."""

    kind = "sim"
    OPTIONS = ("seed", "resolution", "conditions", "subsamples", "layout", "folder")

    def __init__(self, target: str | None = None, **options):
        super().__init__(target, **options)
        from .scene import CONDITIONS

        seed = self.options.get("seed")
        if target is not None:
            if not target.strip().isdigit():
                raise InputError(f"bad seed {target!r}", source="camera",
                                 hint="give the simulation seed as a whole number, e.g. sim:7")
            if seed is not None and seed != int(target):
                raise InputError(f"seed {seed!r} contradicts the spec {self.spec!r}", source="camera")
            seed = int(target)
        if seed is not None and (not isinstance(seed, int) or isinstance(seed, bool) or not 0 <= seed < 2 ** 63):
            raise InputError(f"bad seed {seed!r}", source="camera sim", hint="use a whole number 0..2^63-1")
        self.given_seed = seed
        self.seed = DEFAULT_SEED if seed is None else seed
        self.resolution = parse_resolution(self.options.get("resolution", DEFAULT_RESOLUTION))
        self.conditions = self.options.get("conditions", "standard")
        if self.conditions not in CONDITIONS:
            raise InputError(f"unknown conditions {self.conditions!r}", source="camera sim",
                             hint="choose one of " + ", ".join(CONDITIONS))
        self.subsamples = self.options.get("subsamples", DEFAULT_SUBSAMPLES)
        if not isinstance(self.subsamples, int) or isinstance(self.subsamples, bool) or not 1 <= self.subsamples <= 16:
            raise InputError(f"option 'subsamples' must be 1..16, got {self.subsamples!r}", source="camera sim")
        layout = self.options.get("layout")
        if layout is not None and not isinstance(layout, str):
            raise InputError(f"option 'layout' must be a name or a JSON file, got {layout!r}", source="camera sim")
        self.layout_spec = layout
        self.order, self.layout = (None, None) if layout is None else resolve_layout(layout, "layout")
        self.scene = None
        self.panel: VirtualPanel | None = None
        self.directory: Path | None = None
        self.pattern_set = None
        self._records: dict[str, dict] = {}
        self._truth: dict | None = None
        if self.options.get("folder") is not None:  # the panel chosen and checked before anything opens
            self._prepare(Path(self.options["folder"]))

    def _open(self) -> list[str]:
        width, height = self.resolution
        lines = [f"virtual camera: seed {self.seed}, {width}x{height} pixels, {self.subsamples}x{self.subsamples} "
                 f"rays per pixel, conditions {self.conditions}"
                 + ("" if self.scene is not None else "; the scene is drawn for the panel size of the first pattern "
                    "shown"),
                 "exposure, focus, white balance: fixed by the simulated scene"]
        if self.scene is not None:
            lines.insert(0, self.panel_line())
        if width * height < MIN_PHOTO_PIXELS:
            lines.append(f"resolution: {width}x{height} is below the {MIN_PHOTO_PIXELS / 1e6:g} megapixel "
                         "'lenticalib fit' needs; these photos are for tests only")
        return lines

    def panel_line(self) -> str:
        """One line naming the virtual panel photographed: seed, why, and its truth (period, slant,
        order or layout, identity).  Empty before the scene is drawn."""
        if self.scene is None:
            return ""
        truth = self.scene.truth_profile(self.pattern_set.views)
        return (f"virtual panel: seed {self.seed} ({self.panel.why}): truth {describe_truth(truth.to_dict())}, "
                f"{profile_identity(truth)}")

    def _prepare(self, directory: Path) -> None:
        """Read the pattern set of ``directory``, choose the virtual panel (:func:`choose_virtual_panel`)
        and draw its scene for the set's panel size; InputError when the panel the patterns' profile
        was fitted on cannot be photographed again (another seed, or another truth)."""
        from .scene import random_scene

        source = str(directory / MANIFEST_NAME)
        pattern_set = read_pattern_folder(directory)
        panel = choose_virtual_panel(pattern_set, self.given_seed, source, self._folder_record(directory, pattern_set))
        order, layout = self.order, self.layout
        truth = (panel.record or {}).get("truth")
        if self.layout_spec is None and isinstance(truth, dict):  # the fitted panel's own layout
            if truth.get("subpixel_layout") is not None:
                order, layout = None, layout_from_dict(truth["subpixel_layout"], f"{source} (virtual_panel)")
            elif truth.get("subpixel_order") in ("RGB", "BGR"):
                order = truth["subpixel_order"]
        scene = random_scene(panel.seed, width=pattern_set.width, height=pattern_set.height,
                             resolution=self.resolution, conditions=self.conditions, subsamples=self.subsamples,
                             order=order, layout=layout)
        recorded = (panel.record or {}).get("truth_id")
        drawn = profile_identity(scene.truth_profile(pattern_set.views))
        if recorded is not None and drawn != recorded:
            raise InputError(f"seed {panel.seed} now draws a virtual panel of truth {drawn}, the profile was fitted "
                             f"on truth {recorded}", source=source,
                             hint="photograph with the calibration capture's layout: leave out `layout` or give the same")
        self.seed, self.panel, self.scene = panel.seed, panel, scene
        self.directory, self.pattern_set = directory, pattern_set
        self._records = self._earlier_records()

    def _start(self, shown: np.ndarray, directory: Path) -> None:
        """Draw the scene for the pattern set of ``directory`` (:meth:`_prepare`), checking the shown size."""
        pattern_set = read_pattern_folder(directory)
        check_raster(shown, pattern_set.width, pattern_set.height, str(directory / MANIFEST_NAME),
                     "the pattern set's panel", hint="show the patterns of this folder")
        self._prepare(directory)

    @staticmethod
    def _folder_record(directory: Path, pattern_set) -> dict | None:
        """``DIR/simulation.json`` when it records a seed for this very pattern set, else None."""
        from .capture import SIMULATION_NAME

        try:
            record = read_document(directory / SIMULATION_NAME, FORMATS["lenticalib.simulation-run"])
        except (OSError, InputError):
            return None
        same = isinstance(record.get("pattern_set"), dict) and record["pattern_set"].get("set_id") == pattern_set.set_id
        seed = record.get("seed")
        ok = same and isinstance(seed, int) and not isinstance(seed, bool) and 0 <= seed < 2 ** 63
        return record if ok and isinstance(record.get("truth"), (dict, type(None))) else None

    def _earlier_records(self) -> dict[str, dict]:
        """The entries of an existing ``simulation.json`` of this very scene and pattern set whose
        photos are still there (a resumed capture); empty otherwise."""
        from .capture import SIMULATION_NAME
        from .scene import Scene

        try:
            record = read_document(self.directory / SIMULATION_NAME, FORMATS["lenticalib.simulation-run"])
            same = (Scene.from_dict(record) == self.scene
                    and record["pattern_set"]["set_id"] == self.pattern_set.set_id)
            entries = [c for c in record["captures"] if isinstance(c, dict)]
        except (OSError, ValueError, KeyError, TypeError, InputError):  # none, or not ours: start afresh
            return {}
        if not same:
            return {}
        names = set(self.pattern_set.names)
        return {c["pattern"]: c for c in entries if c.get("pattern") in names
                and isinstance(c.get("file"), str) and (self.directory / c["file"]).is_file()}

    def _capture(self, name, shown, destination: Path) -> Path:
        from .capture import photo_record, photograph_pattern, write_truth

        if shown is None:
            raise CameraError("the virtual camera photographs the shown raster, and none was given",
                              source=self.spec, hint="pass the pattern image shown on the panel")
        directory = destination.parent.parent
        if self.scene is None:
            self._start(shown, directory)
        if directory.resolve() != self.directory.resolve():
            raise InputError(f"this virtual camera already photographs {self.directory}", source=str(destination),
                             hint="open another camera for another capture set")
        optics = self.scene.optics
        shown = check_raster(shown, optics.width, optics.height, "shown", "the simulated panel",
                             hint="show every pattern at the panel size")
        path = write_photo(photograph_pattern(self.scene, name, np.ascontiguousarray(shown)), destination, ".jpg")
        if name in self.pattern_set.names:
            self._records[name] = photo_record(self.scene, name, path.relative_to(directory).as_posix())
        if self._truth is None:
            from .capture import TRUTH_NAME

            _, constants = write_truth(directory, self.scene, self.pattern_set)
            self._truth = {"file": TRUTH_NAME, **constants}
        self._write_record()
        return path

    def _write_record(self) -> None:
        from .capture import write_simulation_record

        complete = set(self.pattern_set.names) <= set(self._records)
        write_simulation_record(self.directory, self.scene, self.pattern_set,
                                "complete" if complete else "in progress", list(self._records.values()), self._truth)

    def _close(self) -> None:
        if self.scene is not None and self._records:
            self._write_record()
