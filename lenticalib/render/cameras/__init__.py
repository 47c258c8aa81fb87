"""The view cameras: the N virtual cameras an avatar is rendered from, and their models by name.

Importing this package loads nothing; each module imports what it needs.

    view_cameras  the N virtual cameras: container, projection, near plane, view order, ``cameras.json``
    models        the arc and shear camera models, selected by name (``make_cameras``)
"""
