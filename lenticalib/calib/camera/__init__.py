"""The calibration camera: the one owner of the ``.cameramodel`` format, its estimate from the panel, its pose.

Importing this package loads nothing; each module imports what it needs.

    from_panel  the camera's intrinsics and pose estimated from the panel (or given by a file)
    model_file  a calibrated camera as a file: mrcal ``.cameramodel`` read, checked and written (the
                one owner of the format), OpenCV YAML/JSON read
    pose        where the camera was (mm), from the panel's own pixel grid
"""
