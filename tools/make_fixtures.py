#!/usr/bin/env python3
"""Generate the bundled demo fixtures (deterministic; re-run to rebuild them).

    fixtures/panel-4k-32.json              an example profile of a 3840x2160, 32-view panel
    fixtures/demo_qs8x4a1.7778.png         a 32-view quilt (8x4 tiles of 480x270, view 0 bottom-left)
                                           of a synthetic scene with depth: views differ by parallax

    python tools/make_fixtures.py [--out fixtures]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import cv2
import numpy as np

from lenticalib.core.files.imageio import write_image
from lenticalib.core.profile import PanelProfile, make_provenance, save_profile
from lenticalib.core.view_direction import with_direction
from lenticalib.render.compose.views import QuiltGrid, make_quilt

DIRECTION_WHY = ("the demo panel is the modelled panel of docs/simulator.md (raster x along world x, lenses "
                 "focused on the pixel plane), whose truth_view_direction is always +1")

N, TILE_W, TILE_H = 32, 480, 270


def render_view(i: int) -> np.ndarray:
    """View i of a toy scene: background grid far, discs at several depths, a label; yaw -25..25 deg."""
    yaw = np.radians(-25 + 50 * i / (N - 1))
    img = np.zeros((TILE_H, TILE_W, 3), np.uint8)
    img[:] = (30, 36, 48)
    shift_far = -40 * np.sin(yaw)
    for x in range(-40, TILE_W + 40, 40):
        cv2.line(img, (int(x + shift_far), 0), (int(x + shift_far), TILE_H), (60, 70, 90), 1)
    for depth, colour, cx, cy, r in [(0.2, (220, 80, 60), 140, 120, 50), (0.5, (70, 200, 110), 260, 160, 42),
                                    (0.9, (80, 140, 240), 360, 110, 36)]:
        dx = int(round(120 * depth * np.sin(yaw)))
        cv2.circle(img, (cx + dx, cy), r, colour, -1, lineType=cv2.LINE_AA)
    cv2.putText(img, f"view {i:02d}", (12, TILE_H - 14), cv2.FONT_HERSHEY_SIMPLEX, 0.7, (240, 240, 240), 2, cv2.LINE_AA)
    return img[:, :, ::-1]  # RGB


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default="fixtures")
    args = parser.parse_args()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    profile = PanelProfile(views=N, slant=0.1835, period=19.47, offset=7.3, reference_view=16.0, width=3840,
                           height=2160, subpixel_order="RGB", name="example 4K 32-view panel",
                           provenance=make_provenance("example values for the demo; not a measured panel"))
    # the demo panel is the virtual panel of docs/simulator.md, whose view index always grows to the right
    profile = with_direction(profile, 1, "the virtual panel's truth", why=DIRECTION_WHY)
    save_profile(profile, out / "panel-4k-32.json")
    views = np.stack([render_view(i) for i in range(N)])
    write_image(out / "demo_qs8x4a1.7778.png", make_quilt(views, QuiltGrid(8, 4)))
    print(f"wrote {out}/panel-4k-32.json and {out}/demo_qs8x4a1.7778.png")


if __name__ == "__main__":
    main()
