"""Photographing a pattern folder on the virtual panel: a synthetic capture set with its truth.

Layout written into the pattern folder ``DIR`` (the one ``lenticalib patterns`` wrote):

    DIR/captures/NAME.jpg   one camera JPEG per pattern NAME.png (nothing else goes here); with
                            ``raw``: NAME.png, 16-bit linear RGB as a raw converter writes it
    DIR/simulation.json     the scene (every optics and camera parameter), its seed, the
                            per-photo noise seeds, the pattern set id and the lenticalib
                            version: enough to reproduce every photo bit for bit
    DIR/truth.json          the ideal profile for the camera position (provenance "simulation")
    DIR/crosstalk-truth.json  for a crosstalk pattern folder: the true mixing matrix M of the
                            profile the patterns were drawn from, and the true view cone
                            (:mod:`.crosstalk_truth`)

``simulation.json`` is written first with ``"status": "in progress"`` and rewritten with
``"complete"`` at the end, so an interrupted run is recognisable.  A ``captures`` folder that
holds files but no ``simulation.json`` (real photos, presumably) is never written into.

The per-photo step (:func:`photograph_pattern`, :func:`photo_record`) and the two records
(:func:`write_truth`, :func:`write_simulation_record`) are shared with the virtual capture camera
(:mod:`lenticalib.sim.capture_backend`), which photographs what ``lenticalib capture`` shows.
"""

from __future__ import annotations

import datetime as _dt
import os
import zlib
from pathlib import Path
from typing import Any, Callable, Iterable

import numpy as np

from .. import __version__
from ..core.files.atomic import write_bytes_atomic
from ..core.files.documents import FORMATS, write_document
from ..core.errors import InputError
from ..core.files.imageio import read_image
from ..core.pattern_sets import MANIFEST_NAME, read_pattern_folder
from ..core.profile import make_provenance, save_profile
from ..core.sizes import check_raster
from .scene import Scene

SIMULATION_NAME = "simulation.json"
TRUTH_NAME = "truth.json"
CROSSTALK_TRUTH_NAME = "crosstalk-truth.json"
CAPTURE_FOLDER = "captures"


def noise_seed(scene: Scene, pattern_name: str) -> list[int]:
    """The seed of the sensor noise of one photo: ``[scene seed (0 if None), crc32(name)]``."""
    return [int(scene.seed or 0), zlib.crc32(pattern_name.encode("utf-8"))]


def photo_scene(scene: Scene, pattern_name: str) -> tuple[Scene, dict[str, float]]:
    """The scene as photo ``pattern_name`` is taken: the camera's per-photo exposure drift and shake
    (:meth:`.camera.Camera.for_photo`) drawn from ``[*noise_seed, 1]``; returns (scene, the draws)."""
    camera, draws = scene.camera.for_photo(np.random.default_rng([*noise_seed(scene, pattern_name), 1]))
    return (scene if camera is scene.camera else scene.replace_camera(**{
        k: getattr(camera, k) for k in ("exposure", "cx", "cy")})), draws


def photo_record(scene: Scene, pattern_name: str, file: str | None = None, raw: bool = False) -> dict[str, Any]:
    """The ``simulation.json`` entry of photo ``pattern_name``: pattern, file (relative to the pattern
    folder; default ``captures/NAME.jpg``), noise seed and the per-photo camera draws."""
    return {"pattern": pattern_name, "file": file or f"{CAPTURE_FOLDER}/{pattern_name}.{'png' if raw else 'jpg'}",
            "noise_seed": noise_seed(scene, pattern_name), "photo": photo_scene(scene, pattern_name)[1]}


def photograph_pattern(scene: Scene, pattern_name: str, raster: np.ndarray, raw: bool = False) -> bytes:
    """The camera JPEG of the panel of ``scene`` showing ``raster`` as photo ``pattern_name``.

    ``raster`` is uint8 ``(H, W, 3)`` sRGB at the panel's size.  The noise and the per-photo draws
    come from :func:`noise_seed` / :func:`photo_scene`, so the same scene, name and raster give the
    same bytes (what ``simulation.json`` promises).
    """
    from .photo import photograph_jpeg, photograph_raw_png

    rng = np.random.default_rng(noise_seed(scene, pattern_name))
    shoot = photograph_raw_png if raw else photograph_jpeg
    return shoot(raster, photo_scene(scene, pattern_name)[0], rng)


def write_truth(directory: str | os.PathLike, scene: Scene, pattern_set) -> tuple[Path, dict[str, Any]]:
    """Write ``DIR/truth.json``, the ideal profile for the camera position of ``scene``.

    Returns (its path, the constants recorded in ``simulation.json``: views, slant, period, offset,
    reference_view, width, height, subpixel_order, view_direction, and ``subpixel_layout`` (its
    JSON form), ``views_reversed``, ``flip_image_x``/``_y`` when the truth has them).
    """
    directory = Path(directory)
    provenance = make_provenance("simulation", inputs=[directory / MANIFEST_NAME], seed=scene.seed,
                                 simulation=SIMULATION_NAME, camera_position_mm=list(scene.eye))
    profile = scene.truth_profile(pattern_set.views, name="simulation truth", provenance=provenance)
    truth_path = save_profile(profile, directory / TRUTH_NAME)
    if hasattr(pattern_set, "bands"):  # a crosstalk pattern set: its true M too
        write_crosstalk_truth(directory / CROSSTALK_TRUTH_NAME, scene, pattern_set.profile)
    constants = {k: getattr(profile, k) for k in ("views", "slant", "period", "offset", "reference_view",
                                                   "width", "height", "subpixel_order", "view_direction")}
    if profile.subpixel_layout is not None:
        constants["subpixel_layout"] = profile.subpixel_layout.to_dict()
    for key in ("views_reversed", "flip_image_x", "flip_image_y"):
        if getattr(profile, key):
            constants[key] = True
    return truth_path, constants


def write_crosstalk_truth(path: Path, scene: Scene, profile) -> Path:
    """Write the true crosstalk of ``profile`` on the scene's panel, seen from its camera (JSON, atomic)."""
    from .crosstalk_truth import true_mixing_matrix, true_view_cone

    matrix = true_mixing_matrix(scene.optics, scene.eye, profile)
    offsets = np.arange(-4.0, 4.0001, 0.25)
    cone = true_view_cone(scene.optics, scene.eye, profile, offsets)
    document = {"views": profile.views,
                "definition": "matrix[i][j]: share of the light an eye at the centre of view i's zone receives "
                              "from view j, through the centre region, from the camera's viewing position",
                "matrix": [[round(float(v), 8) for v in r] for r in matrix],
                "own_view_share": round(float(matrix[0, 0]), 8),
                "view_cone": {"offsets_views": offsets.tolist(), "share_of_white": [round(float(v), 8) for v in cone]},
                "camera_position_mm": list(scene.eye), "seed": scene.seed}
    return write_document(path, FORMATS["lenticalib.crosstalk-truth"], document)


def write_simulation_record(directory: str | os.PathLike, scene: Scene, pattern_set, status: str,
                            captures: list[dict[str, Any]], truth: dict[str, Any] | None) -> Path:
    """Write ``DIR/simulation.json`` atomically (status "in progress" or "complete"); returns its path."""
    return write_document(Path(directory) / SIMULATION_NAME, FORMATS["lenticalib.simulation-run"],
                          _simulation_record(scene, pattern_set, status, captures, truth))


def _simulation_record(scene: Scene, pattern_set, status: str, captures: list[dict[str, Any]],
                       truth: dict[str, Any] | None) -> dict[str, Any]:
    record: dict[str, Any] = {
        **FORMATS["lenticalib.simulation-run"].envelope(), "status": status,
        "created": _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds"),
        "lenticalib_version": __version__, "seed": scene.seed,
        "pattern_set": {"set_id": pattern_set.set_id, "width": pattern_set.width,
                        "height": pattern_set.height, "views": pattern_set.views},
        "camera_position_mm": list(scene.eye),
        "view_zone_width_mm": scene.optics.view_zone_width(scene.camera.distance, pattern_set.views),
        "scene": scene.to_dict(), "captures": captures,
    }
    if truth is not None:
        record["truth"] = truth
    return record


def simulate_capture_set(pattern_dir: str | os.PathLike, scene: Scene, raw: bool = False,
                         progress: Callable[[Iterable], Iterable] | None = None) -> dict[str, Any]:
    """Photograph every pattern of ``pattern_dir`` on the virtual panel of ``scene``.

    ARGUMENTS
    pattern_dir   folder with ``patterns.json`` and the pattern PNGs
    scene         panel + camera; the panel raster size must equal the pattern set's
    progress      optional wrapper of the pattern iterable (e.g. ``tqdm.tqdm``), called once

    RETURNED VALUE
    dict: ``directory``, ``captures`` (folder), ``photos`` (count), ``truth`` (path of
    truth.json), ``simulation`` (path of simulation.json), ``profile`` (the truth constants),
    ``resolution`` [w, h], ``seed``.

    Raises InputError (file named) for a missing or foreign manifest, a scene of another panel
    size, a captures folder with foreign files, or an unreadable pattern image.
    """
    directory = Path(pattern_dir)
    pattern_set = read_pattern_folder(directory)
    manifest = directory / MANIFEST_NAME
    optics = scene.optics
    if (optics.width, optics.height) != (pattern_set.width, pattern_set.height):
        raise InputError(f"patterns are for a {pattern_set.width}x{pattern_set.height} panel, the scene "
                         f"simulates {optics.width}x{optics.height}", source=str(manifest),
                         hint="simulate a panel of the pattern set's size")
    captures = directory / CAPTURE_FOLDER
    simulation_path = directory / SIMULATION_NAME
    if captures.is_dir() and any(captures.iterdir()) and not simulation_path.exists():
        raise InputError("holds files that the simulator did not write (real photos?)", source=str(captures),
                         hint="simulate into a fresh copy of the pattern folder")
    if captures.exists() and not captures.is_dir():
        raise InputError("is not a folder", source=str(captures))
    try:
        captures.mkdir(exist_ok=True)
    except OSError as exc:
        raise InputError(f"cannot create: {exc.strerror}", source=str(captures),
                         hint="choose a writable pattern folder") from None

    records = [photo_record(scene, p.name, raw=raw) for p in pattern_set.patterns]
    write_simulation_record(directory, scene, pattern_set, "in progress", records, None)

    items: Iterable = pattern_set.patterns if progress is None else progress(pattern_set.patterns)
    for pattern in items:
        source = directory / pattern.file
        raster = read_image(source, expected_size=(optics.width, optics.height), what="the simulated panel")
        raster = check_raster(raster, optics.width, optics.height, str(source), "the simulated panel",
                              hint="write the patterns again with 'lenticalib patterns'")
        write_bytes_atomic(captures / f"{pattern.name}.{'png' if raw else 'jpg'}",
                           photograph_pattern(scene, pattern.name, raster, raw=raw))

    truth_path, constants = write_truth(directory, scene, pattern_set)
    write_simulation_record(directory, scene, pattern_set, "complete", records, {"file": TRUTH_NAME, **constants})
    return {"directory": str(directory), "captures": str(captures), "photos": len(records),
            "truth": str(truth_path), "simulation": str(simulation_path), "profile": constants,
            "resolution": [scene.camera.width, scene.camera.height], "seed": scene.seed}
