"""Presentation: panel rasters shown pixel-exact, in a window, offscreen or nowhere, by name.

Importing this package loads nothing; each module imports what it needs.

    base       the presenters' base: ``Presenter``, ``FrameTiming``, ``RASTER_HINT``
    window     pixel-exact full-screen presentation on a monitor (glfw + moderngl)
    displays   presenters by display spec: the registry (``PRESENTERS``) and ``open_presenter``
    offscreen  presenters with no window: an offscreen framebuffer, or no graphics
"""
