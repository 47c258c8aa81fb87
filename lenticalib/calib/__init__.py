"""The calib layer: the fit of a panel profile from camera photos of test patterns.

calib imports only core (and itself).  Importing this package loads nothing; each module
imports numpy and OpenCV itself.

Stage packages, top to bottom (a layered import contract in ``pyproject.toml`` keeps the order:
a package imports only the ones below it; packages on one line never import each other)

    fleet        a fleet of panels fitted on a Dask cluster (``lenticalib batch fit``): the task,
                 the inputs' identity for resuming, the summary and the fleet figure
    capture      guided capture: show each pattern on the panel, photograph it (capture cameras by
                 name), pattern folders written whole
    routing      the routing fit: photo groups, the global model, subpixel order and layout,
                 uncertainty, physical constants, the fit pipeline, its report, profile comparison
    crosstalk    per-view crosstalk: measurement from photos of the sweep, ``crosstalk.json``, checks
    intrinsics   the camera's own calibration with mrcal, from photos of a chessboard or ChArUco board
    camera       the calibration camera: the ``.cameramodel`` format, the estimate from the panel, the pose
    patterns     the patterns drawn (calibration and crosstalk), capture sets of their photos, phase
                 demodulation and registration of a photo

The layers and their rule: ``docs/architecture.md``.
"""
