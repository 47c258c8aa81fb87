"""The core layer: what every other layer of lenticalib shares.

core imports none of the other layers (calib, render, device, sim, cli); each of them may
import it.  Importing this package loads nothing; each module imports what it needs.

The panel profile and its routing
    profile             ``PanelProfile``: the routing constants of one panel, as JSON (load,
                        save, provenance)
    physical            the profile's optional physical block: lenses and pixels in millimetres
    layout              subpixel layouts: each channel's position per cell and the cell pattern
    routing             which view each subpixel shows: the LentiAvatar rule (``docs/routing.md``)
    view_direction      which way the view index runs: said for people, parsed, warned about
    retarget            routing constants carried to another eye position
    lkg                 Looking Glass ``visual.json``: import to and export from panel profiles
    lkg_file            reading a ``visual.json``: unwrapped and every field validated
    lkg_rule            our port of the Looking Glass lenticular rule, the oracle for ``lkg``
    lkg_models          Looking Glass models by serial prefix and the quilt each renders (vendor's table)
    view_defaults       a render's defaults for a panel: view size, view count, camera arc

Errors and user input
    errors              the one exception tree (``LenticalibError``, ``InputError`` ...)
    fields              checks every document reader shares: finite numbers, known key names
    sizes               the one ``WxH`` parser, the size limits and the raster-size check
    terminal_text       text from outside made safe for a terminal: controls escaped, long values cut

Files and documents
    input_files         every input file opened bounded: a regular file (no FIFO, device) within a size cap
    atomic              atomic file output: a reader sees the old file or the new one
    outputs             output files and folders checked before the work, folders staged whole
    documents           the one document envelope (format, version), its table and its reader
    crosstalk_document  ``crosstalk.json``'s format and reader (the mixing matrix)
    identity            a panel profile's identity; results of different panels refused together
    pattern_sets        pattern-set folders: the PNGs and their manifest ``patterns.json``
    arrayfile           ``.npy`` and ``.npz`` files read with every header checked first
    imageio             images as RGB numpy arrays ``(H, W, 3)``: read and written (atomically)
    video               video files opened through OpenCV, their stated frame size and count checked first
    colour              the sRGB transfer curve (IEC 61966-2-1) and its 8-bit form
    figures             report figures: one style, one atomic PNG writer, the record of what they say

Shared machinery
    plugins             the one loader behind every registry of backends by name (entry points)
    jit                 numba's njit with the compiled kernels cached on disk (silently not, where no folder is writable)
    slides              what ``show`` and ``capture`` step through: an image, a pattern set, a
                        folder

The layers and their rule: ``docs/architecture.md``.
"""
