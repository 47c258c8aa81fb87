"""The sRGB curve (lenticalib.core.colour) against IEC 61966-2-1 values worked out by hand."""

from __future__ import annotations

import numpy as np

from lenticalib.core.colour import srgb_decode, srgb_decode_lut, srgb_encode, srgb_encode8

# (linear light, encoded value): the knee, its image, mid grey, the ends
GOLDEN = [(0.0, 0.0), (0.0031308, 0.040449936), (0.001, 0.01292), (0.18, 0.461356), (0.5, 0.735357),
          (1.0, 1.0)]


def test_encode_and_decode_give_the_standard_values():
    linear, encoded = np.array(GOLDEN).T
    np.testing.assert_allclose(srgb_encode(linear), encoded, atol=1e-6)
    np.testing.assert_allclose(srgb_decode(encoded), linear, atol=1e-6)
    np.testing.assert_allclose(srgb_encode(np.array([-0.5, 2.0])), [0.0, 1.0], atol=1e-12)  # clipped to [0, 1]


def test_eight_bit_codes_survive_decoding_and_encoding_again():
    lut = srgb_decode_lut()
    assert lut.shape == (256,) and lut.dtype == np.float64 and lut[0] == 0.0 and lut[255] == 1.0
    assert np.array_equal(srgb_encode8(lut), np.arange(256, dtype=np.uint8))
    assert srgb_encode8(np.float64(0.5)) == 188  # 255 * 0.735357 = 187.52


def test_torch_tensors_get_the_same_curve_in_their_own_dtype():
    import torch

    values = np.linspace(0.0, 1.0, 1001)
    for dtype in (torch.float32, torch.float64):
        tensor = torch.tensor(values, dtype=dtype)
        encoded, decoded = srgb_encode(tensor), srgb_decode(tensor)
        assert isinstance(encoded, torch.Tensor) and encoded.dtype == dtype
        np.testing.assert_allclose(encoded.numpy(), srgb_encode(values), atol=1e-6)
        np.testing.assert_allclose(decoded.numpy(), srgb_decode(values), atol=1e-6)
