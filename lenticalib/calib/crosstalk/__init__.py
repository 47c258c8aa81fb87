"""Per-view crosstalk: patterns drawn from a fitted profile, measurement from photos, figures.

Modules
    patterns     the sweep patterns and their manifest (``lenticalib crosstalk patterns``)
    photos       reading the photos: linear light, the panel's lit area, registration, the halves
    photometry   camera response (tone curve) and veiling glare, from the photos
    checks       duplicate photos and band photos that do not fit the others
    cone         the angular profile of a view (light vs. eye position, in views) from the sweeps
    measure      the whole measurement (``lenticalib crosstalk measure``)
    result       ``crosstalk.json``: the mixing matrix, derived figures, reading and checking
    report       the report's figures

The method is in ``docs/crosstalk.md``.
"""
