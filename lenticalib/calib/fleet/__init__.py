"""A fleet of panels calibrated in one run on a Dask cluster: ``lenticalib batch fit``.

Part of the calib layer: imports only core and calib (and ``dask.distributed``, inside the
functions that run a cluster).  Modules, in the order a run uses them:

    identity   what a panel's result was made from: the fit options and a content hash of the
               capture folder, recorded in the panel folder's ``batch.json`` (resuming)
    task       ``fit_panel``: one panel's fit (``lenticalib fit``'s library call) into its folder,
               written whole; the task a Dask worker runs
    summary    ``summary.json`` and ``summary.csv``: one row per panel, the fleet's limits and outliers
    figure     ``fleet.png``: each constant across the panels, limits drawn, outliers named
    run        ``fit_fleet``: the whole of ``lenticalib batch fit`` as one library call

Usage and the numbers of a shift: ``docs/batch.md``.
"""
