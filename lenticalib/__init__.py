"""lenticalib: calibration, device access and encoding for slanted-lenticular 3D panels.

Packages, one layer each:

    core    what every layer shares: the panel profile, routing, errors, documents, atomic
            output, image and array files, sizes, the plug-in loader, Looking Glass files
    calib   the fit of a panel profile from camera photos of test patterns; capture cameras,
            per-view crosstalk and the camera's own (mrcal) calibration
    render  N views -> the panel raster (encoders), the Gaussian avatar and its renderers,
            crosstalk pre-compensation, pixel-exact presentation
    device  panel controllers: read, flash and verify their calibration record over serial,
            HID, USB or an emulated controller
    sim     the virtual panel: a physically based panel photographed by a virtual camera, with
            the ground truth of every synthetic set
    cli     the ``lenticalib`` console script, one small module per subcommand

Layers import only downward: core imports none of the other layers; calib, render and device
import only core; sim may import core, calib and render; cli sits on top and nothing imports it.
``__main__`` runs the console script (``python -m lenticalib``).  The layers, their rule and how
it is checked are in ``docs/architecture.md``.
"""

__version__ = "0.1.0"
