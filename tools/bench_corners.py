#!/usr/bin/env python3
"""Chessboard corner accuracy against the simulator's truth: error, and its radial bias by radius.

For every photo of simulated print sets (folders that ``tools/bench_camera.py --keep DIR`` or
``lenticalib camera simulate`` wrote: ``captures/``, ``board.json``, ``truth.cameramodel``,
``simulation.json``), the corners that :func:`lenticalib.calib.intrinsics.corners.detect_photo`
returns are compared with the true corners (the board's points through the true pose and the
true lens; a corner whose true projection does not map back to its own ray, a ray from outside
the field that the lens polynomial folds into the frame, is left out).  Printed per set: corners
used, RMS error per coordinate, and the mean radial component of the error (px, + outward from
the distortion centre) in five bins of the distance from the centre (share of the half diagonal),
with its standard error: a systematic corner error that the solve cannot average away.

    python tools/bench_corners.py DIR/wide-1 DIR/strong-1 [--rectified] [--window 0.35] [--jobs 2]

The corners are those of the first pass (``cornerSubPix`` in the photo); ``--rectified`` locates
them once more in views rectified with the TRUE camera model
(:func:`lenticalib.calib.intrinsics.rectified.refine_rectified`; ``camera calibrate`` uses the model
of its first solve), printed as a second row, ``SET rect``: what that pass leaves.  ``--window`` sets ``corners.SUBPIX_WINDOW``
(the first pass's half-window as a share of the smallest square) to compare windows on the same photos.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

BINS = (0.0, 0.2, 0.4, 0.6, 0.8, 1.01)


def true_corners(folder: Path):
    """{photo name: (rows, cols, 2) true pixel corners, NaN where not seen}, the board, the truth model."""
    import mrcal
    import numpy as np

    from lenticalib.calib.intrinsics.board import read_board
    from lenticalib.sim.board_set import read_truth_poses

    board = read_board(folder / "board.json")
    truth = mrcal.cameramodel(str(folder / "truth.cameramodel"))
    lensmodel, intrinsics = truth.intrinsics()
    points = board.object_points()
    out = {}
    for name, rt in read_truth_poses(folder).items():
        p = mrcal.transform_point_rt(rt, points)
        q = mrcal.project(p, lensmodel, intrinsics)
        back = mrcal.unproject(q, lensmodel, intrinsics, normalize=True)
        ray = p / np.linalg.norm(p, axis=-1, keepdims=True)
        q[np.linalg.norm(back - ray, axis=-1) > 1e-6] = np.nan
        out[name] = q
    return out, board, truth


def measure(folder: Path, jobs: int, rectified: bool = False) -> list[dict]:
    """The statistics (:func:`stats`) of the first pass's corners of the set in ``folder``, and with
    ``rectified`` of the same corners located again in views rectified with the true model."""
    import numpy as np

    from lenticalib.calib.intrinsics.corners import detect_photos

    truth, board, model = true_corners(folder)
    names = sorted(truth)
    found = detect_photos([folder / "captures" / n for n in names], board, jobs=jobs)
    corners = {n: f.corners for n, f in zip(names, found) if f.corners is not None}
    rows = [stats(f"{folder.name}", corners, truth, model)]
    if rectified:
        from lenticalib.calib.intrinsics.rectified import refine_photos

        again = refine_photos([folder / "captures" / n for n in corners], np.stack(list(corners.values())), board,
                              model)
        rows.append(stats(f"{folder.name} rect", dict(zip(corners, again)), truth, model))
    return rows


def stats(label: str, corners: dict, truth: dict, model) -> dict:
    """Corners used, RMS and worst error (px) of ``corners`` ({photo: (rows, cols, 2)}) against
    ``truth``, and the mean radial error +- its standard error in the bins of ``BINS``."""
    import numpy as np

    w, h = model.imagersize()
    cx, cy = model.intrinsics()[1][2:4]
    half = 0.5 * float(np.hypot(w, h))
    errors, radii, radial = [], [], []
    for name, c in corners.items():
        t = truth[name]
        ok = np.isfinite(c[..., 0]) & np.isfinite(t[..., 0])
        e = c[ok] - t[ok]
        d = t[ok] - [cx, cy]
        r = np.linalg.norm(d, axis=-1)
        errors.append(e)
        radii.append(r / half)
        radial.append(np.sum(e * d, axis=-1) / np.maximum(r, 1e-9))
    e, r, rad = np.concatenate(errors), np.concatenate(radii), np.concatenate(radial)
    bins = []
    for lo, hi in zip(BINS[:-1], BINS[1:]):
        pick = (r >= lo) & (r < hi)
        n = int(pick.sum())
        bins.append((float(rad[pick].mean()) if n else float("nan"),
                     float(rad[pick].std() / np.sqrt(n)) if n > 1 else float("nan"), n))
    return {"set": label, "photos": len(corners), "corners": len(e),
            "rms": float(np.sqrt(np.mean(e * e))), "worst": float(np.linalg.norm(e, axis=-1).max()), "bins": bins}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("sets", nargs="+", help="folders of simulated print sets")
    ap.add_argument("--window", type=float, default=None, help="cornerSubPix half-window, share of a square")
    ap.add_argument("--rectified", action="store_true",
                    help="locate the corners once more in views rectified with the true model")
    ap.add_argument("--jobs", type=int, default=2, help="photos searched in parallel")
    a = ap.parse_args(argv)
    from lenticalib.calib.intrinsics import corners

    if a.window is not None:
        corners.SUBPIX_WINDOW = a.window
    head = "".join(f"{f'r {lo:.1f}-{min(hi, 1.0):.1f}':>17}" for lo, hi in zip(BINS[:-1], BINS[1:]))
    print("corner error against the truth (px): RMS per coordinate, worst; mean radial error (+ outward) "
          "+- its standard error by distance from the centre (share of the half diagonal)")
    print(f"{'set':<12}{'photos':>7}{'corners':>8}{'rms':>7}{'worst':>7}{head}")
    for folder in a.sets:
        for m in measure(Path(folder), a.jobs, a.rectified):
            cells = "".join(f"{mean:>+10.4f}+-{se:.4f}" for mean, se, _ in m["bins"])
            print(f"{m['set']:<12}{m['photos']:>7}{m['corners']:>8}{m['rms'] / 2 ** 0.5:>7.3f}{m['worst']:>7.3f}{cells}",
                  flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
