"""``lenticalib crosstalk measure``: the mixing matrix and the view cone from photos of the crosstalk patterns.

Frames: photo pixels -> working pixels (the photo area-averaged by ``factor``); view offsets in
views.  The method is in ``docs/crosstalk.md``; in short:

1. photos -> linear light (camera JPEGs through the camera's tone curve, measured on the black,
   white and half photos (:mod:`.tone`); ``linear`` for 16-bit linear photos from RAW),
   summed over R, G, B and area-averaged to working pixels; every photo registered to white
   on the panel's outline (:mod:`lenticalib.calib.patterns.register`), the black photo subtracted, the
   camera's veiling glare measured outside the panel and removed (:mod:`.photometry`);
2. each band photo divided by white: ``r_k(p)``, the share of white's light that reaches the
   camera from a one-view band ``delta(p) + c_k`` views away;
3. the view cone ``h(t)`` with ``delta(p)`` and the photos' exposures fitted to all ``r_k``
   (:mod:`.cone`); ``h`` of the centre region at integer offsets, normalised, is the row of the
   circulant ``M``;
4. uncertainties: the spread between 16 strips of rows of the centre region (noise, moire, local
   non-uniformity; a robust spread) or, where larger, the jackknife over the band photos (what
   differs from photo to photo: :func:`.cone.photo_jackknife`), a quarter of the difference between its left and right halves
   (the cone's change across it, ``ACROSS_SHARE``) and, in quadrature, what the photometric assumptions could
   move: the glare's size (+-30 %), the tone curve (a power ``1 +- d`` on the linearised light:
   ``d`` the measured curve's own 1-sigma for camera JPEGs, 0.05 where it could not be measured
   (cameras are sRGB only to about +-8 %); 0.005 for linear photos), the light of the codes just
   above black (the tone curve's toe, :func:`.tone._toe_sigma`: a relative change fading out by
   ``ratios.TOE_END`` of white's light), a camera JPEG's noise sigma where the sensor clips it at
   black (read from the black photo's coarse detail, :func:`.dark.block_noise`: the photos unclipped
   with ``dark.SIGMA_RANGE`` times it, half the row's change between the two carried,
   :func:`.dark.reclipped`), the far views' scatter about a
   smooth cone (:func:`.cone.far_scatter`), the dark floor every entry sits on and, for camera
   JPEGs, the whole change of the row when the toe is set so that the band photos' light adds up
   to white's (the light's closure, :mod:`.closure`).
"""

from __future__ import annotations

import dataclasses
import math
import os
import time
from pathlib import Path
from typing import Any, Callable

import numpy as np

from ...core.errors import CaptureError, InputError
from ...core.pattern_sets import MANIFEST_NAME, read_pattern_folder
from ...core.profile import PanelProfile
from . import closure, cone, dark, photometry
from .band_check import check_bands
from .checks import routing_diagnostics
from .photos import MAX_CLIPPED, check_encoding, load_all, measure_tone, panel_mask, register_photos
from ..patterns.crosstalk_patterns import CrosstalkPatternSet
from .ratios import CENTRE_FRACTION, band_ratios, bounding_box, centre_region

CENTRE_DEGREE = 3  # of the centre region's own sweep model
SWEEP_BLUR_PIXELS = 1.5  # working pixels: the camera's blur of the sweep (defocus, demosaicing, averaging)
REGION_GRID = (6, 4)  # columns x rows of the uniformity map
BLOCKS = 16  # the centre region is split into this many strips of rows for the statistical spread
GLARE_RELATIVE_SIGMA = 0.3
TONE_FLOOR = 0.05  # 1-sigma of the power on sRGB-decoded light where the tone curve could not be measured
LINEAR_TONE_SIGMA = 0.005  # the same for linear photos (sensor non-linearity)
PHOTO_MODES = ("srgb", "linear")
FLOOR_SIGMA = 0.0002  # 1-sigma of every matrix entry's dark floor (black subtraction, flare) ...
FLOOR_GLARE_SHARE = 0.2  # ... plus this share of the glare fraction, spread over the N views
ACROSS_SHARE = 0.25  # of the difference between the centre region's left and right halves: the cone's change across it


@dataclasses.dataclass
class Measurement:
    """Everything ``crosstalk.json`` and the report need.

    ``row``: (N,) the centre region's h at offsets 0..N-1 (sums to 1); ``row_sigma``: (N,)
    1-sigma.  ``cone_grid``/``cone``/``cone_sigma``: the view cone on a 1/16-view grid (share of
    the light at an eye from one view, same normalisation).  ``regions``: own-view share per
    region, (rows, cols), with ``regions_sigma``; ``region_boxes``: working-pixel boxes.
    """

    views: int
    row: np.ndarray
    row_sigma: np.ndarray
    cone_grid: np.ndarray
    cone: np.ndarray
    cone_sigma: np.ndarray
    regions: np.ndarray
    regions_sigma: np.ndarray
    samples: dict[str, np.ndarray]  # label -> (N,) rows of the perturbed / block evaluations ("far-scatter": a sigma per view)
    photometry: dict[str, Any]
    diagnostics: dict[str, Any]
    warnings: list[str]
    inputs: list[Path]
    profile: PanelProfile
    pattern_set: CrosstalkPatternSet
    seconds: float
    images: dict[str, np.ndarray] = dataclasses.field(default_factory=dict)  # for the report

    @property
    def matrix(self) -> np.ndarray:
        """M (N, N): M[i][j] = row[(j - i) mod N]."""
        n = self.views
        return self.row[(np.arange(n)[None, :] - np.arange(n)[:, None]) % n]


def open_crosstalk_set(directory: str | os.PathLike, profile: PanelProfile | None = None,
                       profile_source: str = "profile"):
    """(pattern set, capture set) of a crosstalk folder; InputError/CaptureError naming the fault."""
    from ..patterns.capture_sets import match_captures
    from ..patterns.calibration_patterns import PatternSet

    directory = Path(directory)
    if not directory.is_dir():
        raise CaptureError("is not a folder", source=str(directory),
                           hint="give the folder 'lenticalib crosstalk patterns' wrote, with the photos in captures/")
    pattern_set = read_pattern_folder(directory)
    if isinstance(pattern_set, PatternSet):
        raise InputError("holds calibration patterns, not crosstalk patterns", source=str(directory / MANIFEST_NAME),
                         hint="fit them with 'lenticalib fit'; write crosstalk patterns with "
                              "'lenticalib crosstalk patterns --profile P -o DIR'")
    if profile is not None:
        drawn = pattern_set.profile
        if (profile.width, profile.height, profile.views) != (drawn.width, drawn.height, drawn.views):
            raise InputError(f"is for a {profile.width}x{profile.height} panel with {profile.views} views, the "
                             f"patterns for {drawn.width}x{drawn.height} with {drawn.views}", source=profile_source,
                             hint="give the profile the crosstalk patterns were drawn from")
        if profile.routing_key() != drawn.routing_key():
            raise InputError("is not the profile the crosstalk patterns were drawn from", source=profile_source,
                             hint=f"give that profile, or write the patterns again from this one with "
                                  f"'lenticalib crosstalk patterns --profile {profile_source}'")
    return pattern_set, match_captures(directory, pattern_set)


def _row_from(fit, ratios, rows, cols, shifts, views) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(row (N,), cone (B,), counts (B,)) of the samples given, normalised so the row sums to 1."""
    grid, profile, counts = cone.profile_for(fit, ratios, rows, cols, shifts)
    row = cone.values_at_integers(grid, profile, counts, views)
    total = float(row.sum())
    if not total > 0:
        return np.full(views, np.nan), np.full(grid.size, np.nan), counts
    return row / total, profile / total, counts


def measure_crosstalk(directory: str | os.PathLike, profile: PanelProfile | None = None, *,
                      photos: str = "srgb", profile_source: str = "profile",
                      progress: Callable[[str], None] | None = None, force: bool = False) -> Measurement:
    """Measure the crosstalk of the panel from the photos in ``DIR/captures``.

    ARGUMENTS
    directory   folder from ``lenticalib crosstalk patterns`` with ``captures/``
    profile     optional: must be the profile the patterns were drawn from
    photos      "srgb" (JPEG or 8/16-bit sRGB-encoded) or "linear" (16-bit linear from RAW)
    force       measure photos that do not follow the profile's routing (:func:`.checks.check_routing`)
                anyway, with a warning, instead of refusing them

    Raises InputError / CaptureError (one line, naming the file) for every problem with the
    inputs, before the long work where possible.
    """
    start = time.perf_counter()
    if photos not in PHOTO_MODES:
        raise InputError(f"unknown photo encoding {photos!r}", source="photos", hint="use srgb or linear")
    pattern_set, capture = open_crosstalk_set(directory, profile, profile_source)
    warnings: list[str] = []
    curve = measure_tone(capture, warnings) if photos == "srgb" else None
    measured = _measure_linearised(capture, pattern_set, profile, photos, curve, warnings, progress, start, force)
    undecided = 0.0 if curve is None else curve.undecided()
    if curve is not None and curve.alternative is not None and (curve.alternative_weight > 0 or undecided > 0):
        # between the tone models (tone_choice): the other one measured too, the two blended, and
        # half their difference in the uncertainty where the photos leave the choice open
        other = _measure_linearised(capture, pattern_set, profile, photos, curve.alternative, [], progress, start,
                                    force=True)  # judged on the main pass
        measured = _blend(measured, other, curve.alternative_weight, undecided)
    return measured


def _measure_linearised(capture, pattern_set, profile, photos, curve, warnings, progress, start,
                        force=False) -> Measurement:
    """Steps 1-4 of the module docstring with the photos linearised through ``curve`` (None: plain
    sRGB decoding, or linear photos)."""
    from ..patterns.calibration_patterns import FRAME_FRACTION

    luma, clipped, factor, noise = load_all(capture, pattern_set, photos, progress, None if curve is None else curve.lut())
    white_path = capture.photo("white")
    lit0 = luma["white"] - luma["black"]
    mask = panel_mask(lit0, white_path)
    check_encoding(luma, mask, photos, capture)
    clip_fraction = float(clipped[mask].mean())
    if clip_fraction > MAX_CLIPPED:
        raise CaptureError(f"is overexposed: {100 * clip_fraction:.0f}% of the panel is clipped", source=str(white_path),
                           hint="lower the exposure until white is not pure white, lock it, and retake every photo")
    shifts = register_photos(luma, pattern_set.names, capture.photos, lit0, FRAME_FRACTION, warnings)
    column_average, routing = check_bands(luma, mask, pattern_set, capture, warnings, force)
    if progress:
        progress("band photos checked")
    if progress:
        progress("photometry")
    return _analyse(luma, mask, pattern_set, capture, profile or pattern_set.profile, warnings, shifts,
                    curve, photos, factor, start, progress, column_average, noise, routing)


def _blend(main: Measurement, other: Measurement, weight: float, undecided: float = 0.0) -> Measurement:
    """``main`` with ``other`` (the same photos through the other tone model) blended in at
    ``weight``: the row, the cone and the uniformity map, their sigmas as a mixture's, with
    ``undecided`` times half their difference (tone_choice.blended_sigma)."""
    from .tone_choice import blended, blended_sigma

    mixed = {name: blended(getattr(main, name), getattr(other, name), weight)
             for name in ("row", "cone", "regions")}
    sigmas = {f"{name}_sigma": blended_sigma(getattr(main, name), getattr(main, f"{name}_sigma"),
                                             getattr(other, name), getattr(other, f"{name}_sigma"), weight, undecided)
              for name in ("row", "cone", "regions")}
    diagnostics = dict(main.diagnostics, tone_blend={"weight": weight, "undecided": undecided,
                                                     "other_row": other.row.round(6).tolist(),
                                                     "row_difference": float(np.max(np.abs(other.row - main.row)))})
    # the figures derived from the row carry the two models' spread too (result.figures_with_sigma)
    samples = dict(main.samples, **{"tone-main": main.row, "tone-other": other.row, "tone-weight": np.array([weight]),
                                    "tone-undecided": np.array([undecided])})
    return dataclasses.replace(main, **mixed, **sigmas, samples=samples, diagnostics=diagnostics, seconds=other.seconds)


def _analyse(luma, mask, pattern_set, capture, profile, warnings, shifts, curve, photos,
             factor, start, progress, column_average, noise=None, routing=None) -> Measurement:
    import cv2

    n = pattern_set.views
    # camera JPEGs: the band photos' exposures over white's, read on the registration frame, for the
    # light's closure below.  Not undone on the photos: a drifted photo's light above black holds
    # (e_k - e_black) times black's panel light, but dividing each photo by its exposure scales a
    # black level that does not follow the exposure as well (hard case 7's linear photos: the own
    # view 0.135 for 0.618; docs/crosstalk.md, "The light adds up").  Read from the photo files once
    # per pass (twice where two tone models are measured): holding the full-size photos from one
    # pass to the next would cost more memory than reading 12 of them again costs time
    exposures = closure.band_exposures(capture, pattern_set, None if curve is None else curve.lut()) \
        if photos == "srgb" else None
    lit = luma["white"] - luma["black"]
    outside = ~(cv2.dilate(mask.astype(np.uint8), np.ones((15, 15), np.uint8)) > 0)
    glare = photometry.fit_glare(np.where(outside | mask, lit, 0.0).astype(np.float32), outside)
    ratios, rows, cols, white = band_ratios(luma, mask, pattern_set, glare, column_average=column_average)
    bands = pattern_set.bands
    band_shifts = np.array([p.shift for p in bands])
    panel_fit = cone.fit_cone(ratios, rows, cols, band_shifts, n, mask.shape)
    r0, r1, c0, c1 = bounding_box(mask)
    if progress:
        progress("view cone")
    height, width = r1 - r0, c1 - c0
    lo, hi = 0.5 - CENTRE_FRACTION / 2, 0.5 + CENTRE_FRACTION / 2
    centre = centre_region(rows, cols, (r0, r1, c0, c1))
    # the centre region gets its own, lower-degree sweep model: a whole-panel polynomial leaves
    # errors of a tenth of a view here and there, which smear (broaden) the cone
    fit = cone.fit_cone(ratios[centre], rows[centre], cols[centre], band_shifts, n, mask.shape,
                        degree=CENTRE_DEGREE, start=panel_fit)
    # a camera JPEG's clipping sigma, read from the black photo's blocks (dark.block_noise): what it leaves
    # open is carried below
    clip_sigma = dark.block_read_sigma(noise)
    # camera JPEGs: how far the band photos' light is from adding up to white's in the centre region,
    # and the toe that would close it (closure.py; its row change is carried in the uncertainty, not
    # applied).  The region, not the whole panel: a panel whose sides show another cone (a lens that
    # cuts steep rays, bench case 17) is not binned into one cone there (1.114 over the whole panel)
    closed = None
    if photos == "srgb":
        closed = closure.close_toe(lambda lift: band_ratios(luma, mask, pattern_set, glare, 1.0, column_average, 0.0,
                                                            None, lift)[0][centre],
                           fit, rows[centre], cols[centre], band_shifts, exposures, bands)
        if closed.clamped:
            warnings.append(f"the band photos' light adds up to {closed.integral:.3f} of white's, further from it than "
                            "a camera's tone curve explains: photos of another pattern set, or a camera that "
                            "processed them unevenly (the uncertainty carries it, up to a toe of "
                            f"{closure.MAX_TOE})")
    row, cone_values, counts = _row_from(fit, ratios[centre], rows[centre], cols[centre], band_shifts, n)
    # the sweep model itself: the row as the whole-panel model would have it (its own smear included);
    # where the whole panel does not follow one cone (band_check judged the centre region alone) that
    # model is not one of the region's, and the region's own fit of the whole panel's degree stands in
    alternative = panel_fit if (routing or {}).get("region") != "centre" else cone.fit_cone(
        ratios[centre], rows[centre], cols[centre], band_shifts, n, mask.shape, start=panel_fit)
    panel_row, panel_cone, _ = _row_from(alternative, ratios[centre], rows[centre], cols[centre], band_shifts, n)
    samples: dict[str, np.ndarray] = {}
    # statistical spread: blocks of the centre region
    block_rows, block_cones = [], []
    rr, cc = rows[centre], cols[centre]
    # blocks are strips of rows: the sweep runs along x, so each strip sees every offset
    strip = np.minimum(((rr - (r0 + lo * height)) / (CENTRE_FRACTION * height) * BLOCKS).astype(int), BLOCKS - 1)
    for index in range(BLOCKS):
        sel = strip == index
        if sel.sum() < 50:
            continue
        b_row, b_cone, _ = _row_from(fit, ratios[centre][sel], rr[sel], cc[sel], band_shifts, n)
        block_rows.append(b_row)
        block_cones.append(b_cone)
    block_rows = np.array(block_rows)
    k = max(1, len(block_rows))
    # the average along the columns (_ratios) ties strips within about 2 sqrt(pi) sigma of each
    # other: the region holds only that many independent strips
    independent = (max(1.0, min(k, CENTRE_FRACTION / (2 * math.sqrt(math.pi) * column_average))) if column_average
                   else float(k))
    stat_sigma = _robust_spread(block_rows) / math.sqrt(independent) if k > 1 else np.zeros(n)
    # what differs from photo to photo is common to every strip (an exposure that drifted by e_k
    # adds e_k times black's light over white's to each of the photo's ratios: a floor of its own):
    # the rows with one band photo left out show it (a jackknife over the photos; it holds their
    # noise too, so the larger of the two spreads is taken)
    photo_rows = cone.photo_jackknife(fit, ratios[centre], rr, cc, band_shifts)
    photo_sigma = cone.jackknife_sigma(photo_rows)
    stat_sigma = np.maximum(stat_sigma, photo_sigma)
    cone_stat = (_robust_spread(np.array(block_cones)) / math.sqrt(independent) if k > 1
                 else np.zeros_like(cone_values))
    # the cone's change across the region (a blur that grows with the angle sharpens one side): the
    # pixels' average is not quite the light an eye receives (bench case 16: 0.0036 for a left-right
    # difference of 0.017), so a quarter of the halves' difference is carried (docs/crosstalk.md)
    middle = c0 + 0.5 * width
    across = ACROSS_SHARE * np.subtract(*(
        _row_from(fit, ratios[centre][side], rr[side], cc[side], band_shifts, n)[0] for side in (cc >= middle, cc < middle)))
    across_sigma = np.abs(across)
    # systematic: the glare's size, the tone curve's power (its 1-sigma relative to the curve the
    # photos were linearised with) and its toe (camera JPEGs with a measured curve: tone._toe_sigma)
    tone_sigma = (LINEAR_TONE_SIGMA if photos == "linear" else TONE_FLOOR if curve is None
                  else curve.sigma)
    toe_sigma = 0.0 if curve is None else curve.toe_sigma  # no curve for linear photos
    # (glare scale, power, toe, clip, lift): band_ratios' variations
    variations = {"glare-": (1 - GLARE_RELATIVE_SIGMA, 1.0, 0.0, None, 0.0),
                  "glare+": (1 + GLARE_RELATIVE_SIGMA, 1.0, 0.0, None, 0.0),
                  "tone-": (1.0, 1.0 - tone_sigma, 0.0, None, 0.0),
                  "tone+": (1.0, 1.0 + tone_sigma, 0.0, None, 0.0)}
    if toe_sigma:
        variations.update({"toe-": (1.0, 1.0, -toe_sigma, None, 0.0), "toe+": (1.0, 1.0, toe_sigma, None, 0.0)})
    if closed is not None and closed.pinned_toe():
        # the lift that would make the light add up, less its own 1-sigma: its whole change is
        # carried ("closure-" mirrors it)
        variations["closure+"] = (1.0, 1.0, 0.0, None, closed.pinned_toe())
    perturbed = {}
    if clip_sigma:
        # the noise sigma read from the black photo's blocks (a camera JPEG) is left open by
        # dark.SIGMA_RANGE: half the change of the row between its ends is its 1-sigma (dark.reclipped)
        variations.update({"clip-": (1.0, 1.0, 0.0, (clip_sigma, dark.SIGMA_RANGE[0]), 0.0),
                           "clip+": (1.0, 1.0, 0.0, (clip_sigma, dark.SIGMA_RANGE[1]), 0.0)})
    for label, (g_scale, p, t, clip, lift) in variations.items():
        g = dataclasses.replace(glare, fraction=glare.fraction * g_scale)
        r_p, rows_p, cols_p, _ = band_ratios(luma, mask, pattern_set, g, p, column_average, t, clip, lift)
        sel = np.isin(rows_p * mask.shape[1] + cols_p, rr * mask.shape[1] + cc)
        perturbed[label] = _row_from(fit, r_p[sel], rows_p[sel], cols_p[sel], band_shifts, n)
    if "closure+" in perturbed:
        perturbed["closure-"] = (2 * row - perturbed["closure+"][0], 2 * cone_values - perturbed["closure+"][1], counts)

    def half_change(name: str, part: int):
        """Half the change of the row (part 0) or the cone (1) between ``name``'s two variations (0: none)."""
        if f"{name}+" not in perturbed:
            return np.zeros_like(row if part == 0 else cone_values)
        return (perturbed[f"{name}+"][part] - perturbed[f"{name}-"][part]) / 2

    glare_sigma, tone_sig, toe_sig, clip_sig = (np.abs(half_change(name, 0)) for name in ("glare", "tone", "toe", "clip"))
    closure_sig = np.abs(half_change("closure", 0))
    # the sweep model: its local error (tile by tile) smears the cone by eps^2 / 2 h''; and how the
    # row changes with the whole-panel model instead
    offsets = cone.local_offsets(fit, ratios[centre], rr, cc, band_shifts)
    eps2 = float(np.mean(offsets ** 2)) if offsets.size else 0.0
    # ... and the blur the measurement leaves uncorrected: the camera blurs the sweep over about
    # SWEEP_BLUR_PIXELS working pixels, the lens sheet samples it once per lens (a box)
    views_per_pixel = float(np.median(np.abs(fit.delta(rr, cc + 1.0) - fit.delta(rr, cc))))
    lens_views = n * (pattern_set.profile.period / 3.0) / pattern_set.sweep
    eps2 += (SWEEP_BLUR_PIXELS * views_per_pixel) ** 2 + lens_views ** 2 / 12.0
    curvature = np.array([row[(m + 1) % n] - 2 * row[m] + row[m - 1] for m in range(n)])
    model_sigma = np.sqrt((0.5 * eps2 * curvature) ** 2 + (row - panel_row) ** 2)
    # the dark floor: what a glare halo that is not Gaussian (real lenses have long tails) leaves
    floor_sigma = np.full(n, FLOOR_SIGMA + FLOOR_GLARE_SHARE * glare.fraction / n)
    far_sigma = np.full(n, cone.far_scatter(row))  # what the sampling of each offset left (neither spread shows it)
    row_sigma = np.sqrt(stat_sigma ** 2 + across_sigma ** 2 + glare_sigma ** 2 + tone_sig ** 2 + toe_sig ** 2 + clip_sig ** 2
                        + closure_sig ** 2 + far_sigma ** 2 + floor_sigma ** 2 + model_sigma ** 2)
    cone_sigma = np.sqrt(cone_stat ** 2 + floor_sigma[0] ** 2 + (cone_values - panel_cone) ** 2
                         + sum(half_change(name, 1) ** 2 for name in ("glare", "tone", "toe", "closure", "clip")))
    samples = {"blocks": block_rows, "photos-left-out": photo_rows, "far-scatter": far_sigma,
               **{k2: v[0] for k2, v in perturbed.items()},
               "across-": row - across, "across+": row + across}  # half their difference: across_sigma
    # uniformity map: own-view share per region
    cols_n, rows_n = REGION_GRID
    regions = np.full((rows_n, cols_n), np.nan)
    regions_sigma = np.full((rows_n, cols_n), np.nan)
    gy = np.minimum(((rows - r0) / max(height, 1) * rows_n).astype(int), rows_n - 1)
    gx = np.minimum(((cols - c0) / max(width, 1) * cols_n).astype(int), cols_n - 1)
    for j in range(rows_n):
        for i in range(cols_n):
            sel = (gy == j) & (gx == i)
            if sel.sum() < 200:
                continue
            own = _row_from(panel_fit, ratios[sel], rows[sel], cols[sel], band_shifts, n)[0][0]
            halves = []
            for part in range(2):
                sub = sel & ((cols % 2) == part)
                halves.append(_row_from(panel_fit, ratios[sub], rows[sub], cols[sub], band_shifts, n)[0][0])
            regions[j, i] = own
            regions_sigma[j, i] = math.sqrt(stat_sigma[0] ** 2 + (halves[0] - halves[1]) ** 2 / 4
                                            + glare_sigma[0] ** 2 + tone_sig[0] ** 2 + toe_sig[0] ** 2
                                            + closure_sig[0] ** 2
                                            + clip_sig[0] ** 2 + model_sigma[0] ** 2)
    photometry_record = {"photos": photos, "working_factor": factor, "glare": glare.to_dict(),
                         "tone_curve": None if curve is None else curve.to_dict(),
                         "tone_power_sigma": round(tone_sigma, 4), "tone_toe_sigma": round(toe_sigma, 4),
                         "closure": None if closed is None else closed.to_dict(),
                         "frame_exposures": None if exposures is None else exposures.to_dict(),
                         "exposures": {p.name: round(float(g), 4) for p, g in zip(bands, panel_fit.gains)},
                         "shifts": shifts,
                         # the camera's noise sigma per channel (share of full scale) where it clips dark pixels
                         # at 0, their bias undone (photos.load_all); None: no clipping seen on the black photo
                         "dark_clipping_sigma": None if noise is None else [round(float(v), 6) for v in noise.sigma],
                         # the 2 x 2 phases (row % 2, column % 2) of each channel holding the sensor's own values
                         "dark_clipping_sites": None if noise is None else [[list(p) for p in s] for s in noise.sites]}
    diagnostics = {"cone_residual_rms": panel_fit.rms, "centre_cone_residual_rms": fit.rms, "centre_pixels": int(centre.sum()), "blocks": int(k),
                   "independent_strips": float(independent),
                   "sigma_statistical": stat_sigma, "sigma_photos": photo_sigma, "sigma_across_region": across_sigma, "sigma_glare": glare_sigma, "sigma_tone": tone_sig,
                   "sigma_tone_toe": toe_sig, "sigma_dark_clipping": clip_sig, "sigma_closure": closure_sig, "sigma_far_scatter": far_sigma,
                   "sigma_floor": floor_sigma, "sigma_sweep_model": model_sigma,
                   "sweep_smear_views": math.sqrt(eps2),
                   "sweep_model_offset_rms": float(np.sqrt(np.mean(offsets ** 2))) if offsets.size else 0.0,
                   **routing_diagnostics(panel_fit, (r0, r1, c0, c1), pattern_set), "routing_check": routing}
    delta = np.full(mask.shape, np.nan)
    delta[rows, cols] = panel_fit.delta(rows, cols)
    images = {"white": white, "delta": delta, "mask": mask,
              "centre_box": np.array([r0 + lo * height, r0 + hi * height, c0 + lo * width, c0 + hi * width]),
              "region_box": np.array([r0, r1, c0, c1])}
    return Measurement(n, row, row_sigma, fit.grid.copy(), cone_values, cone_sigma, regions, regions_sigma, samples,
                       photometry_record, diagnostics, warnings, capture.inputs, profile, pattern_set,
                       time.perf_counter() - start, images)


def _robust_spread(values: np.ndarray) -> np.ndarray:
    """Per column: 1.4826 x the median absolute deviation (a standard deviation that one odd block cannot inflate)."""
    med = np.nanmedian(values, axis=0)
    return 1.4826 * np.nanmedian(np.abs(values - med), axis=0)
