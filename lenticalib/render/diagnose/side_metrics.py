"""The LentiAvatar side-view diagnostics of one rendered view: six lower-is-better artifact
measures and one contour sharpness (the paper's "Evaluation metrics", Tables 1 and 2).

Inputs, per view, all (H, W) in the view's pixels (OpenCV: y down, pixel centres at integers):
colour C (H, W, 3) in 0..1 composited over black (premultiplied, as every renderer returns it),
alpha A (H, W) in 0..1, and the mesh mask M (H, W) bool (:mod:`.mesh_raster`).  Derived maps:

    D   = M dilated by :data:`DILATION_PX` pixels (a disc of that radius: every pixel within
          9 px of the mesh)
    P   = 1[A > :data:`SUPPORT_ALPHA`] (0.03), the rendered support
    B   = the boundary of P: pixels of P with a 4-neighbour outside P (one pixel wide, inside)
    s   = HSV saturation of C, (max - min) / max over R, G, B (0 where max = 0); it does not
          change with the premultiplication by alpha
    |grad C|_1 = sum over R, G, B of |dC/dx| + |dC/dy| (central differences, per pixel)
    N   = the neck-rear region {0.46 <= y/H <= 0.90 and (x/W <= 0.42 or x/W >= 0.58)}, with
          (x, y) the pixel centre in the crop, H and W the crop's size

and, with WM(v, w) = sum(w v) / sum(w) the weighted mean (0 when sum(w) = 0):

    O_alpha = sum A (1 - D) / sum A                        outside-support opacity
    G_m     = sum_N A (1 - D) / sum A                      neck-rear ghost mass
    G_d     = sum_N A (1 - D) / |N|                        neck-rear ghost density
    S_n     = sum_N 4 A (1 - A) / |N|                      translucent smear in the neck region
    S_alpha = sum 4 A (1 - A) D / sum D                    translucent smear on the support
    F_c     = 0.45 WM(s, B A) + 0.35 WM(s, A (1 - D)) + 0.20 WM(s, 4 A (1 - A) D)   colour fringe heat
    E_c     = WM(|grad C|_1, B A)                          side-contour edge energy (higher: sharper)

Sums run over the *crop* (:class:`Crop`), the same rectangle in every view of an avatar
(:func:`crop_rule`): the box around the mesh mask over all views, grown by :data:`CROP_MARGIN`
of its larger side (at least the dilation plus two pixels) and kept inside the image.  The maps
are computed on the crop and one pixel around it (the neighbours the boundary and the
differences need), so the crop's edge changes nothing but what is summed.
"""

from __future__ import annotations

import dataclasses

import numpy as np

DILATION_PX = 9
SUPPORT_ALPHA = 0.03
NECK_REAR = (0.46, 0.90, 0.42, 0.58)  # y/H from, y/H to, x/W at most, x/W at least
CROP_MARGIN = 0.25
F_C_WEIGHTS = (0.45, 0.35, 0.20)
METRICS = ("O_alpha", "G_m", "G_d", "S_n", "S_alpha", "F_c", "E_c")
HIGHER_IS_BETTER = frozenset({"E_c"})
METRIC_MEANINGS = {
    "O_alpha": "outside-support opacity", "G_m": "neck-rear ghost mass", "G_d": "neck-rear ghost density",
    "S_n": "neck-region translucent smear", "S_alpha": "support translucent smear", "F_c": "colour fringe heat",
    "E_c": "side-contour edge energy",
}


@dataclasses.dataclass(frozen=True)
class Crop:
    """The rectangle of a view the metrics sum over: columns x0..x1-1, rows y0..y1-1 (pixels)."""

    x0: int
    y0: int
    x1: int
    y1: int

    @property
    def width(self) -> int:
        return self.x1 - self.x0

    @property
    def height(self) -> int:
        return self.y1 - self.y0

    def slices(self) -> tuple[slice, slice]:
        return slice(self.y0, self.y1), slice(self.x0, self.x1)

    def as_dict(self) -> dict:
        return {"x0": self.x0, "y0": self.y0, "x1": self.x1, "y1": self.y1,
                "rule": f"box of the mesh mask over all views, grown by {CROP_MARGIN:.0%} of its larger side "
                        f"(at least {DILATION_PX + 2} px), inside the image"}


def crop_rule(masks: np.ndarray) -> Crop:
    """The crop of an avatar's views (module docstring) from its mesh masks (N, H, W) bool; the
    whole view when no mask pixel is set."""
    _, H, W = masks.shape
    any_y = np.flatnonzero(masks.any(axis=(0, 2)))
    any_x = np.flatnonzero(masks.any(axis=(0, 1)))
    if not len(any_y):
        return Crop(0, 0, W, H)
    x0, x1, y0, y1 = int(any_x[0]), int(any_x[-1]) + 1, int(any_y[0]), int(any_y[-1]) + 1
    grow = max(int(np.ceil(CROP_MARGIN * max(x1 - x0, y1 - y0))), DILATION_PX + 2)
    return Crop(max(x0 - grow, 0), max(y0 - grow, 0), min(x1 + grow, W), min(y1 + grow, H))


def neck_rear_region(height: int, width: int) -> np.ndarray:
    """(height, width) bool: the neck-rear region N of a crop of that size (module docstring)."""
    y0, y1, left, right = NECK_REAR
    y = (np.arange(height) + 0.5) / height
    x = (np.arange(width) + 0.5) / width
    rows = (y >= y0) & (y <= y1)
    cols = (x <= left) | (x >= right)
    return rows[:, None] & cols[None, :]


def dilate(mask: np.ndarray, radius: int = DILATION_PX) -> np.ndarray:
    """(H, W) bool: every pixel within ``radius`` pixels (Euclidean, centre to centre) of ``mask``."""
    import cv2

    r = int(radius)
    yy, xx = np.mgrid[-r:r + 1, -r:r + 1]
    disc = ((xx * xx + yy * yy) <= r * r).astype(np.uint8)
    return cv2.dilate(mask.astype(np.uint8), disc, borderType=cv2.BORDER_CONSTANT, borderValue=0).astype(bool)


def alpha_boundary(alpha: np.ndarray, edge_outside: bool = True) -> np.ndarray:
    """(H, W) bool: pixels with alpha > :data:`SUPPORT_ALPHA` that have a 4-neighbour at or below it.
    Beyond the array's edge counts as outside the support (``edge_outside``, a whole view) or as
    the edge pixel itself (a part of a view whose neighbours are not known)."""
    P = alpha > SUPPORT_ALPHA
    padded = np.pad(P, 1, constant_values=False) if edge_outside else np.pad(P, 1, mode="edge")
    inner = padded[:-2, 1:-1] & padded[2:, 1:-1] & padded[1:-1, :-2] & padded[1:-1, 2:]
    return P & ~inner


def saturation(colour: np.ndarray) -> np.ndarray:
    """(H, W) HSV saturation of colour (H, W, 3): (max - min) / max, 0 where max is 0."""
    hi = colour.max(-1)
    lo = colour.min(-1)
    return np.divide(hi - lo, hi, out=np.zeros_like(hi), where=hi > 0)


def gradient_l1(colour: np.ndarray) -> np.ndarray:
    """(H, W) sum over channels of |dC/dx| + |dC/dy|, central differences (one-sided at the edges)."""
    gy, gx = np.gradient(colour, axis=(0, 1))
    return (np.abs(gx) + np.abs(gy)).sum(-1)


def weighted_mean(values: np.ndarray, weights: np.ndarray) -> float:
    total = float(weights.sum())
    return float((weights * values).sum() / total) if total > 0 else 0.0


def view_metrics(colour: np.ndarray, alpha: np.ndarray, mask: np.ndarray, crop: Crop) -> dict[str, float]:
    """The seven metrics of one view (module docstring), as {name: value} in :data:`METRICS` order.

    ``colour`` (H, W, 3) and ``alpha`` (H, W) float in 0..1 (colour over black), ``mask`` (H, W)
    bool, ``crop`` the avatar's :class:`Crop`.
    """
    H, W = np.shape(alpha)
    # the maps need one pixel around the crop (the boundary's neighbours, central differences);
    # the mask has no pixel within the crop's margin of its edge, so its dilation is exact here
    y0, y1, x0, x1 = max(crop.y0 - 1, 0), min(crop.y1 + 1, H), max(crop.x0 - 1, 0), min(crop.x1 + 1, W)
    C = np.asarray(colour[y0:y1, x0:x1], dtype=np.float32)
    A = np.clip(np.asarray(alpha[y0:y1, x0:x1], dtype=np.float32), 0.0, 1.0)
    D = dilate(np.asarray(mask[y0:y1, x0:x1], dtype=bool))
    B = alpha_boundary(A, edge_outside=False)
    s = saturation(C)
    grad = gradient_l1(C)
    inner = (slice(crop.y0 - y0, crop.y1 - y0), slice(crop.x0 - x0, crop.x1 - x0))
    A, s, grad = A[inner].astype(np.float64), s[inner].astype(np.float64), grad[inner].astype(np.float64)
    D, B = D[inner].astype(np.float64), B[inner].astype(np.float64)
    N = neck_rear_region(crop.height, crop.width)
    outside = A * (1.0 - D)
    smear = 4.0 * A * (1.0 - A)
    total_alpha = float(A.sum())
    n_area = max(int(N.sum()), 1)
    d_area = float(D.sum())
    f1, f2, f3 = F_C_WEIGHTS
    return {
        "O_alpha": float(outside.sum() / total_alpha) if total_alpha > 0 else 0.0,
        "G_m": float(outside[N].sum() / total_alpha) if total_alpha > 0 else 0.0,
        "G_d": float(outside[N].sum() / n_area),
        "S_n": float(smear[N].sum() / n_area),
        "S_alpha": float((smear * D).sum() / d_area) if d_area > 0 else 0.0,
        "F_c": f1 * weighted_mean(s, B * A) + f2 * weighted_mean(s, outside) + f3 * weighted_mean(s, smear * D),
        "E_c": weighted_mean(grad, B * A),
    }
