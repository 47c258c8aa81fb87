"""Looking Glass models and the quilt Looking Glass's own software renders for each.

A unit's ``visual.json`` does not say how many views its content has: Looking Glass's software
takes the quilt from the model, and the model from the calibration's ``serial``, by its prefix
(``LKG-P03996``: a Portrait).  :data:`QUILT_MODELS` is that table, transcribed from
Looking-Glass/looking-glass-webxr, ``src/LookingGlassConfig.ts`` at b44ed27 (the merge of its
``feat/spatial-display-support`` branch, July 2024): the getters ``quiltResolution`` (the quilt's
size in pixels), ``quiltWidth`` (columns) and ``quiltHeight`` (rows), each a ``switch`` on
``serial.startsWith(...)`` in the order kept here.  A serial none of the prefixes starts
(their ``default``: a 4096 x 4096 quilt of 1 x 1, i.e. no model) gives None here.

A quilt of ``columns x rows`` tiles holds ``columns * rows`` views, view 0 bottom left; one
tile is ``quilt_width / columns`` by ``quilt_height / rows`` pixels (their ``tileWidth`` and
``tileHeight``, rounded).  Where to use it: :mod:`lenticalib.core.view_defaults`
(view size, view count and camera arc of a render for a profile) and ``docs/looking-glass-devices.md``
("Models and their quilts").
"""

from __future__ import annotations

import dataclasses
from typing import Any, Mapping

SOURCE = ("Looking-Glass/looking-glass-webxr src/LookingGlassConfig.ts at b44ed27 "
          "(quiltResolution, quiltWidth, quiltHeight)")
"""Where :data:`QUILT_MODELS` comes from."""


@dataclasses.dataclass(frozen=True)
class QuiltModel:
    """One Looking Glass model: its serial ``prefix``, ``name``, and the quilt Looking Glass
    renders for it: ``quilt_width`` x ``quilt_height`` pixels in ``columns`` x ``rows`` tiles."""

    prefix: str
    name: str
    quilt_width: int
    quilt_height: int
    columns: int
    rows: int

    @property
    def views(self) -> int:
        """The quilt's view count, ``columns * rows`` (their ``numViews``)."""
        return self.columns * self.rows

    @property
    def tile_size(self) -> tuple[int, int]:
        """(width, height) of one tile in pixels, rounded as their ``tileWidth``/``tileHeight``."""
        return round(self.quilt_width / self.columns), round(self.quilt_height / self.rows)


QUILT_MODELS: tuple[QuiltModel, ...] = (
    QuiltModel("LKG-2K", 'Looking Glass 8.9" (first generation)', 4096, 4096, 5, 9),
    QuiltModel("LKG-4K", 'Looking Glass 15.6" (first generation)', 4096, 4096, 5, 9),
    QuiltModel("LKG-8K", 'Looking Glass 32" (first generation)', 8192, 8192, 5, 9),
    QuiltModel("LKG-P", "Looking Glass Portrait", 3360, 3360, 8, 6),
    QuiltModel("LKG-A", 'Looking Glass 16" (second generation)', 4096, 4096, 5, 9),
    QuiltModel("LKG-B", 'Looking Glass 32" (second generation)', 8192, 8192, 5, 9),
    QuiltModel("LKG-D", 'Looking Glass 65"', 8192, 8192, 8, 9),
    QuiltModel("LKG-F", "Looking Glass Kiosk", 3360, 3360, 8, 6),
    QuiltModel("LKG-E", "Looking Glass Go", 4092, 4092, 11, 6),
    QuiltModel("LKG-H", 'Looking Glass 16" Spatial OLED, portrait (gen3)', 5995, 6000, 11, 6),
    QuiltModel("LKG-J", 'Looking Glass 16" Spatial OLED, landscape (gen3)', 5999, 5999, 7, 7),
    QuiltModel("LKG-K", 'Looking Glass 32" Spatial Display, portrait (gen3)', 8184, 8184, 11, 6),
    QuiltModel("LKG-L", 'Looking Glass 32" Spatial Display, landscape (gen3)', 8190, 8190, 7, 7),
)
"""Every model Looking Glass's software knows, in the order it tries the prefixes."""


def model_for_serial(serial: Any) -> QuiltModel | None:
    """The model whose prefix ``serial`` (a calibration's ``serial`` string) starts with, tried in
    :data:`QUILT_MODELS`' order as Looking Glass does; None for anything else (not a string, or a
    serial of no model in the table)."""
    if not isinstance(serial, str):
        return None
    return next((model for model in QUILT_MODELS if serial.startswith(model.prefix)), None)


def model_of(looking_glass: Mapping[str, Any] | None) -> QuiltModel | None:
    """The model of a profile's ``looking_glass`` block (the fields import kept: ``serial`` ...),
    None when there is no block or its serial names no model."""
    return model_for_serial(looking_glass.get("serial")) if looking_glass else None
