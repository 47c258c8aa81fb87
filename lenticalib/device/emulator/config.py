"""How an emulated controller is configured: its panel and firmware generation, as text.

The same spellings serve ``lenticalib emulate`` (``--panel 3840x2160 --subpixel-order RGB
--view-counts 32 --protocol 1.1``) and ``emu://`` URLs (``emu://bench?panel=1920x1080&views=8,16``);
each parser raises ValueError with a message that fits after the option's name.
"""

from __future__ import annotations

from ...core import sizes
from ...core.errors import InputError
from ..protocol import MAX_VIEW_COUNTS, PROTOCOL_MINOR, PROTOCOL_VERSION, PanelGeometry

PROTOCOLS = {"1.0": 0, "1.1": 1}  # spelling -> protocol minor version the firmware speaks


def parse_size(text: str) -> tuple[int, int]:
    """``"3840x2160"`` -> (width, height) in pixels, each 1..:data:`~lenticalib.core.sizes.MAX_SIDE`
    (:func:`lenticalib.core.sizes.parse_size`)."""
    try:
        return sizes.parse_size(text, "panel")
    except InputError as exc:
        raise ValueError(f"{exc.message} ({exc.hint})") from None


def parse_view_counts(text: str) -> tuple[int, ...]:
    """``"16,32"`` -> (16, 32): the view counts N the controller supports, each 2..254."""
    try:
        counts = tuple(sorted({int(part) for part in text.split(",")}))
    except ValueError:
        counts = ()
    if not (1 <= len(counts) <= MAX_VIEW_COUNTS and all(2 <= n <= 254 for n in counts)):
        raise ValueError(f"must be 1 to {MAX_VIEW_COUNTS} view counts in 2..254 separated by commas, "
                         f"e.g. 32 or 16,32, got '{text}'")
    return counts


def parse_order(text: str) -> str:
    if text.upper() not in ("RGB", "BGR"):
        raise ValueError(f"must be RGB or BGR, got '{text}'")
    return text.upper()


def parse_protocol(text: str) -> int:
    """``"1.1"`` -> 1, ``"1.0"`` -> 0: the protocol minor version the emulated firmware speaks."""
    if text not in PROTOCOLS:
        raise ValueError(f"must be {' or '.join(PROTOCOLS)} (the firmware generation to emulate), got '{text}'")
    return PROTOCOLS[text]


def panel_geometry(default: PanelGeometry, size: str | None = None, order: str | None = None,
                   views: str | None = None) -> PanelGeometry:
    """``default`` with the given fields replaced (texts as for the parsers above)."""
    width, height = parse_size(size) if size is not None else (default.width, default.height)
    return PanelGeometry(width, height, parse_order(order) if order is not None else default.subpixel_order,
                         parse_view_counts(views) if views is not None else default.view_counts)


CURRENT_PROTOCOL = f"{PROTOCOL_VERSION}.{PROTOCOL_MINOR}"
