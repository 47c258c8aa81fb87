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
    looking_glass       Looking Glass formats: ``visual.json`` read and converted, the vendor's
                        lenticular rule (our oracle), the models and their quilts
    view_defaults       a render's defaults for a panel: view size, view count, camera arc

Errors and user input
    errors              the one exception tree (``LenticalibError``, ``InputError`` ...)
    sizes               the one ``WxH`` parser, the size limits and the raster-size check
    terminal_text       text from outside made safe for a terminal: controls escaped, long values cut

Files and documents
    files               every input opened bounded, every output atomic: input files, outputs,
                        the document envelope and its field checks, arrays, images, videos
    crosstalk_document  ``crosstalk.json``'s format and reader (the mixing matrix)
    identity            a panel profile's identity; results of different panels refused together
    pattern_sets        pattern-set folders: the PNGs and their manifest ``patterns.json``
    colour              the sRGB transfer curve (IEC 61966-2-1) and its 8-bit form
    figures             report figures: one style, one atomic PNG writer, the record of what they say

Shared machinery
    plugins             the one loader behind every registry of backends by name (entry points)
    jit                 numba's njit with the compiled kernels cached on disk (silently not, where no folder is writable)
    slides              what ``show`` and ``capture`` step through: an image, a pattern set, a
                        folder

The layers and their rule: ``docs/architecture.md``.
"""
