"""The routing fit: capture sets -> a panel profile, in the order it runs.

Importing this package loads nothing; each module imports what it needs.

    checks        per-photo and per-set checks, each naming the photo and what to do
    groups        photo groups: loaded, registered against camera shake, demodulated
    photometric   the camera's tone response, cancelled where it biases the fringe phase
    model         the global model: the view-coordinate plane and the subpixel order
    order_photos  the subpixel order (order photos) and the layout (cell photos) against the fitted plane
    layout_fit    the subpixel layout (stripe or cells) from the cell photos, with its uncertainty
    uncertainty   jackknife plus floors, propagated into the profile's constants
    physical_fit  the panel's physical constants from routing constants and camera poses
    direction     which way the view index runs: a LEFT/RIGHT pattern, or two fits compared
    fit           ``fit_capture_set``: one capture set -> a calibrated panel profile
    fit_pipeline  ``fit_capture_sets``: the whole of ``lenticalib fit`` as one library call
    report        the fit report: figures and ``summary.json`` next to a fitted profile
    compare       how far one profile is from another, in views (``docs/optics.md``)
"""
