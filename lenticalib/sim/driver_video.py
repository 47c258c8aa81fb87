"""A training video for the student driver that needs no person and no tracker: the demo avatar's
front view under a known control sequence, with its true controls.

:func:`driver_motion` draws a smooth random control sequence (seeded): head turns (yaw within
+-YAW_DEG, pitch, roll), talking (the jaw, in phrases), blinks, the demo's expressions (smile,
frown, mouth wide or pucker, one at a time; raised brows with any of them) and small head
translations.  :func:`make_driver_video` renders each frame with the ``cpu`` renderer from one
camera in front of the avatar, over a textured background (smooth coloured noise drawn from
``room``: the same room for a subject's training and test videos, as a user records and calls
from one place), shakes the camera by a pixel or two (what a tracker's crop jitter looks like),
adds sensor noise and saves every frame as a JPEG, with the true controls as ``controls.csv``
(one row per frame) and ``video.json`` (the seed, the size, the face's box in the frames
(:func:`face_box`): the crop a student should use).

    DIR/frame-00000.jpg ...   the frames, FPS frames a second
    DIR/controls.csv          t and the true control vector of every frame (columns GROUP.I)
    DIR/video.json            {"seed", "room", "frames", "fps", "size", "face_box": [x, y, w, h], ...}
"""

from __future__ import annotations

import json
import math
import os
from pathlib import Path
from typing import Callable

import numpy as np

from ..core.files.atomic import write_bytes_atomic, write_text_atomic
from ..core.files.outputs import staged_folder
from ..render.cameras.models import make_cameras
from ..render.controls.records import write_controls_csv
from ..render.avatar.demo_avatar import make_demo_avatar
from ..render.renderers import render
from ..render.avatar.rig import DEFAULT_LAYOUT

FPS = 30.0
YAW_DEG, PITCH_DEG, ROLL_DEG = 25.0, 12.0, 8.0
MOUTH_EXPRESSIONS = (0, 1, 4, 5)  # smile, frown, mouth_wide, pucker: one at a time
BROWS_UP = 2
JAW_MAX = 0.22
EXPRESSION_PERIOD = 30  # frames between expression changes (1 s: a talking face)
SHAKE_PX = 2.0
NOISE = 0.02
FOV_DEG = 22.0  # the camera's vertical field of view: the head about half the frame's height
FACE_Y = (-0.105, 0.09)   # the demo avatar's chin and hairline heights (m, canonical frame)
FACE_Z = 0.03             # its front half
FACE_MARGIN = 0.08
CONTENTS = ("frame-[0-9]*.jpg", "controls.csv", "video.json")


def _smooth_noise(rng, n: int, period_frames: float) -> np.ndarray:
    """(n,) smooth noise in about [-1, 1]: random values every period, cubic-interpolated."""
    knots = rng.uniform(-1, 1, int(n / period_frames) + 4)
    x = np.arange(n) / period_frames + 1
    i = np.floor(x).astype(int)
    f = x - i
    p0, p1, p2, p3 = knots[i - 1], knots[i], knots[i + 1], knots[i + 2]
    return 0.5 * ((2 * p1) + (-p0 + p2) * f + (2 * p0 - 5 * p1 + 4 * p2 - p3) * f ** 2 + (-p0 + 3 * p1 - 3 * p2 + p3) * f ** 3)


def _mouth_expressions(rng, n: int) -> np.ndarray:
    """(n, 4) weights of MOUTH_EXPRESSIONS: every EXPRESSION_PERIOD frames the face holds one of
    them (or none, one time in five) at a strength of 0.3-1, and eases into the next (a cosine
    ramp over the period's first half); two overlap only while one fades into the other, as a
    face does not smile and frown at once (their mouth corners would cancel)."""
    knots = int(n / EXPRESSION_PERIOD) + 2
    held = np.zeros((knots, len(MOUTH_EXPRESSIONS)))
    pick = rng.integers(0, len(MOUTH_EXPRESSIONS) + 1, knots)
    strength = rng.uniform(0.3, 1.0, knots)
    for k in range(knots):
        if pick[k] < len(MOUTH_EXPRESSIONS):
            held[k, pick[k]] = strength[k]
    x = np.arange(n) / EXPRESSION_PERIOD
    i = np.floor(x).astype(int)
    ramp = 0.5 - 0.5 * np.cos(np.pi * np.clip(2 * (x - i), 0, 1))
    return held[i] + ramp[:, None] * (held[i + 1] - held[i])


def driver_motion(frames: int, seed: int) -> np.ndarray:
    """(frames, 70) float32 controls of the default layout (module docstring)."""
    rng = np.random.default_rng(seed)
    L = DEFAULT_LAYOUT
    c = np.zeros((frames, L.dim), dtype=np.float64)
    head = L.slice("head").start
    c[:, head] = math.radians(PITCH_DEG) * np.clip(_smooth_noise(rng, frames, 50), -1, 1)
    c[:, head + 1] = math.radians(YAW_DEG) * np.clip(_smooth_noise(rng, frames, 40), -1, 1)
    c[:, head + 2] = math.radians(ROLL_DEG) * np.clip(_smooth_noise(rng, frames, 60), -1, 1)
    talk = np.clip(_smooth_noise(rng, frames, 45) + 0.3, 0, 1)                      # phrases
    syllable = 0.5 - 0.5 * np.cos(2 * math.pi * np.cumsum(rng.uniform(3, 5, frames)) / FPS)
    c[:, L.slice("jaw").start] = JAW_MAX * talk * syllable
    c[:, L.slice("expression")][:, list(MOUTH_EXPRESSIONS)] = _mouth_expressions(rng, frames)
    c[:, L.slice("expression").start + BROWS_UP] = np.clip(_smooth_noise(rng, frames, EXPRESSION_PERIOD), 0, 1)
    t = np.arange(frames) / FPS
    blink = np.zeros(frames)
    for at in np.cumsum(rng.uniform(2.0, 5.0, int(frames / FPS / 2) + 2)):
        blink = np.maximum(blink, np.exp(-(((t - at) / 0.06) ** 2)))
    c[:, L.slice("eyelids")] = blink[:, None]
    tr = L.slice("translation").start
    c[:, tr] = 0.008 * _smooth_noise(rng, frames, 80)
    c[:, tr + 1] = 0.005 * _smooth_noise(rng, frames, 90)
    return c.astype(np.float32)


def _background(rng, width: int, height: int) -> np.ndarray:
    """(H, W, 3) float32 smooth coloured noise in 0.15..0.85 (a room behind the subject)."""
    import cv2

    out = np.zeros((height, width, 3), np.float32)
    for scale, amp in ((90, 0.6), (30, 0.3), (10, 0.12)):
        small = rng.uniform(0, 1, (max(2, height // scale), max(2, width // scale), 3)).astype(np.float32)
        out += amp * cv2.resize(small, (width, height), interpolation=cv2.INTER_CUBIC)
    out = (out - out.min()) / max(float(out.max() - out.min()), 1e-6)
    return 0.15 + 0.7 * out


def face_box(rig, cams, width: int, height: int) -> list[int]:
    """[x, y, w, h] int, frame pixels: the square that holds the face (FACE_Y, FACE_Z of the rig's
    canonical frame, metres: chin to hairline, the front half) under every extreme head pose of
    :func:`driver_motion` (yaw, pitch and roll at their limits, alone and together), grown by
    FACE_MARGIN; the same for every motion, so a training and a test video share it."""
    head = DEFAULT_LAYOUT.slice("head").start
    means = rig.canonical.to_numpy().means
    face = (means[:, 1] > FACE_Y[0]) & (means[:, 1] < FACE_Y[1]) & (means[:, 2] > FACE_Z)
    lo, hi = np.array([np.inf, np.inf]), np.array([-np.inf, -np.inf])
    for pitch in (-1, 0, 1):
        for yaw in (-1, 0, 1):
            for roll in (-1, 0, 1):
                c = np.zeros(DEFAULT_LAYOUT.dim, np.float32)
                c[head:head + 3] = np.radians([pitch * PITCH_DEG, yaw * YAW_DEG, roll * ROLL_DEG])
                m = rig.deform(c).to_numpy().means[face].astype(np.float64)
                p = cams.viewmats[0, :3, :3] @ m.T + cams.viewmats[0, :3, 3:4]
                uv = np.stack([cams.K[0, 0, 0] * p[0] / p[2] + cams.K[0, 0, 2],
                               cams.K[0, 1, 1] * p[1] / p[2] + cams.K[0, 1, 2]], 1)
                lo, hi = np.minimum(lo, uv.min(0)), np.maximum(hi, uv.max(0))
    centre = (lo + hi) / 2
    side = min((1 + FACE_MARGIN) * float((hi - lo).max()), width, height)
    x = min(max(centre[0] - side / 2, 0), width - side)
    y = min(max(centre[1] - side / 2, 0), height - side)
    return [int(round(x)), int(round(y)), int(round(side)), int(round(side))]


def make_driver_video(directory: str | os.PathLike, frames: int = 1800, seed: int = 0, size: tuple[int, int] = (480, 360),
                      avatar=None, step: Callable[..., None] | None = None, room: int = 0) -> dict:
    """Write the video (module docstring) into ``directory`` (staged: complete or not at all):
    the motion, shake and noise from ``seed``, the background from ``room``; ``avatar`` a Rig
    (default: the demo avatar); returns the ``video.json`` record."""
    import cv2

    from .photo import encode_jpeg

    rig = avatar if avatar is not None else make_demo_avatar()
    W, H = size
    rng = np.random.default_rng(seed + 1000)
    controls = driver_motion(frames, seed)
    background = _background(np.random.default_rng([room, 7]), W, H)
    box_min, box_max = rig.canonical.to_numpy().bounding_box()
    cams = make_cameras("arc", (box_min, box_max), 1, view_size=(W, H), fov_deg=FOV_DEG, yaw_range_deg=1.0)
    box = face_box(rig, cams, W, H)
    record = {"seed": int(seed), "room": int(room), "frames": int(frames), "fps": FPS, "size": [W, H], "face_box": box,
              "camera": {"fov_deg": FOV_DEG, "radius": float(cams.params["r"])},
              "made_by": "lenticalib.sim.driver_video.make_driver_video"}
    with staged_folder(directory, "driver video", CONTENTS, inputs=()) as stage:  # drawn from objects, no file read
        for k in range(frames):
            g = rig.deform(controls[k]).to_numpy()
            rgba = render(g, cams.viewmats, cams.K, W, H)[0]
            img = rgba[..., :3] + (1 - rgba[..., 3:4]) * background
            dx, dy = rng.normal(0, SHAKE_PX / 2, 2)
            img = cv2.warpAffine(img, np.array([[1, 0, dx], [0, 1, dy]], np.float32), (W, H),
                                 borderMode=cv2.BORDER_REFLECT)
            img = np.clip(img + rng.normal(0, NOISE, img.shape).astype(np.float32), 0, 1)
            write_bytes_atomic(Path(stage) / f"frame-{k:05d}.jpg", encode_jpeg((img * 255 + 0.5).astype(np.uint8), 92))
            if step is not None:
                step()
        write_controls_csv(Path(stage) / "controls.csv", np.arange(frames) / FPS, controls, DEFAULT_LAYOUT)
        write_text_atomic(Path(stage) / "video.json", json.dumps(record, indent=2) + "\n")
    return record
