"""The level photos' colour channels: which of them each level's relation in the tone curve rests on.

A level photo lights every subpixel of one panel row in ``K``: in linear light each of the photo's
three channels holds ``1/K`` of white's (above black), whatever white's colour, because the rows it
lights show the same mix of the panel's colours as white does.  A camera's demosaicing need not
keep that for rows it resolves: OpenCV's edge-aware one (the bench's phones) took a quarter of the
green channel's light off 1-in-8 rows of bench hard cases 4, 5, 7 and 8 (linear photos: green 0.77
of its share, red and blue 0.99) and little off the others, and a 4:2:0 JPEG moved part of that
deficit into red and blue (under the camera's true curve: red 1.03-1.05, green 0.71-0.84, blue
1.01-1.03).  A tone curve fitted to the three channels pooled bent its mid-tones to follow the
green's loss (the own-view share 0.010-0.013 low).  So each level's share is read per channel
under the curve fitted with the channels pooled, and where the channel furthest from the middle
one is more than ``OUTLIER`` from it, the level's relation rests on the other two (their white and
black photos' same channels with them): one channel that lost light is outvoted by the two that
did not.  Where the three agree the relation stays on all of them (a single channel, the middle
one, put bench hard case 6, whose levels lost 2 % in every channel, 0.0117 off for 0.0104).

Channels are the photos' own (0, 1, 2: R, G, B as the photo files hold them).  Histogram keys:
:func:`channel_key` names a photo's histogram over one level's chosen channel, and
:func:`photo_of` the photo a key is a histogram of (the exposures are the photo's).
"""

from __future__ import annotations

import numpy as np

from .tiles import tile_histograms

CHANNEL_NAMES = ("R", "G", "B")
OUTLIER = 0.05  # a channel's share this far from the middle one's: left out of the level's relation


def channel_key(photo: str, level: str) -> str:
    """The histogram key of ``photo`` ("white", "black" or the level itself) over the channel the
    relation of ``level`` rests on."""
    return f"{photo}@{level}"


def photo_of(key: str) -> str:
    """The photo a histogram key (a photo's name, or a :func:`channel_key`) is a histogram of."""
    return key.split("@", 1)[0]


def channel_light(image: np.ndarray, table: np.ndarray, tile: int, picked: np.ndarray) -> np.ndarray:
    """float (3,): each channel's light of ``image`` (uint8 (h, w, 3)) under the curve ``table``
    (float (256,)), summed over the ``picked`` tiles (flat indices of the ``tile`` x ``tile`` grid)."""
    h, w = image.shape[:2]
    hh, ww = h // tile, w // tile
    light = np.asarray(table, np.float64)[image[:hh * tile, :ww * tile]]
    return light.reshape(hh, tile, ww, tile, 3).sum(axis=(1, 3)).reshape(hh * ww, 3)[picked].sum(axis=0)


def channel_shares(level: np.ndarray, white: np.ndarray, black: np.ndarray, period: int) -> tuple[float, ...]:
    """Each channel's light of a level photo over its ``1/period`` of white's (above black), from the
    three photos' :func:`channel_light`: 1 where the channel kept it (NaN where white is not brighter)."""
    lit = white - black
    return tuple(float(period * (v - b) / d) if d > 0 else float("nan") for v, b, d in zip(level, black, lit))


def agreeing_channels(shares: tuple[float, float, float]) -> tuple[int, ...]:
    """The channels a level's relation rests on: all three, or the two left where the channel
    furthest from the middle share is more than ``OUTLIER`` from it (a NaN share is always left out)."""
    values = np.nan_to_num(np.asarray(shares, np.float64), nan=np.inf)
    middle = float(np.median(values))
    far = int(np.argmax(np.abs(values - middle)))
    if not abs(values[far] - middle) > OUTLIER:
        return (0, 1, 2)
    return tuple(c for c in range(3) if c != far)


def with_level_channels(hist: dict, images: dict[str, np.ndarray], table: np.ndarray, tile: int, picked: np.ndarray,
                        levels: tuple[str, ...], periods: tuple[int, ...]) -> tuple[dict, dict[str, dict]]:
    """(``hist`` with, for each level whose channels disagree, its relation's histograms over the
    agreeing channels added under :func:`channel_key` keys (:func:`.tiles.tile_histograms` of the
    ``picked`` tiles); the record: level -> {"channels", "shares"}), the shares under ``table`` (None
    for a channel whose white is not brighter than its black)."""
    out, record, made = dict(hist), {}, {}
    white, black = (channel_light(images[name], table, tile, picked) for name in ("white", "black"))
    for level, period in zip(levels, periods):
        shares = channel_shares(channel_light(images[level], table, tile, picked), white, black, period)
        used = agreeing_channels(shares)
        if len(used) < 3:
            for photo in ("white", "black", level):  # white's and black's made once per set of channels
                if (photo, used) not in made:
                    made[(photo, used)] = tile_histograms(images[photo][:, :, list(used)], tile, picked)
                out[channel_key(photo, level)] = made[(photo, used)]
        record[level] = {"channels": "".join(CHANNEL_NAMES[c] for c in used),
                         "shares": [round(v, 4) if np.isfinite(v) else None for v in shares]}
    return out, record
