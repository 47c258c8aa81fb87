"""Calibration: test patterns, capture sets, and the fit of a panel profile from camera photos.

Modules, in the order the fit uses them:

    patterns   the test patterns lenticalib draws and their manifest (``patterns.json``)
    captures   loading and checking a capture set (``DIR/captures/NAME.jpg`` ...)
    phase      phase-shift demodulation, unwrapping and smoothing of the seen-coordinate maps
    model      the global fit of the view-coordinate plane, subpixel order, uncertainties
    camera     camera intrinsics and pose estimated from the panel (or an optional model)
    report     the figures and summary written next to a fitted profile
    compare    how far one profile is from another, in views (the docs/optics.md convention)

Before the fit, ``cameras`` holds the capture cameras ``lenticalib capture`` triggers (gphoto2,
OpenCV webcams, a manual shutter, the simulator's virtual camera), behind one registry.
"""
