"""``crosstalk.json``: the measured mixing matrix, the figures derived from it, writing, reading and checking.

The document's format and its matrix check: :mod:`lenticalib.core.crosstalk_document`.

Definitions (``docs/crosstalk.md``; :data:`FIGURES` holds them for the document, the check's
messages and the report), for a circulant ``M`` with row ``h = M[i]`` (``h[m]`` the share of the
light an eye at the centre of a view's zone receives from the view ``m`` further on, ``m``
modulo N).  Every crosstalk is leakage over signal (Woods 2012), black-corrected, a ratio (x 100
= %) that exceeds 100 % when the leaking views together are brighter than the view itself:

    own-view share          h[0], a share 0..1
    adjacent crosstalk      (h[1] + h[-1]) / h[0]
    non-adjacent crosstalk  sum_{2 <= |m| <= N/2} h[m] / h[0]
    system crosstalk        (1 - h[0]) / h[0]: all other views over the view's own light, the
                            system crosstalk of IEC 62629 for autostereoscopic displays (key
                            ``total_crosstalk``)
    eye-pair crosstalk      h[e] / h[0], e = the eye separation rounded to whole views (the mean
                            of +e and -e: what each eye of a centred viewer gets of the other's view)
"""

from __future__ import annotations

import json
import math
import os
from pathlib import Path
from typing import Any, Mapping

import numpy as np

from ...core.files.atomic import write_text_atomic
from ...core.crosstalk_document import DOCUMENT, mixing_matrix, read_crosstalk_document
from ...core.files.fields import is_finite_number
from ...core.identity import profile_identity
from .cone import jackknife_sigma


# key in crosstalk.json "figures": (name, what it is, in a few words), and the unit it is quoted in
FIGURES = {
    "own_view_share": ("own-view share", "the share of the light at a view's zone centre that comes from that view",
                       "share"),
    "adjacent_left_share": ("left neighbour's share", "the share of the light from the view one lower", "share"),
    "adjacent_right_share": ("right neighbour's share", "the share of the light from the view one higher", "share"),
    "adjacent_crosstalk": ("adjacent crosstalk", "light from the two neighbouring views over the view's own light",
                           "%"),
    "non_adjacent_crosstalk": ("non-adjacent crosstalk", "light from the views two or more away over the view's own "
                               "light", "%"),
    "total_crosstalk": ("system crosstalk", "light from all other views over the view's own light, IEC 62629's "
                        "system crosstalk", "%"),
    "eye_pair_crosstalk": ("eye-pair crosstalk", "light of the other eye's view over the eye's own view's light",
                           "%"),
}
HEADLINE = ("own_view_share", "adjacent_crosstalk", "non_adjacent_crosstalk", "total_crosstalk", "eye_pair_crosstalk")
OVER_100 = ("a crosstalk above 100 % means the leaking views together send more light than the view itself: normal "
            "for the adjacent and system crosstalk of a multi-view lens sheet whose neighbouring views overlap (smooth "
            "motion parallax); ghosting between the eyes is the eye-pair crosstalk")


def describe_figure(key: str, value: float, sigma: float | None = None, definition: bool = True,
                    plus_minus: str = "+-") -> str:
    """``name (what it is) value [+- sigma]``, in the figure's unit (a share to 4 digits, a crosstalk
    in % to 2); ``definition=False`` leaves out what it is."""
    name, what, unit = FIGURES[key]
    if unit == "%":
        text = f"{100 * value:.2f}%" + (f" {plus_minus} {100 * sigma:.2f}%" if sigma is not None else "")
    else:
        text = f"{value:.4f}" + (f" {plus_minus} {sigma:.4f}" if sigma is not None else "")
    return f"{name} ({what}) {text}" if definition else f"{name} {text}"


def derived_figures(row: np.ndarray, eye_separation: float | None) -> dict[str, float]:
    """The figures above from one row ``h`` (N,) summing to 1 (``eye_separation`` in views, or None)."""
    n = row.size
    own = float(row[0])
    adjacent = float(row[1] + row[-1]) / own if n > 2 else float(row[1]) / own
    rest = float(row.sum() - row[0] - row[1] - (row[-1] if n > 2 else 0.0)) / own
    figures = {"own_view_share": own, "adjacent_left_share": float(row[-1]), "adjacent_right_share": float(row[1]),
               "adjacent_crosstalk": adjacent, "non_adjacent_crosstalk": rest, "total_crosstalk": (1.0 - own) / own}
    if eye_separation is not None:
        e = int(round(eye_separation)) % n
        figures["eye_pair_crosstalk"] = float(row[e] + row[-e]) / (2.0 * own) if e else 1.0
    return figures


def figures_with_sigma(row: np.ndarray, samples: Mapping[str, np.ndarray],
                       eye_separation: float | None, independent: float | None = None) -> dict[str, dict[str, float]]:
    """Each derived figure with its 1-sigma: the block spread and the photometric perturbations
    propagated (the block rows' spread / sqrt(independent) or, where larger, the jackknife over the
    rows with one band photo left out (``samples["photos-left-out"]``, as the row's own sigma has
    it), the perturbed rows' half differences, and each view's own scatter
    (``samples["far-scatter"]``, (N,), independent from view to view)).

    ``independent``: how many of the blocks are independent of each other (the measurement's
    ``diagnostics['independent_strips']``: its column average ties neighbouring strips); None:
    every block."""
    base = derived_figures(row, eye_separation)
    out = {k: {"value": v, "sigma": 0.0} for k, v in base.items()}
    blocks = samples.get("blocks")
    variance = {k: 0.0 for k in base}
    if blocks is not None and len(blocks) > 1:
        values = [derived_figures(b, eye_separation) for b in blocks if np.all(np.isfinite(b))]
        for k in base:
            variance[k] += float(np.var([v[k] for v in values], ddof=1)) / min(independent or len(values),
                                                                                len(values))
    left_out = samples.get("photos-left-out")
    if left_out is not None and len(left_out) > 1:
        values = [derived_figures(r, eye_separation) for r in left_out if np.all(np.isfinite(r))]
        for k in base:
            variance[k] = max(variance[k], float(jackknife_sigma(np.array([v[k] for v in values]))) ** 2)
    for low, high in (("glare-", "glare+"), ("tone-", "tone+"), ("toe-", "toe+"), ("closure-", "closure+"), ("clip-", "clip+"),
                      ("across-", "across+")):
        if low in samples and high in samples:
            a, b = derived_figures(samples[low], eye_separation), derived_figures(samples[high], eye_separation)
            for k in base:
                variance[k] += ((a[k] - b[k]) / 2.0) ** 2
    scatter = samples.get("far-scatter")  # (N,): each view's own 1-sigma, independent of the others' (cone.far_scatter)
    if scatter is not None:
        for m, s in enumerate(np.asarray(scatter, np.float64)):
            if s > 0:
                moved = np.array(row, np.float64)
                moved[m] += s
                changed = derived_figures(moved, eye_separation)
                for k in base:
                    variance[k] += (changed[k] - base[k]) ** 2
    if "tone-other" in samples:  # two tone models blended (measure._blend): the mixture's spread, and the undecided share
        from .tone_choice import blended_sigma

        w = float(samples["tone-weight"][0])
        u = float(samples.get("tone-undecided", np.zeros(1))[0])
        a, b = derived_figures(samples["tone-main"], eye_separation), derived_figures(samples["tone-other"], eye_separation)
        for k in base:
            variance[k] += float(blended_sigma(a[k], 0.0, b[k], 0.0, w, u)) ** 2
    for k in base:
        out[k]["sigma"] = math.sqrt(variance[k])
    return out


def eye_separation_views(millimetres: float, distance: float, cone_angle: float, views: int) -> float:
    """Views between two eyes ``millimetres`` apart at ``distance`` mm from a panel whose N views span
    ``cone_angle`` degrees: one view is ``2 D tan(cone/2) / N`` mm wide there."""
    zone = 2.0 * distance * math.tan(math.radians(cone_angle) / 2.0) / views
    return millimetres / zone


def _r(value: float, digits: int = 6):
    return None if value is None or not math.isfinite(value) else round(float(value), digits)


def region_edges(width: int, height: int, shape: tuple[int, int]) -> dict[str, list[float]]:
    """The uniformity regions' edges in panel pixels: ``columns_panel_x`` (cols + 1), ``rows_panel_y``
    (rows + 1) for a (rows, cols) grid.  The regions divide the panel's outline in the photo evenly,
    so these edges are approximate: the photo's perspective moves them (by a few pixels for a camera
    facing the panel)."""
    rows, cols = shape
    return {"columns_panel_x": [round(width * i / cols, 1) for i in range(cols + 1)],
            "rows_panel_y": [round(height * j / rows, 1) for j in range(rows + 1)]}


def crosstalk_document(measurement, eye_separation: float | None, eye_note: str | None,
                       provenance: Mapping[str, Any]) -> dict[str, Any]:
    """The JSON document of a measurement (see ``docs/crosstalk.md`` for every key)."""
    m = measurement
    n = m.views
    matrix = m.matrix
    sigma = m.row_sigma[(np.arange(n)[None, :] - np.arange(n)[:, None]) % n]
    figures = figures_with_sigma(m.row, m.samples, eye_separation, m.diagnostics.get("independent_strips"))
    per_view = [{"view": i, **{k: _r(v["value"]) for k, v in figures.items()}} for i in range(n)]
    diag = {k: (v.round(6).tolist() if isinstance(v, np.ndarray) else v) for k, v in m.diagnostics.items()}
    return {
        **DOCUMENT.envelope(),
        "views": n, "width": m.profile.width, "height": m.profile.height,
        "definition": "matrix[i][j]: share of the light an eye at the centre of view i's zone receives from view j "
                      "(rows sum to 1, black-corrected), through the panel's centre region",
        "matrix": [[_r(v) for v in r] for r in matrix],
        "matrix_sigma": [[_r(v) for v in r] for r in sigma],
        "circulant_row": [_r(v) for v in m.row], "circulant_row_sigma": [_r(v) for v in m.row_sigma],
        "figures": {k: {"value": _r(v["value"]), "sigma": _r(v["sigma"])} for k, v in figures.items()},
        "figure_definitions": {k: {"name": FIGURES[k][0], "definition": FIGURES[k][1],
                                   "unit": "share 0..1" if FIGURES[k][2] == "share" else
                                   "ratio, leakage over signal (x 100 = %)"} for k in figures},
        "per_view": per_view,
        "eye_separation_views": _r(eye_separation, 4), "eye_separation_note": eye_note,
        "view_cone": {"offsets_views": [_r(v, 5) for v in m.cone_grid], "share": [_r(v) for v in m.cone],
                      "sigma": [_r(v) for v in m.cone_sigma]},
        "uniformity": {"grid": list(m.regions.shape[::-1]), "own_view_share": [[_r(v) for v in r] for r in m.regions],
                       "sigma": [[_r(v) for v in r] for r in m.regions_sigma],
                       "layout": "rows top to bottom, columns left to right, over the panel as photographed",
                       **region_edges(m.profile.width, m.profile.height, m.regions.shape)},
        "photometry": m.photometry, "diagnostics": diag, "warnings": list(m.warnings),
        "profile": {k: v for k, v in m.profile.to_dict().items() if k != "provenance"},
        "profile_id": profile_identity(m.profile),
        "provenance": dict(provenance),
    }


def write_crosstalk(path: str | os.PathLike, document: Mapping[str, Any]) -> Path:
    return write_text_atomic(path, json.dumps(document, indent=2) + "\n")


def read_crosstalk(path: str | os.PathLike, views: int | None = None, source: str | None = None) -> dict[str, Any]:
    """A ``crosstalk.json`` document, checked (:func:`~lenticalib.core.crosstalk_document.read_crosstalk_document`:
    format, the N x N mixing ``matrix``, ``views``), with its ``figures`` derived again from the matrix.
    InputError naming the file otherwise."""
    data = read_crosstalk_document(path, views=views, source=source)
    # the figures are derived again from the checked matrix (its first row: the light from each view
    # offset), so a hand-edited or older 'figures' block can neither break nor bend a check
    stored = data.get("figures") if isinstance(data.get("figures"), dict) else {}
    figures = derived_figures(mixing_matrix(data)[0], data.get("eye_separation_views"))
    data["figures"] = {key: {"value": value, "sigma": _stored_sigma(stored.get(key))} for key, value in figures.items()}
    return data


def _stored_sigma(entry: Any) -> float | None:
    """The 1-sigma a file's figure entry holds, or None when it holds no usable one."""
    sigma = entry.get("sigma") if isinstance(entry, dict) else None
    return float(sigma) if is_finite_number(sigma) and sigma >= 0 else None


def check_crosstalk(data: Mapping[str, Any], max_adjacent: float | None, max_eye_pair: float | None,
                    max_system: float | None = None) -> list[str]:
    """One line per failed limit (empty: pass).  Limits are fractions (0.08 = 8 %).  Each line names
    the figure with its definition (:data:`FIGURES`), and says what a crosstalk above 100 % means."""
    failures = []
    figures = data.get("figures", {})
    for key, limit in (("adjacent_crosstalk", max_adjacent), ("total_crosstalk", max_system),
                       ("eye_pair_crosstalk", max_eye_pair)):
        if limit is None:
            continue
        value = (figures.get(key) or {}).get("value")
        if value is None:
            failures.append(f"{FIGURES[key][0]} was not measured (measure with the viewer's eye separation given)"
                            if key == "eye_pair_crosstalk" else f"{FIGURES[key][0]} is missing from the file")
        elif value > limit:
            line = f"{describe_figure(key, value)} exceeds the limit {100 * limit:.2f}%"
            if key == "eye_pair_crosstalk":
                line += f" (eye separation {data.get('eye_separation_views')} views)"
            if value > 1.0:
                line += f"; {OVER_100}"
            failures.append(line)
    return failures
