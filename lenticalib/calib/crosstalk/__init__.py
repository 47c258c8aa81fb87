"""Per-view crosstalk: patterns drawn from a fitted profile, measurement from photos, figures.

Part of the calib layer: imports only core and calib.  Modules, in the order a measurement
uses them:

    patterns     the sweep patterns and their manifest (``lenticalib crosstalk patterns``)
    photos       reading the photos: linear light, the panel's lit area, registration
    tone         the camera's tone curve, from the black, white, half and level photos
    tone_models  the tone curve's relations (the black's clipping light off) and its two models (power, bent curve)
    tiles        photo tiles for the tone curve: the tile side, each tile's mean and largest code, histograms
    level_texture the level photos' rows as the camera resolved them: the light its demosaicing takes off them
    level_channels the level photos' colour channels: those that agree carry each level's relation
    exposure     each photo's exposure, read on the registration frame's step down to the bezel
    tone_choice  the power, the bent curve or a blend of the two: the curve's weight, the blend
    dark         dark pixels clipped at zero: their sigma (at the sensor's sites, or a JPEG's block means), their bias undone
    photometry   the camera's veiling glare, from the photos
    ratios       the band photos over white (relinearised for the tone curve's uncertainty, lifted for the closure, glare removed)
    checks       duplicate photos, band photos that do not fit the others, photos of another panel
    band_check   the checks as the measurement runs them: the whole panel, then its centre region
    cone         the angular profile of a view (light vs. eye position, in views) from the sweeps
    closure      how far the band photos' light is from adding up to white's (their exposures read on the frame)
    measure      the measurement: the mixing matrix and the view cone from the photos
    result       ``crosstalk.json``: the mixing matrix, derived figures, writing, reading, checking
    report       the report's figures (titles, axes with units, legends)
    pipeline     ``measure_crosstalk_set``: all of ``lenticalib crosstalk measure`` in one call

The method is in ``docs/crosstalk.md``.
"""
