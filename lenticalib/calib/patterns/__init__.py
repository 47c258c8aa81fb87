"""The patterns lenticalib draws, the capture sets of their photos, and reading a photo back.

Importing this package loads nothing; each module imports what it needs.

    calibration_patterns  the calibration test patterns and their manifest ``patterns.json``
    crosstalk_patterns    the crosstalk sweep patterns and their manifest (``lenticalib crosstalk patterns``)
    capture_sets          capture sets: one photo per pattern in ``DIR/captures/NAME.{jpg,png,tif}``
    phase                 phase-shift demodulation, unwrapping and smoothing of the seen-coordinate maps
    register              camera shake between photos, measured on the registration frame and undone
"""
