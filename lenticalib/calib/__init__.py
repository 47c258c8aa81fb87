"""The calib layer: the fit of a panel profile from camera photos of test patterns.

calib imports only core (and itself).  Importing this package loads nothing; each module
imports numpy and OpenCV itself.

Patterns and photos
    patterns         the calibration test patterns and their manifest ``patterns.json``
    pattern_folders  pattern folders written whole (``lenticalib patterns``, ``crosstalk patterns``)
    direction        which way the view index runs: a LEFT/RIGHT pattern, or two fits compared
    acquire          guided capture: show each pattern, photograph it, check it at once
    captures         capture sets: one photo per pattern in ``DIR/captures/NAME.{jpg,png,tif}``
    checks           per-photo and per-set checks, each naming the photo and what to do

The fit, in the order it runs
    groups           photo groups: loaded, registered against camera shake, demodulated
    register         camera shake between photos, measured on the registration frame and undone
    phase            phase-shift demodulation, unwrapping and smoothing of the seen-coordinate maps
    photometric      the camera's tone response, cancelled where it biases the fringe phase
    model            the global model: the view-coordinate plane and the subpixel order
    order_photos     the subpixel order (order photos) and the layout (cell photos) against the fitted plane
    layout_fit       the subpixel layout (stripe or cells) from the cell photos, with its uncertainty
    uncertainty      jackknife plus floors, propagated into the profile's constants
    camera_file      a calibrated camera from a file (mrcal ``.cameramodel``, OpenCV YAML/JSON)
    pose             where the camera was (mm), from the panel's own pixel grid
    camera           the camera's intrinsics and pose estimated from the panel (or given by a file)
    physical_fit     the panel's physical constants from routing constants and camera poses
    fit              ``fit_capture_set``: one capture set -> a calibrated panel profile
    fit_pipeline     ``fit_capture_sets``: the whole of ``lenticalib fit`` as one library call
    report           the fit report: figures and ``summary.json`` next to a fitted profile
    compare          how far one profile is from another, in views (``docs/optics.md``)

Subpackages
    cameras          the capture cameras ``lenticalib capture`` triggers (gphoto2, OpenCV,
                     manual, the simulator's), behind one registry
    crosstalk        per-view crosstalk: sweep patterns, measurement from photos, ``crosstalk.json``
    fleet            a fleet of panels fitted on a Dask cluster (``lenticalib batch fit``): the task,
                     the inputs' identity for resuming, the summary and the fleet figure
    intrinsics       the camera's own calibration with mrcal, from photos of a chessboard
"""
