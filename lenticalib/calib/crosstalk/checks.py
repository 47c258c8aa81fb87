"""Checks of the band photos: duplicates, and a photo whose band is not where the others put it."""

from __future__ import annotations

import numpy as np

from ...core.errors import CaptureError
from . import cone

MAX_MISFIT = 0.15  # of the profile's contrast
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


def photo_misfit(fit, ratios, rows, cols, shifts) -> np.ndarray:
    """Per band photo: RMS of ``r_k - a h(delta + c_k)`` with the photo's own best exposure ``a``, over the
    profile's contrast (a right photo: a few hundredths; a photo of another band: ~0.3 or more)."""
    t = fit.delta(rows, cols)[:, None] + shifts[None, :]
    model = cone.profile_at(fit.grid, fit.profile, t, fit.views)
    contrast = max(float(np.max(fit.profile) - np.min(fit.profile)), 1e-9)
    out = []
    for j in range(ratios.shape[1]):
        a = float(np.dot(ratios[:, j], model[:, j]) / max(np.dot(model[:, j], model[:, j]), 1e-30))
        out.append(float(np.sqrt(np.mean((ratios[:, j] - a * model[:, j]) ** 2))) / contrast)
    return np.array(out)



def check_band_photos(ratios, rows, cols, shifts, bands, capture, views, shape) -> None:
    """Each band photo must show its band where the others put it.  When one does not, each photo is
    judged against a fit of the others (a wrong photo pulls a fit that includes it towards itself):
    the one that fits badly while all the others then fit well is named.

    Runs before the cone fit of the measurement, on its own quick fit of :data:`CHECK_SAMPLES`
    working pixels drawn with a fixed seed (``ratios`` float (n, K), ``rows``/``cols`` int (n,),
    ``shifts`` float (K,) views, ``shape`` (h, w) of the working image), so a wrong photo is
    named in seconds.  Only this fit is judged: the measurement's fit of the whole panel is not
    checked again (its residual is reported in the diagnostics, ``cone_residual_rms``)."""
    pick = np.random.default_rng(1).choice(len(rows), size=min(CHECK_SAMPLES, len(rows)), replace=False)
    ratios, rows, cols = ratios[pick], rows[pick], cols[pick]
    fit = cone.fit_cone(ratios, rows, cols, shifts, views, shape)
    misfit = photo_misfit(fit, ratios, rows, cols, shifts)
    if misfit.max() <= MAX_MISFIT and np.all((fit.gains > 0.6) & (fit.gains < 1.6)):
        return
    best = None
    for j in range(len(bands)):
        keep = np.arange(len(bands)) != j
        others = cone.fit_cone(ratios[:, keep], rows, cols, shifts[keep], fit.views, shape)
        rest = photo_misfit(others, ratios[:, keep], rows, cols, shifts[keep])
        t = others.delta(rows, cols) + shifts[j]
        model = cone.profile_at(others.grid, others.profile, t, others.views)
        a = float(np.dot(ratios[:, j], model) / max(np.dot(model, model), 1e-30))
        contrast = max(float(np.max(others.profile) - np.min(others.profile)), 1e-9)
        alone = float(np.sqrt(np.mean((ratios[:, j] - a * model) ** 2))) / contrast
        if rest.max() <= MAX_MISFIT and (alone > MAX_MISFIT or not 0.6 < a < 1.6):
            if best is None or alone > best[1]:
                best = (j, alone, a)
    if best is not None:
        j, alone, a = best
        raise CaptureError(f"does not show pattern {bands[j].name} where the other band photos say it should be "
                           f"(misfit {alone:.2f} of the band's contrast, exposure {a:.2f} of the others')",
                           source=str(capture.photo(bands[j].name)),
                           hint=f"show {bands[j].file} of this folder full screen and photograph it again from "
                                "the same place")
    worst = int(np.argmax(misfit))
    raise CaptureError(f"the band photos do not agree with each other (worst: {bands[worst].name}, misfit "
                       f"{misfit[worst]:.2f})", source=str(capture.directory / "captures"),
                       hint="photograph every pattern of this folder from one camera position, with the exposure "
                            "locked; they may be photos of another pattern set")
