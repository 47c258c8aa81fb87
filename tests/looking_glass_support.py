"""Shared helpers for the Looking Glass unit tests: composed calibrations, emulated units, drives."""

from __future__ import annotations

import json
from pathlib import Path

from lenticalib.core.profile import PanelProfile

VIEWS = 45
STRIPE = {  # a first-generation calibration (configVersion 1.0), as a unit's EEPROM holds it
    "configVersion": "1.0", "serial": "LKG-2K-04321", "pitch": {"value": 49.91}, "slope": {"value": 5.45},
    "center": {"value": 0.042}, "viewCone": {"value": 40.0}, "invView": {"value": 1.0},
    "verticalAngle": {"value": 0.0}, "DPI": {"value": 338.0}, "screenW": {"value": 2560.0},
    "screenH": {"value": 1600.0}, "flipImageX": {"value": 0.0}, "flipImageY": {"value": 0.0},
    "flipSubp": {"value": 0.0},
}
CELLS = dict(  # a later calibration (configVersion 3.0): two cells alternating by column, mirrored image
    STRIPE, configVersion="3.0", serial="LKG-P-01234", slope={"value": -7.24467}, screenW={"value": 1536.0},
    screenH={"value": 2048.0}, invView={"value": 0.0}, flipImageX={"value": 1.0}, fringe={"value": 0.0},
    CellPatternMode={"value": 1.0}, subpixelCells=[
        {"ROffsetX": -0.25, "ROffsetY": -0.31, "GOffsetX": -0.25, "GOffsetY": 0.28, "BOffsetX": 0.25,
         "BOffsetY": 0.0},
        {"ROffsetX": 0.25, "ROffsetY": -0.31, "GOffsetX": 0.25, "GOffsetY": 0.28, "BOffsetX": -0.25,
         "BOffsetY": 0.0}])
CALIBRATIONS = {"stripe": STRIPE, "cells": CELLS}


def visual_bytes(visual: dict) -> bytes:
    """A visual.json's bytes as the vendor writes them (compact JSON)."""
    return json.dumps(visual, separators=(",", ":")).encode()


def make_drive(root: Path, text: bytes) -> Path:
    """A folder laid out as a unit's drive: ROOT/LKG_calibration/visual.json holding ``text``."""
    (root / "LKG_calibration").mkdir(parents=True)
    (root / "LKG_calibration" / "visual.json").write_bytes(text)
    return root


def without_provenance(profile: PanelProfile) -> dict:
    """The profile's document without its provenance: what two reads of one calibration share."""
    out = profile.to_dict()
    out.pop("provenance", None)
    return out
