"""Per-view crosstalk: patterns drawn from a fitted profile, measurement from photos, figures.

Modules
    patterns     the sweep patterns and their manifest (``lenticalib crosstalk patterns``)
    photometry   camera response (tone curve), exposure drift and veiling glare, from the photos
    cone         the angular profile of a view (light vs. eye position, in views) from the sweeps
    measure      the whole measurement (``lenticalib crosstalk measure``)
    result       ``crosstalk.json``: the mixing matrix, derived figures, reading and checking
    report       the report's figures

The method is in ``docs/crosstalk.md``.
"""
