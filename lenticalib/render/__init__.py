"""The render layer: from a Gaussian avatar and a calibrated profile to pixels on the panel.

render imports only core (and itself).  Importing this package loads nothing; modules import
numpy, numba, torch, OpenCV, glfw and moderngl themselves, most only when used.

Stage packages, top to bottom (a layered import contract in ``pyproject.toml`` keeps the order:
a package imports only the ones below it; packages on one line never import each other)

    pipeline     composition only: the avatar frame (host and GL), the session, live and offline
                 loops, ``encode_to_file``, quilt playback
    diagnose     the LentiAvatar side-view diagnostics of an avatar along the view cone
    present      presenters by name: a full-screen window, offscreen, none
    student      the student driver: a network trained per subject, camera frames -> controls
    controls     control sources by spec (files, streams, the demo motion, plug-ins) and their records
    encoders     N views ``(N, H_v, W_v, 3)`` -> one panel raster, by name
    renderers    Gaussians + N cameras -> N RGBA views, by name
    compose      the views stage (host and GPU), view inputs, sampling tables, pre-compensation
    cameras      the N virtual view cameras and their models by name
    avatar       what is drawn: Gaussians, PLY, meshes, rigs and their deformation, the demo head
    gpu          GPU contexts only: OpenGL contexts, CUDA-OpenGL interop, torch devices, monitors

The layers and their rule: ``docs/architecture.md``.
"""
