"""Checks of the band photos: duplicates, a photo whose band is not where the others put it, and a set
that does not follow the routing of the profile the patterns were drawn from (:func:`check_routing`:
another panel photographed, or a wrong profile; judged on the whole panel's cone fit, limits in
:data:`ROUTING_LIMITS`, measured in docs/crosstalk.md, "Photos that do not follow the profile").

How well a photo agrees with the view-cone model is judged on a scale the photos themselves set
(:func:`photo_disagreement`): the photo's misfit to the model beyond its own noise, over the
misfit (beyond noise) the photos show against the same model moved half the views away, which
is what a photo of another band shows.  The noise is taken out (it is what differs between
neighbouring pixels), and both misfits scale with the cone's contrast, so one limit serves a
sharp lens sheet and a soft one, clean and noisy photos, close up and from afar.  On the virtual
panel (own-view shares 0.26-0.64, 400-900 mm): 0-0.12 for right photos (more before a close
camera's moire is averaged out along the columns), 7-9 for a photo of a half pattern, about 1 for
a band elsewhere.  The former limit, a misfit of 0.15 of the cone's peak-to-peak contrast with the
noise left in, refused right photos of a soft sheet (own-view share 0.26) with a noise of 0.04 of
white per working pixel; these pass with disagreements below 0.2.
"""

from __future__ import annotations

import math

import numpy as np

from ...core.errors import CaptureError
from . import cone

MAX_DISAGREEMENT = 0.5  # a photo's misfit beyond noise, over what a photo of another band shows (photo_disagreement)
EXPOSURE_RANGE = (0.6, 1.6)  # a band photo's exposure relative to white, as the cone fit finds it
NOISE_STEP = 2  # rows between the pixels whose residuals give a photo's noise (1: neighbours share the camera's blur)
SEEN_SHARE = 0.25  # of the median band's model energy: a band seen enough to tell its exposure (band_seen)
CHECK_SAMPLES = 6000  # working pixels the band-photo check fits (a fifth of the cone fit's: seconds, not minutes)


def check_distinct(ratios, bands, capture) -> None:
    """Two band photos that are the same image (one pattern photographed twice, or a copy)."""
    energy = np.mean(ratios ** 2, axis=0)
    lit = energy > 0.3 * energy.max()  # a band may lie off the panel in some photos (a long sweep)
    for i in range(len(bands)):
        for j in range(i + 1, len(bands)):
            if lit[i] and lit[j] and float(np.mean((ratios[:, i] - ratios[:, j]) ** 2)) < 0.02 * min(energy[i], energy[j]):
                raise CaptureError(f"shows the same pattern as {capture.photo(bands[i].name).name}",
                                   source=str(capture.photo(bands[j].name)),
                                   hint=f"photograph {bands[j].file} and {bands[i].file} each in its own photo")


def _misfit(values: np.ndarray, model: np.ndarray) -> tuple[float, float]:
    """(RMS of ``values - a model`` with the best ``a``, that ``a``), both (n,) float."""
    a = float(np.dot(values, model) / max(float(np.dot(model, model)), 1e-30))
    return float(np.sqrt(np.mean((values - a * model) ** 2))), a


def sample_pairs(rows: np.ndarray, cols: np.ndarray, count: int, seed: int = 1) -> tuple[np.ndarray, np.ndarray]:
    """(pick, partner): ``count`` indices into ``rows``/``cols`` (int (n,), working pixels) drawn
    with ``seed`` among the pixels whose pixel :data:`NOISE_STEP` rows below is in the list too,
    and the index of that pixel (same column) for each."""
    index = np.full((int(rows.max()) + NOISE_STEP + 1, int(cols.max()) + 1), -1, np.int64)
    index[rows, cols] = np.arange(rows.size)
    partner = index[rows + NOISE_STEP, cols]
    candidates = np.flatnonzero(partner >= 0)
    pick = np.random.default_rng(seed).choice(candidates, size=min(count, candidates.size), replace=False)
    return pick, partner[pick]


def photo_disagreement(fit, ratios, rows, cols, shifts, below=None,
                       scale: float | None = None) -> tuple[np.ndarray, np.ndarray, float]:
    """Per band photo ``k``: (disagreement (K,), exposure (K,)), and the scale they were judged on.

    The disagreement is the RMS of ``r_k - a h(delta + c_k)`` (``a``: the photo's own best
    exposure, returned) beyond the photo's noise, over ``scale``: by default the median over the
    photos of the same RMS beyond noise with the model half the views away (``h(delta + c_k +
    N/2)``, its own best exposure), which is what a photo of another band shows.  0: a photo the
    model explains down to its noise; about 1: a photo the model explains no better than a band
    elsewhere.  The median, not each photo's own: a band that lies off the panel in a long sweep
    shows nothing either way.

    The noise is what differs between the residuals of neighbouring pixels along a column
    (``below``: (ratios (n, K), rows, cols) of the pixels :data:`NOISE_STEP` rows below, from
    :func:`sample_pairs`; None: no noise taken out): half their mean square difference.  A moire
    or a misfit of the model changes little from one pixel to the next and stays.

    ``fit``: a :class:`.cone.ConeFit`; ``ratios`` float (n, K); ``rows``/``cols`` (n,) working
    pixels; ``shifts`` (K,) views.
    """
    shifts = np.asarray(shifts, np.float64)
    t = fit.delta(rows, cols)[:, None] + shifts[None, :]
    t_below = None if below is None else fit.delta(below[1], below[2])[:, None] + shifts[None, :]
    n = fit.views
    own, away, exposure = [], [], []
    for j in range(ratios.shape[1]):
        model = cone.profile_at(fit.grid, fit.profile, t[:, j], n)
        misfit, a = _misfit(ratios[:, j], model)
        noise2 = 0.0
        if below is not None:
            model_below = cone.profile_at(fit.grid, fit.profile, t_below[:, j], n)
            noise2 = 0.5 * float(np.mean(((ratios[:, j] - a * model) - (below[0][:, j] - a * model_below)) ** 2))
        own.append(math.sqrt(max(misfit ** 2 - noise2, 0.0)))
        exposure.append(a)
        if scale is None:
            other = _misfit(ratios[:, j], cone.profile_at(fit.grid, fit.profile, t[:, j] + n / 2.0, n))[0]
            away.append(math.sqrt(max(other ** 2 - noise2, 0.0)))
    scale = float(np.median(away)) if scale is None else scale
    return np.array(own) / max(scale, 1e-12), np.array(exposure), scale


def _exposure_ok(a, seen) -> np.ndarray:
    """bool (K,): exposure ``a`` (K,) within ``EXPOSURE_RANGE``, or a band not ``seen`` (K,) enough to tell."""
    return ((np.asarray(a) > EXPOSURE_RANGE[0]) & (np.asarray(a) < EXPOSURE_RANGE[1])) | ~np.asarray(seen)


def band_seen(fit, rows, cols, shifts) -> np.ndarray:
    """bool (K,): which bands the pixels (``rows``, ``cols``) show enough of to tell their exposure:
    the model's energy (mean of ``h(delta + c_k)^2``) at least ``SEEN_SHARE`` of the median band's.
    A part of the panel narrower than the sweep sees some bands only in the cone's tails, where a
    cone that changes across the panel (a lens aperture that cuts steep rays) puts their scale
    anywhere: the centre region of bench case 17 with an aperture of 0.35 gave one such band an
    exposure of 9.9 times the others'."""
    t = fit.delta(rows, cols)[:, None] + np.asarray(shifts, np.float64)[None, :]
    energy = np.mean(cone.profile_at(fit.grid, fit.profile, t, fit.views) ** 2, axis=0)
    return energy >= SEEN_SHARE * float(np.median(energy))


def check_band_photos(ratios, rows, cols, shifts, bands, capture, views, shape, judge=None) -> None:
    """Each band photo must show its band where the others put it.  When one does not, each photo is
    judged against a fit of the others (a wrong photo pulls a fit that includes it towards itself):
    the one that disagrees while all the others then agree is named.

    Runs right after the photos are read (before the glare fit and the cone fits of the
    measurement), on its own quick fit of :data:`CHECK_SAMPLES` working pixels drawn with a fixed
    seed by :func:`sample_pairs` (with the pixels below them, for the noise), so a wrong photo is
    named in seconds.  ``ratios`` float (n, K), ``rows``/``cols`` int (n,), ``shifts`` float (K,)
    views, ``shape`` (h, w) of the working image.  Only this fit is judged: the measurement's fit of the whole panel is not
    checked again (its residual is reported in the diagnostics, ``cone_residual_rms``).

    ``judge`` (:func:`check_routing`) is called once, with the fit the verdict rests on, before a
    refusal: the fit of all photos when they agree or none can be named, the fit of the others
    when one is named (a wrong photo pulls the fit of all; a set that does not follow the
    profile's routing still shows it without that photo, and is refused as a set, not by the photo
    it throws furthest)."""
    pick, partner = sample_pairs(rows, cols, CHECK_SAMPLES)
    below = (ratios[partner], rows[partner], cols[partner])
    ratios, rows, cols = ratios[pick], rows[pick], cols[pick]
    judge = judge or (lambda fit: None)
    fit = cone.fit_cone(ratios, rows, cols, shifts, views, shape)
    disagreement, _, _ = photo_disagreement(fit, ratios, rows, cols, shifts, below)
    if disagreement.max() <= MAX_DISAGREEMENT and np.all(_exposure_ok(fit.gains, band_seen(fit, rows, cols, shifts))):
        judge(fit)
        return
    best = None
    for j in range(len(bands)):
        keep = np.arange(len(bands)) != j
        others = cone.fit_cone(ratios[:, keep], rows, cols, shifts[keep], fit.views, shape)
        rest, _, scale = photo_disagreement(others, ratios[:, keep], rows, cols, shifts[keep],
                                            (below[0][:, keep], below[1], below[2]))
        alone, a, _ = photo_disagreement(others, ratios[:, [j]], rows, cols, shifts[[j]],
                                         (below[0][:, [j]], below[1], below[2]), scale)
        seen = band_seen(others, rows, cols, shifts)
        if rest.max() <= MAX_DISAGREEMENT and (alone[0] > MAX_DISAGREEMENT or not _exposure_ok(a, seen[[j]])[0]):
            if best is None or alone[0] > best[1]:
                best = (j, float(alone[0]), float(a[0]), others)
    if best is not None:
        j, alone, a, others = best
        judge(others)
        raise CaptureError(f"does not show pattern {bands[j].name} where the other band photos say it should be "
                           f"(disagreement {alone:.2f}, exposure {a:.2f} of the others'; right photos show below "
                           f"{MAX_DISAGREEMENT}, a photo of another band about 1)",
                           source=str(capture.photo(bands[j].name)),
                           hint=f"show {bands[j].file} of this folder full screen and photograph it again from "
                                "the same place")
    judge(fit)
    worst = int(np.argmax(disagreement))
    raise CaptureError(f"the band photos do not agree with each other (worst: {bands[worst].name}, disagreement "
                       f"{disagreement[worst]:.2f}; right photos show below {MAX_DISAGREEMENT}, a photo of another band "
                       "about 1)", source=str(capture.directory / "captures"),
                       hint="photograph every pattern of this folder from one camera position, with the exposure "
                            "locked; they may be photos of another pattern set, or of another panel than the "
                            "profile's (docs/crosstalk.md, 'Photos that do not follow the profile')")


def sweep_geometry(fit, box, views: int, width: int, sweep: float, edge: float = 0.05,
                   span=None) -> dict[str, float]:
    """Where the photos put the bands against where the profile drew them (views).

    ``fit``: the whole panel's :class:`.cone.ConeFit`; ``box``: (r0, r1, c0, c1) the panel's outline in
    working pixels (:func:`.ratios.bounding_box`); ``width``: the panel in pixels; ``sweep``: the
    patterns' sweep (pixels).  The patterns put the band ``N x / sweep`` views from the fit's camera
    at panel column ``x``, the same at every row, so on photos of the panel the profile was fitted
    to the sweep ``delta`` changes by ``N W / sweep`` views from the left edge to the right and by 0
    from top to bottom.  Returned, each the mean over 5 rows or columns of the middle, ``edge`` of
    the outline in from its edges:

    sweep_drift_views   the change across the width less what was drawn (a period not the panel's)
    sweep_rate_error    that over what was drawn there (a fraction; the period's relative error
                        times ``3 sweep / period``)
    sweep_tilt_views    the change from top to bottom (a slant not the panel's: ``3 H N / period``
                        views per unit of slant)
    sweep_centre_views  delta at the outline's centre less what was drawn there, modulo N into
                        -N/2..N/2 (an offset not the panel's; the photo's perspective moves it too)

    ``span``: (r0, r1, c0, c1) inside ``box``, the part of the panel the fit was made on (None:
    the whole outline); the change across and down is then read ``edge`` in from its edges and
    scaled to the outline's extent, so the fit is not extrapolated to parts it did not see.
    """
    r0, r1, c0, c1 = box
    s0, s1, t0, t1 = box if span is None else span
    middle = np.linspace(0.3, 0.7, 5)
    rows, cols = s0 + middle * (s1 - s0), t0 + middle * (t1 - t0)
    ones = np.ones_like(middle)
    across = fit.delta(rows, (t1 - edge * (t1 - t0)) * ones) - fit.delta(rows, (t0 + edge * (t1 - t0)) * ones)
    down = fit.delta((s1 - edge * (s1 - s0)) * ones, cols) - fit.delta((s0 + edge * (s1 - s0)) * ones, cols)
    centre = float(fit.delta(np.array([(r0 + r1) / 2.0]), np.array([(c0 + c1) / 2.0]))[0])
    share_across = max(t1 - t0, 1e-9) / max(c1 - c0, 1e-9)  # of the outline: 1 without a span
    share_down = max(s1 - s0, 1e-9) / max(r1 - r0, 1e-9)
    drawn = views * width * (1 - 2 * edge) / sweep
    drift = float(np.mean(across)) / share_across - drawn
    return {"sweep_drift_views": drift, "sweep_rate_error": drift / drawn,
            "sweep_tilt_views": float(np.mean(down)) / share_down,
            "sweep_centre_views": (centre - views * (width / 2.0) / sweep + views / 2.0) % views - views / 2.0}



# Photos that do not follow the profile's routing (docs/crosstalk.md, "Photos that do not follow the
# profile"): diagnostic -> (warn above, refuse above) on its absolute value, measured on right sets and
# on sets photographed through the profile of another panel or a wrong one
ROUTING_LIMITS = {
    "cone_residual_relative": (0.35, 0.7),  # the cone fit's residual over the cone's contrast
    "sweep_rate_error": (0.12, 0.2),  # sweep_geometry: the bands' drift across the width over what was drawn
    "sweep_tilt_views": (0.8, 2.0),  # sweep_geometry: the bands' drift from top to bottom, views
}


def _routing_reason(key: str, d: dict, warn: float, refuse: float) -> str:
    if key == "cone_residual_relative":
        return (f"the bands do not sweep across the panel as drawn: the view-cone model leaves {d[key]:.2f} times "
                f"the cone's contrast unexplained (warned above {warn:g}, refused above {refuse:g})")
    if key == "sweep_rate_error":
        return (f"the bands drift {d['sweep_drift_views']:+.1f} views across the panel from where the profile puts "
                f"them, {100 * d[key]:+.0f}% of the sweep drawn: a period not the panel's (warned above "
                f"{100 * warn:g}%, refused above {100 * refuse:g}%)")
    return (f"the bands drift {d[key]:+.1f} views from the panel's top to its bottom: a slant not the panel's "
            f"(warned above {warn:g}, refused above {refuse:g})")


def routing_verdict(diagnostics: dict) -> tuple[str, list[str]]:
    """("ok" | "warn" | "refuse", one reason per diagnostic past its warning limit) for a
    measurement's ``diagnostics`` (``cone_residual_relative`` and :func:`sweep_geometry`'s) against
    :data:`ROUTING_LIMITS`; a diagnostic that is not a number (a fit that found no cone) refuses.
    Where the cone model does not hold (the residual past its refusal limit) the sweep's geometry
    means nothing and is not quoted."""
    verdict, reasons = "ok", []
    residual = abs(float(diagnostics["cone_residual_relative"]))
    chaotic = not residual <= ROUTING_LIMITS["cone_residual_relative"][1]
    for key, (warn, refuse) in ROUTING_LIMITS.items():
        if chaotic and key != "cone_residual_relative":
            continue
        value = abs(float(diagnostics[key]))
        if value <= warn:
            continue
        reasons.append(_routing_reason(key, diagnostics, warn, refuse))
        verdict = "refuse" if not value <= refuse or verdict == "refuse" else "warn"
    return verdict, reasons


def routing_diagnostics(fit, box, pattern_set, span=None) -> dict[str, float]:
    """What :func:`routing_verdict` judges, from a cone fit ``fit`` of the whole panel (or of
    ``span``, a part of it): ``cone_contrast`` (the cone's peak to peak, share of white),
    ``cone_residual_relative`` (the fit's residual over it) and :func:`sweep_geometry`'s (``box``:
    the panel's outline in working pixels)."""
    contrast = float(fit.profile.max() - fit.profile.min())
    return {"cone_contrast": contrast, "cone_residual_relative": fit.rms / contrast if contrast > 0 else math.inf,
            **sweep_geometry(fit, box, pattern_set.views, pattern_set.width, pattern_set.sweep, span=span)}


def check_routing(fit, box, pattern_set, capture, warnings: list[str], force: bool = False, span=None) -> dict:
    """Do the photos follow the routing of the profile the patterns were drawn from?  Judged
    (:func:`routing_verdict`) on the band-photo check's quick fit of the whole panel (``fit``, see
    :func:`check_band_photos`: the fit of all photos, or of the others where one is out of place),
    before that check refuses anything and before the measurement's own work.
    Refused: CaptureError naming the capture folder, unless ``force``; warned of (and when forced):
    a line added to ``warnings``.

    RETURNED VALUE
    {"verdict": "ok" | "warn" | "refuse", "reasons": [...], "forced": a refusal overridden by
    ``force``, "judged": :func:`routing_diagnostics` of ``fit``} (``routing_check`` in the
    measurement's diagnostics)."""
    found = routing_diagnostics(fit, box, pattern_set, span)
    verdict, reasons = routing_verdict(found)
    if verdict == "refuse" and not force:
        raise CaptureError("the photos do not follow the routing of the profile the patterns were drawn from: "
                           + "; ".join(reasons), source=str(capture.directory),
                           hint="they show another panel than the profile's, or the profile is wrong: photograph "
                                "the panel the profile was fitted to from the fit's camera position, or fit this "
                                "panel and draw the crosstalk patterns from its profile; `force` measures anyway")
    if reasons:
        warnings.append(("measured anyway (forced): " if verdict == "refuse" else "")
                        + "the photos may not follow the routing of the profile the patterns were drawn from: "
                        + "; ".join(reasons))
    return {"verdict": verdict, "reasons": reasons, "forced": verdict == "refuse",
            "judged": {key: round(float(value), 4) for key, value in found.items()}}
