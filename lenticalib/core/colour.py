"""The sRGB transfer curve (IEC 61966-2-1) and its 8-bit form: the one copy every layer uses.

    encode  v = 12.92 L                      for L <= 0.0031308
            v = 1.055 L ** (1 / 2.4) - 0.055 otherwise
    decode  L = v / 12.92                    for v <= 0.04045
            L = ((v + 0.055) / 1.055) ** 2.4 otherwise

``L`` is linear light and ``v`` the encoded value, both in [0, 1] (inputs are clipped to it).
The functions take numpy arrays (or numpy scalars) and keep their float dtype; they also take
torch tensors (the render loop works in linear light on the GPU) and return tensors, without
importing torch themselves.
"""

from __future__ import annotations

import numpy as np

_ENCODE_KNEE = 0.0031308  # linear light
_DECODE_KNEE = 0.04045  # encoded value
_SLOPE = 12.92
_GAMMA = 2.4


def srgb_encode(linear):
    """Linear light in [0, 1] -> sRGB-encoded values in [0, 1]; any shape, numpy or torch."""
    if _is_tensor(linear):
        x = linear.clamp(0.0, 1.0)
        return (_SLOPE * x).where(x <= _ENCODE_KNEE, 1.055 * x ** (1 / _GAMMA) - 0.055)
    linear = np.clip(linear, 0.0, 1.0)
    return np.where(linear <= _ENCODE_KNEE, _SLOPE * linear, 1.055 * np.power(linear, 1 / _GAMMA) - 0.055)


def srgb_decode(encoded):
    """sRGB-encoded values in [0, 1] -> linear light in [0, 1]; any shape, numpy or torch."""
    if _is_tensor(encoded):
        x = encoded.clamp(0.0, 1.0)
        return (x / _SLOPE).where(x <= _DECODE_KNEE, ((x + 0.055) / 1.055) ** _GAMMA)
    encoded = np.clip(encoded, 0.0, 1.0)
    return np.where(encoded <= _DECODE_KNEE, encoded / _SLOPE, np.power((encoded + 0.055) / 1.055, _GAMMA))


def srgb_encode8(linear) -> np.ndarray:
    """Linear light (any shape, clipped to [0, 1]) -> uint8 sRGB codes, rounded to the nearest
    (half to even): what the patterns and the compensation table write."""
    return np.rint(255.0 * srgb_encode(linear)).astype(np.uint8)


def srgb_decode_lut() -> np.ndarray:
    """Linear light of the 256 uint8 sRGB codes: float64 ``(256,)``, indexed by the code."""
    return srgb_decode(np.arange(256) / 255.0)


def _is_tensor(value) -> bool:
    return type(value).__module__.startswith("torch")
