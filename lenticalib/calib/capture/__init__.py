"""Capture: showing the patterns on the panel and photographing them.

Importing this package loads nothing; each module imports what it needs.

    acquire          guided capture: show each pattern, photograph it, check it at once
    cameras          the capture cameras ``lenticalib capture`` triggers (gphoto2, OpenCV, manual,
                     the simulator's), behind one registry
    guided           ``guided_capture``: the whole of ``lenticalib capture`` (defaults per camera kind, open
                     order, the fallback to no graphics) as one call
    pattern_folders  pattern folders written whole (``lenticalib patterns``, ``crosstalk patterns``)
"""
