"""The render layer: from a calibrated profile and N rendered views to the panel raster.

    routing    the LentiAvatar routing rule: which view each subpixel shows (canonical 64-bit fixed point)
    sampling   sample points and per-profile sampling tables
    views      view sets: quilts (grid from the file name) and folders of view images
    encoders   N views -> one panel raster, selected by name through a lazy registry
    cameras    the N virtual cameras of the avatar renderer: container, projection, view order, cameras.json
    camera_models  the arc and shear camera models, selected by name (make_cameras)

Later the presenter and the avatar renderer join it.  Modules import numpy and numba
themselves; importing this package loads nothing.
"""
