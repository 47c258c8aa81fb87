"""lenticalib: calibration, device access and encoding for slanted-lenticular 3D panels."""

__version__ = "0.1.0"
