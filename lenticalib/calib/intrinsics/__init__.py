"""Camera intrinsics: calibrating the camera that photographs the panel, with mrcal.

A chessboard or a ChArUco board is shown on the panel (or printed), photographed 15-30 times from
varied, tilted views (a ChArUco board may run off the frame), its corners found in every photo,
and one camera model solved with mrcal together with every board pose.  Part of the calib layer: imports only core and calib.  Modules, in the order
``lenticalib camera`` uses them:

    board     the board (chessboard or ChArUco): geometry, design (panel or printed), ``board.json``
    charuco   ChArUco names and sizes: the ArUco dictionaries, the marker size
    draw      the panel raster and the printable sheet (PDF, 300 dpi PNG)
    corners   corner detection (OpenCV's findChessboardCornersSB, partial boards), in parallel
              over photos
    charuco_corners  ChArUco corners: cv2.aruco's CharucoDetector, windows that miss the markers
    corner_model  the last step of every corner's location: a blurred corner (bent lines, uneven
              light) fitted to every pixel of its window; the grid's local axes
    partial   a chessboard seen only in part: its visible block placed into the board's grid
    rectified corners (chessboard and ChArUco) located again in views rectified with a first camera model
    solve     the mrcal solve: seed, pre-solves, lens models tried, the choice, the .cameramodel
    crossval  cross-validation: is mrcal's uncertainty as large as the real error?
    holdout   a model solved on half the photos predicting the other half; the mrcal calls shared with solve
    quality   residuals, noise, coverage and projection uncertainty of a solve; truth comparison
    report    the figures (residuals.png, coverage.png, uncertainty.png) and summary.json
    pipeline  the whole calibration, photos to model and report: :func:`~.pipeline.calibrate_camera`

Frames and units.  Camera pixels: OpenCV's and mrcal's convention, (0, 0) is the centre of the
top-left pixel.  Board frame (mm): origin at inner corner (0, 0), x along a row of corners (to the
right as the board is drawn), y down the columns, z into the board; corner (i, j) (row i, column
j) is at ``(j s, i s, 0)``, s the square size.  For a board shown on a panel the corners lie in
the panel's pixel plane, so board poses refer to that plane (``docs/camera.md``).

mrcal is imported only inside the functions that use it (through ``solve.import_mrcal``, which
``crossval``, ``quality`` and ``pipeline`` call, and in ``report``); importing the package or
``board``, ``draw`` and ``corners`` does not load it.
"""
