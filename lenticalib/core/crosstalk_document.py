"""``crosstalk.json``: the document format and its reader (format, version, the mixing matrix).

``matrix[i][j]`` is the share of the light an eye at the centre of view ``i``'s zone receives
from view ``j`` (N x N, rows sum to 1, black-corrected; ``docs/crosstalk.md`` has every key).
The measurement that writes the document and the figures derived from the matrix live in
:mod:`lenticalib.calib.crosstalk.result`; pre-compensation
(:mod:`lenticalib.render.compensation`) reads only the matrix.
"""

from __future__ import annotations

import os
from typing import Any

import numpy as np

from .errors import InputError
from .fields import is_finite_number
from .documents import FORMATS, check_envelope, read_json_file
from .profile import MAX_VIEWS

DOCUMENT = FORMATS["lenticalib.crosstalk"]
FORMAT_NAME, FORMAT_VERSION = DOCUMENT.name, DOCUMENT.version


def read_crosstalk_document(path: str | os.PathLike, views: int | None = None,
                            source: str | None = None) -> dict[str, Any]:
    """A ``crosstalk.json`` document, checked: format, a square N x N ``matrix`` of numbers whose rows
    sum to 1, ``views`` equal to ``views`` when given, ``eye_separation_views`` a number >= 0 or
    null.  InputError naming ``source`` (default: the file) otherwise.  The rest of the document
    (the figures among it) is returned as it is in the file."""
    source = source or str(path)
    data = read_json_file(path, DOCUMENT.what, DOCUMENT.hint)
    check_envelope(data, DOCUMENT, source)
    n = data.get("views")
    matrix = data.get("matrix")
    if not (isinstance(n, int) and 2 <= n <= MAX_VIEWS):
        raise InputError(f"field 'views' is missing or not a whole number 2..{MAX_VIEWS}", source=source)
    if (not isinstance(matrix, list) or len(matrix) != n
            or any(not isinstance(r, list) or len(r) != n for r in matrix)
            or any(not is_finite_number(v) for r in matrix for v in r)):
        raise InputError(f"field 'matrix' must be {n} rows of {n} numbers", source=source)
    array = np.asarray(matrix, np.float64)
    if np.any(array < -0.05) or np.any(np.abs(array.sum(axis=1) - 1.0) > 0.02):
        raise InputError("field 'matrix' is not a mixing matrix (rows must be shares summing to 1)", source=source)
    if views is not None and n != views:
        raise InputError(f"is for {n} views, the profile has {views}", source=source,
                         hint="measure the crosstalk of this panel with this profile's view count")
    eye = data.get("eye_separation_views")
    if eye is not None and not (is_finite_number(eye) and eye >= 0):
        raise InputError("field 'eye_separation_views' must be a number of views >= 0 or null", source=source)
    return data


def mixing_matrix(document: dict[str, Any]) -> np.ndarray:
    """The checked document's ``matrix`` as float64 ``(N, N)``."""
    return np.asarray(document["matrix"], np.float64)
