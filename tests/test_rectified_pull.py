"""The first corners' outward pull against the rectified ones (rectified.bend_pull), on synthetic corners."""

import numpy as np

from lenticalib.calib.intrinsics.rectified import BEND_MIN_PX, BEND_T, bend_pull


class _Model:
    """What bend_pull reads of an mrcal cameramodel: the image size and the centre of projection."""

    def imagersize(self):
        return np.array([3000, 2000])

    def intrinsics(self):
        return "LENSMODEL_OPENCV5", np.array([2300.0, 2300.0, 1480.0, 990.0, -0.3, 0.1, 0.0, 0.0, 0.0])


def _corners(seed, pull_px, noise_px=0.012):
    """(refined, first): 20 photos of 11 x 6 corners spread over the image; the first ones moved
    outward by pull_px (r / R)^2 and both given noise."""
    rng = np.random.default_rng(seed)
    refined = np.stack([np.stack(np.meshgrid(np.linspace(100 + 40 * k, 2800 - 30 * k, 11),
                                             np.linspace(80 + 20 * k, 1900 - 25 * k, 6)), axis=-1)
                        for k in range(20)])
    offset = refined - np.array([1480.0, 990.0])
    r = np.linalg.norm(offset, axis=-1, keepdims=True)
    first = refined + pull_px * (r / np.hypot(1500, 1000)) ** 2 * offset / r
    first = first + rng.normal(0, noise_px, first.shape)
    refined = refined + rng.normal(0, noise_px, refined.shape)
    first[3, 0, 0] = np.nan  # a corner the first pass dropped
    return first, refined


def test_an_outward_pull_like_a_barrel_lens_bend_is_found():
    first, refined = _corners(1, 0.035)
    pull = bend_pull(first, refined, _Model())
    assert abs(pull["pull_px"] - 0.035) < 0.005 and pull["t"] > 3 * BEND_T, pull
    assert pull["pull_px"] > BEND_MIN_PX and pull["corners"] == 20 * 66 - 1


def test_no_pull_or_an_inward_one_does_not_count():
    for seed, px in ((2, 0.0), (3, -0.03)):
        pull = bend_pull(*_corners(seed, px), _Model())
        assert not (pull["t"] > BEND_T and pull["pull_px"] > BEND_MIN_PX), pull
