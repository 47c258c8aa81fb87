"""The views stage: rendered views -> the 8-bit views an encoder samples, and where it samples them.

Importing this package loads nothing; each module imports what it needs.

    views         view inputs: a folder of N images, or a quilt (tiles, view 0 bottom-left)
    sampling      where each subpixel samples its view, and which view(s) it shows
    compensation  crosstalk pre-compensation: views sent so that each eye sees what it should
    host_views    the views stage on the host: background, edge desaturation, 8 bits, pre-compensation
    gl_views      the views stage on the GPU: background, edge desaturation, 8 bits, pre-compensation
"""
