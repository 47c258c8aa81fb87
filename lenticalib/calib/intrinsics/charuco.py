"""ChArUco board names and sizes: the ArUco dictionaries a board may use, the marker size.

A ChArUco board (:mod:`.board`, pattern "charuco") names its markers by an OpenCV dictionary,
``DICT_<n>X<n>_<size>``: markers of n x n bits (plus a one-cell black border, so ``n + 2`` cells
across) and ``size`` distinct ids; the board needs one id per white square.  Nothing here
imports OpenCV.
"""

from __future__ import annotations

import re

from ...core.errors import InputError

MARKER_SHARE = 0.6  # ChArUco marker side / square side (0.2 of a square of clean chessboard around a corner)
DICTIONARY_RE = r"DICT_([4-7])X\1_(50|100|250|1000)"
DICTIONARY_EXAMPLE = "DICT_4X4_100"


def check_dictionary(name, markers: int) -> str:
    """``name`` if it is an OpenCV ArUco dictionary (DICT_4X4_50 ... DICT_7X7_1000) that holds
    ``markers`` markers; InputError naming ``dictionary`` otherwise."""
    if not (isinstance(name, str) and re.fullmatch(DICTIONARY_RE, name)):
        raise InputError(f"unknown ArUco dictionary {name!r}", source="dictionary",
                         hint=f"use an OpenCV name DICT_<n>X<n>_<size>, n 4..7, size 50/100/250/1000 "
                              f"(e.g. {DICTIONARY_EXAMPLE})")
    if int(name.rsplit("_", 1)[1]) < markers:
        raise InputError(f"{name} holds {name.rsplit('_', 1)[1]} markers, the board needs {markers}",
                         source="dictionary", hint="use a larger dictionary (e.g. DICT_4X4_250) or fewer squares")
    return name


def default_dictionary(markers: int) -> str:
    """The smallest 4x4 OpenCV dictionary with at least ``markers`` markers (4x4 bits are the
    largest cells, the easiest to read in a small or blurred photo)."""
    for size in (50, 100, 250, 1000):
        if size >= markers:
            return f"DICT_4X4_{size}"
    raise InputError(f"a board of {markers} markers is larger than any ArUco dictionary", source="squares",
                     hint="use fewer squares")


def marker_bits_count(dictionary: str) -> int:
    """Cells across a marker of ``dictionary``, its black border included."""
    return int(dictionary[5]) + 2
