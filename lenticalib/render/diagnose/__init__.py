"""Judging an avatar for the panel: the LentiAvatar side-view diagnostics.

Importing this package loads nothing; each module imports what it needs.

    avatars       ``diagnose_avatars``: every view of the cone rendered and measured
    side_metrics  the LentiAvatar side-view metrics of one view (O_alpha ... E_c), the crop
    mesh_raster   the mesh mask: the pixels of each view the avatar's mesh covers
    report        the diagnostics' table, documents and figures
"""
