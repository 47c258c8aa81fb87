"""``crosstalk.json``: the document format and its reader (format, version, the mixing matrix).

``matrix[i][j]`` is the share of the light an eye at the centre of view ``i``'s zone receives
from view ``j`` (N x N, rows sum to 1, black-corrected; ``docs/crosstalk.md`` has every key).
The measurement that writes the document and the figures derived from the matrix live in
:mod:`lenticalib.calib.crosstalk.result`; pre-compensation
(:mod:`lenticalib.render.compose.compensation`) reads only the matrix.
"""

from __future__ import annotations

import os
from typing import Any

import numpy as np

from .errors import InputError
from .files.fields import is_finite_number
from .files.documents import FORMATS, check_envelope, read_json_file
from .identity import identity_of_record, is_identity
from .profile import MAX_VIEWS

DOCUMENT = FORMATS["lenticalib.crosstalk"]
FORMAT_NAME, FORMAT_VERSION = DOCUMENT.name, DOCUMENT.version


def read_crosstalk_document(path: str | os.PathLike, views: int | None = None,
                            source: str | None = None) -> dict[str, Any]:
    """A ``crosstalk.json`` document, checked: format, a square N x N ``matrix`` of numbers whose rows
    sum to 1, ``views`` equal to ``views`` when given, ``eye_separation_views`` a number >= 0 or
    null.  InputError naming ``source`` (default: the file) otherwise.  The rest of the document
    (the figures among it) is returned as it is in the file.  The panel it was measured for:
    :func:`measured_for`."""
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


def measured_for(document: dict[str, Any], source: str) -> str | None:
    """The identity (:mod:`lenticalib.core.identity`) of the panel profile a checked document was
    measured for: that of its ``profile`` constants (``crosstalk measure`` writes them, and
    ``profile_id`` since identities exist), else its ``profile_id``; None when it records neither
    (a hand-written file).  InputError naming ``source`` for constants that are not a profile, an
    identity that is not one, or the two disagreeing (an edited file)."""
    recorded = document.get("profile_id")
    if recorded is not None and not is_identity(recorded):
        raise InputError(f"field 'profile_id' is not a panel identity (p- and 16 hex digits), got {recorded!r:.40}",
                         source=source, hint="measure the crosstalk again with 'lenticalib crosstalk measure'")
    if document.get("profile") is None:
        return recorded
    derived = identity_of_record(document["profile"], source)
    if recorded is not None and recorded != derived:
        raise InputError(f"field 'profile_id' {recorded} is not the identity of its field 'profile' ({derived}): "
                         "an edited file", source=source,
                         hint="measure the crosstalk again with 'lenticalib crosstalk measure'")
    return derived
