"""``distill_student``: a subject's frames and its teacher controls -> a trained student driver.

Every input is checked before training starts, in this order: the output path, the rig's layout,
the frames, the teacher controls (read in full), their match, the crop, the device, the backbone
weights.  Then:

1. **Matching.**  The same number of frames and control samples: by index.  Otherwise by time:
   frame k at k / fps seconds (a folder: 30 fps), the controls interpolated there; frames past
   the controls' last time (by more than one frame) are refused in one line.
2. **Crops.**  Every frame's crop (:mod:`.crop`) grown by :data:`JITTER` on each side, resized to
   ``input_size * (1 + 2 JITTER)`` and kept as uint8; training cuts a random square of
   ``input_size`` (1 +- SIZE_JITTER) out of it anywhere (the tracker's jitter in place and size),
   validation the centred ``input_size`` one.  The size jitter is small: mouth wide and pucker
   change the mouth's width by a few per cent of the face, and a crop +-5 % in size hid them
   (measured on the demo: with 0.95-1.10 those two were not learnt, correlation with the truth
   0.02-0.78 on held-out motions; with +-2 % 0.94-0.99).
3. **Split.**  Blocks of :data:`BLOCK` consecutive frames (fewer in a short video);
   every :data:`VALIDATION_EVERY`-th block is held out for validation (neighbouring frames are nearly equal: a random split would
   validate on frames the network has seen).
4. **Normalisation.**  Mean and standard deviation per control component over the training
   frames; a component that does not vary (std < :data:`MIN_STD`) is not learnt: it is its mean.
5. **Loss.**  Smooth L1 on the normalised controls, each group of the layout weighted equally
   (its weight shared by its varying components), as the paper's group-weighted loss.
6. **Training.**  AdamW, a learning rate warming up linearly over the first epoch (at most
   15 % of the run) from 1/25 of its peak, then falling as a half cosine to 1/100 at the last
   step (with a time budget, the last step is set again after every epoch, at the pace of the
   slowest of the last :data:`PACE_EPOCHS` epochs), batches of ``batch``, white balance,
   brightness and contrast jitter.  After each epoch the batch norms' statistics are measured
   again on :data:`BN_FRAMES` un-augmented training crops (their running averages lag the
   weights early in training, and a network evaluated with them predicts about the mean), then
   the per-group error on the held-out frames (control units, and as a share of each
   component's range, mean over the group's varying components) is reported; training stops
   after ``patience`` epochs without a better validation loss, keeping the best epoch's weights.
"""

from __future__ import annotations

import dataclasses
import math
import os
import time
from typing import Callable

import numpy as np

from ...core.errors import InputError
from ...core.files.outputs import check_output_file
from ...core.profile import make_provenance
from ..controls.files import load_controls
from ..avatar.rig import DEFAULT_LAYOUT
from .crop import CropTracker, IMAGENET_MEAN, IMAGENET_STD, cut, find_face, parse_crop
from .frames import open_frames
from .model import MAX_CONTROLS, MAX_INPUT_SIZE, MIN_INPUT_SIZE

JITTER = 0.05
SIZE_JITTER = 0.02  # training crops' side: S (1 - SIZE_JITTER) .. S (1 + SIZE_JITTER)
BLOCK = 32
VALIDATION_EVERY = 7
MIN_STD = 1e-6
MIN_FRAMES = 64
BN_FRAMES = 512  # training frames over which the batch norms' statistics are taken after every epoch
MAX_MINUTES = 10080  # a week: a longer budget is a typing error
PACE_EPOCHS = 3  # a time budget plans with the slowest of the last PACE_EPOCHS epochs
ANGLE_GROUPS = ("head", "neck", "jaw", "eyes")  # axis-angle radians: errors also in degrees


@dataclasses.dataclass(frozen=True)
class DistillOptions:
    """``epochs`` (at most), ``batch``, ``input_size`` (S), ``learning_rate`` (peak), ``patience``
    (epochs without improvement before stopping), ``device`` (torch), ``seed``, ``threads``
    (torch's CPU threads; None: all cores), ``minutes`` (a time budget for the whole run, reading
    the frames included: after every epoch, the epochs are set to what fits at the pace of the
    slowest of the last PACE_EPOCHS epochs, at most ``epochs``; None: none)."""

    epochs: int = 30
    batch: int = 32
    input_size: int = 224
    learning_rate: float = 2e-3
    patience: int = 6
    device: str = "cpu"
    seed: int = 0
    threads: int | None = None
    minutes: float | None = None


def match_controls(track, count: int, fps: float, source: str) -> tuple[np.ndarray, np.ndarray]:
    """(t (count,), controls (count, D)) for ``count`` frames at ``fps``: by index when the track has
    one sample per frame, else interpolated at the frames' times; InputError when they do not match."""
    if len(track) == count:
        return track.t.copy(), track.controls.copy()
    times = np.arange(count) / fps
    span = float(track.t[-1] - track.t[0])
    if times[-1] > span + 1.0 / fps:
        raise InputError(f"{count} frames ({times[-1]:.2f} s at {fps:g} fps) but {len(track)} control samples "
                         f"covering {span:.2f} s", source=source,
                         hint="give one control sample per frame, or samples whose times cover the video")
    return times, np.stack([track.at(t, loop=False)[1] for t in times])


def split_blocks(count: int) -> np.ndarray:
    """(count,) bool: True for the validation frames: every VALIDATION_EVERY-th block of BLOCK
    frames (shorter blocks for a short video, so that it holds two validation blocks at least)."""
    block = max(4, min(BLOCK, count // (2 * VALIDATION_EVERY)))
    return (np.arange(count) // block) % VALIDATION_EVERY == VALIDATION_EVERY // 2


def group_weights(layout, active: np.ndarray) -> tuple[np.ndarray, dict]:
    """Per-component loss weights (D,): each group with a varying component weighs 1, shared by
    its varying components; and {group: weight per component}."""
    w = np.zeros(layout.dim, dtype=np.float32)
    per = {}
    for name, _ in layout.groups:
        s = layout.slice(name)
        n = int(active[s].sum())
        if n:
            w[s] = active[s] / n
        per[name] = 1.0 / n if n else 0.0
    return w, per


def group_errors(pred: np.ndarray, truth: np.ndarray, layout, active: np.ndarray, ranges: np.ndarray) -> dict:
    """{group: {"mae", "share_of_range", "mae_deg" (angle groups)}} over the varying components."""
    out = {}
    for name, _ in layout.groups:
        s = layout.slice(name)
        keep = active[s]
        if not keep.any():
            continue
        err = np.abs(pred[:, s][:, keep] - truth[:, s][:, keep])
        mae = float(err.mean())
        entry = {"mae": mae, "share_of_range": float((err.mean(0) / np.maximum(ranges[s][keep], 1e-12)).mean())}
        if name in ANGLE_GROUPS:
            entry["mae_deg"] = math.degrees(mae)
        out[name] = entry
    return out


def _read_crops(frames, rule: dict, size: int, step: Callable) -> np.ndarray:
    """(N, P, P, 3) uint8 crops, P = round(size (1 + 2 JITTER)), each the rule's box grown by JITTER."""
    tracker = CropTracker(rule)
    P = int(round(size * (1 + 2 * JITTER)))
    out = np.empty((len(frames), P, P, 3), dtype=np.uint8)
    for k, _, rgb in frames:
        if k >= len(out):
            break
        x, y, w, h = tracker.box(rgb)
        g = JITTER * max(w, h)
        out[k] = cut(rgb, (x - g, y - g, w + 2 * g, h + 2 * g), P)
        step()
    return out


def training_side(rng, size: int) -> int:
    """The side (px of the stored crop) of one training batch's square: a whole number drawn
    evenly from ``size`` (1 - SIZE_JITTER) to ``size`` (1 + SIZE_JITTER), both included."""
    return int(rng.integers(int(round(size * (1 - SIZE_JITTER))), int(round(size * (1 + SIZE_JITTER))) + 1))


def _batches(crops, targets, index, size, batch, rng, train: bool):
    """Yield (x float32 (B, 3, S, S) normalised, y (B, D)) for the frames ``index``.

    Training draws, per batch, a square of side S (1 - SIZE_JITTER) to S (1 + SIZE_JITTER) (the
    tracker's box a little smaller or larger; :func:`training_side`) resampled to S, and per frame
    its place in the stored crop, white balance (+-4 % per channel), brightness (+-0.08) and
    contrast (0.85-1.15); validation takes the centred S square as it is."""
    import torch

    P = crops.shape[1]
    order = rng.permutation(index) if train else index
    mean = torch.from_numpy(IMAGENET_MEAN).view(1, 3, 1, 1)
    std = torch.from_numpy(IMAGENET_STD).view(1, 3, 1, 1)
    for k in range(0, len(order), batch):
        pick = order[k:k + batch]
        if train:
            side = training_side(rng, size)
            offsets = rng.integers(0, P - side + 1, (len(pick), 2))
            x = torch.from_numpy(np.stack([crops[i, oy:oy + side, ox:ox + side] for i, (ox, oy) in zip(pick, offsets)]))
            x = x.permute(0, 3, 1, 2).float() / 255.0
            if side != size:
                x = torch.nn.functional.interpolate(x, size=(size, size), mode="bilinear", align_corners=False,
                                                    antialias=side > size)
            n = len(pick)
            gain = torch.from_numpy(rng.uniform(0.96, 1.04, (n, 3, 1, 1)).astype(np.float32))
            b = torch.from_numpy(rng.uniform(-0.08, 0.08, (n, 1, 1, 1)).astype(np.float32))
            c = torch.from_numpy(rng.uniform(0.85, 1.15, (n, 1, 1, 1)).astype(np.float32))
            x = ((x * gain - 0.5) * c + 0.5 + b).clamp(0, 1)
        else:
            o = (P - size) // 2
            x = torch.from_numpy(crops[pick, o:o + size, o:o + size]).permute(0, 3, 1, 2).float() / 255.0
        yield (x - mean) / std, torch.from_numpy(targets[pick])


def _refresh_batch_norm(net, batches, device) -> None:
    """Every BatchNorm's running mean and variance estimated again as the plain average over
    ``batches`` (un-augmented training crops), as evaluation sees them; their momentum kept."""
    import torch

    norms = [m for m in net.modules() if isinstance(m, torch.nn.modules.batchnorm._BatchNorm)]
    momenta = [m.momentum for m in norms]
    for m in norms:
        m.reset_running_stats()
        m.momentum = None  # a cumulative average
    net.train()
    with torch.no_grad():
        for x, _ in batches:
            net(x.to(device))
    for m, momentum in zip(norms, momenta):
        m.momentum = momentum


def distill_student(frames: str | os.PathLike, controls: str | os.PathLike, output: str | os.PathLike, *,
                    rig: str | os.PathLike | None = None, crop: str | None = None,
                    backbone_weights: str | os.PathLike | None = None, options: DistillOptions | None = None,
                    stage: Callable[[str, int], Callable[..., None]] | None = None,
                    on_epoch: Callable[[dict], None] | None = None) -> dict:
    """Distil a student (module docstring) and write it to ``output``; returns its summary
    (``validation`` per group at the best epoch, ``epochs`` run, ``best_epoch``, ``seconds``,
    ``frames``, ``history``).  ``on_epoch(record)`` is called after every epoch."""
    import torch

    from ..gpu.torch_devices import device_unavailable
    from .model import build_student
    from .student_file import save_student

    o = options or DistillOptions()
    start = time.perf_counter()
    for name, value, lo, hi in (("epochs", o.epochs, 1, None), ("batch", o.batch, 2, None),
                                ("input_size", o.input_size, MIN_INPUT_SIZE, MAX_INPUT_SIZE), ("patience", o.patience, 1, None)):
        if isinstance(value, bool) or not isinstance(value, int) or value < lo or (hi is not None and value > hi):
            raise InputError(f"{name} {value!r} is out of range", source=name,
                             hint=f"use a whole number >= {lo}" if hi is None else f"use a whole number {lo}..{hi}")
    if o.minutes is not None and (isinstance(o.minutes, bool) or not isinstance(o.minutes, (int, float))
                                  or not 0 < o.minutes <= MAX_MINUTES):
        raise InputError(f"minutes {o.minutes!r} is out of range", source="minutes",
                         hint=f"give a time budget in minutes, more than 0 and at most {MAX_MINUTES}")
    output = check_output_file(output, "student driver", example="student.pt",
                               inputs=(frames, controls, rig, backbone_weights))
    if rig is not None:
        from ..avatar.rig_file import load_rig

        loaded = load_rig(rig)
        layout, names = loaded.layout, loaded.control_names
    else:
        layout, names = DEFAULT_LAYOUT, None
    if layout.dim > MAX_CONTROLS:
        raise InputError(f"the rig has {layout.dim} controls, more than a student predicts ({MAX_CONTROLS})",
                         source=str(rig))
    source = open_frames(frames)
    if len(source) < MIN_FRAMES:
        raise InputError(f"only {len(source)} frames; at least {MIN_FRAMES} are needed", source=str(frames),
                         hint="give a longer training video")
    track = load_controls(controls, layout, names)
    times, targets = match_controls(track, len(source), source.fps, str(controls))
    rule = parse_crop(crop, source.size)
    find_face(source, rule)  # "auto": a face in the first frames, or one line now
    why = device_unavailable(o.device)
    if why:
        raise InputError(why, source="device", hint="use cpu, or a CUDA device torch can see")
    net = build_student(layout.dim, backbone_weights)

    def steps(name: str, total: int):
        return stage(name, total) if stage is not None else (lambda *message: None)

    crops = _read_crops(source, rule, o.input_size, steps("reading frames", len(source)))
    held = split_blocks(len(source))
    train_idx, val_idx = np.flatnonzero(~held), np.flatnonzero(held)
    mean = targets[train_idx].mean(0).astype(np.float32)
    std = targets[train_idx].std(0).astype(np.float32)
    active = std > MIN_STD
    std = np.where(active, std, 1.0).astype(np.float32)
    ranges = targets.max(0) - targets.min(0)
    normed = ((targets - mean) / std * active).astype(np.float32)
    weights, per_group = group_weights(layout, active)

    if o.threads:
        torch.set_num_threads(o.threads)
    torch.manual_seed(o.seed)
    rng = np.random.default_rng(o.seed)
    device = torch.device(o.device)
    net.to(device)
    w = torch.from_numpy(weights).to(device)
    steps_per_epoch = math.ceil(len(train_idx) / o.batch)
    opt = torch.optim.AdamW(net.parameters(), lr=o.learning_rate, weight_decay=1e-4)
    plan = {"epochs": o.epochs}
    warm = max(1, min(steps_per_epoch, int(0.15 * o.epochs * steps_per_epoch)))

    def rate(step: int) -> float:  # factor on the peak rate (docstring, step 6)
        if step < warm:
            return 0.04 + 0.96 * step / warm
        total = max(plan["epochs"] * steps_per_epoch - warm, 1)
        return 0.01 + 0.99 * 0.5 * (1 + math.cos(math.pi * min(1.0, (step - warm) / total)))

    sched = torch.optim.lr_scheduler.LambdaLR(opt, rate)
    best, best_loss, best_epoch, history = None, math.inf, 0, []
    bar = steps("training (first epoch)" if o.minutes else "training", (1 if o.minutes else o.epochs) * steps_per_epoch)
    epoch, durations = 0, []
    while epoch < plan["epochs"]:
        epoch += 1
        epoch_start = time.perf_counter()
        net.train()
        train_loss = 0.0
        for x, y in _batches(crops, normed, train_idx, o.input_size, o.batch, rng, train=True):
            x, y = x.to(device), y.to(device)
            loss = (torch.nn.functional.smooth_l1_loss(net(x), y, reduction="none", beta=0.5) * w).sum(1).mean()
            opt.zero_grad(set_to_none=True)
            loss.backward()
            opt.step()
            sched.step()
            train_loss += float(loss.detach()) * len(x)
            bar()
        _refresh_batch_norm(net, _batches(crops, normed, rng.choice(train_idx, min(len(train_idx), BN_FRAMES),
                                                                    replace=False), o.input_size, o.batch, rng,
                                          train=False), device)
        net.eval()
        preds, losses = [], []
        with torch.inference_mode():
            for x, y in _batches(crops, normed, val_idx, o.input_size, o.batch, rng, train=False):
                out = net(x.to(device)).cpu()
                losses.append(float((torch.nn.functional.smooth_l1_loss(out, y, reduction="none", beta=0.5)
                                     * w.cpu()).sum(1).sum()))
                preds.append(out.numpy())
        val_loss = sum(losses) / len(val_idx)
        pred = mean + std * np.concatenate(preds) * active
        errors = group_errors(pred, targets[val_idx], layout, active, ranges)
        record = {"epoch": epoch, "training_loss": train_loss / len(train_idx), "validation_loss": val_loss,
                  "groups": errors, "seconds": time.perf_counter() - start}
        durations.append(time.perf_counter() - epoch_start)
        if o.minutes:  # the budget: as many epochs as fit in what is left at the recent epochs' pace
            left = 60.0 * o.minutes - (time.perf_counter() - start)
            planned = max(epoch, min(o.epochs, epoch + int(left // max(durations[-PACE_EPOCHS:]))))
            if epoch == 1 or planned != plan["epochs"]:
                plan["epochs"] = record["planned_epochs"] = planned
            if epoch == 1:
                bar = steps("training", (planned - 1) * steps_per_epoch)
        history.append(record)
        if on_epoch is not None:
            on_epoch(record)
        if val_loss < best_loss - 1e-6:
            best_loss, best_epoch = val_loss, epoch
            best = {k: v.detach().cpu().clone() for k, v in net.state_dict().items()}
        elif epoch - best_epoch >= o.patience:
            break
    seconds = time.perf_counter() - start
    best_record = history[best_epoch - 1]
    inputs = [frames] if os.path.isfile(frames) else []
    provenance = make_provenance("driver distill", inputs=inputs + [controls] + ([rig] if rig else []),
                                 frames=str(frames), options=dataclasses.asdict(o),
                                 backbone_weights=None if backbone_weights is None else str(backbone_weights))
    save_student(output, {
        "layout": [[g, int(s)] for g, s in layout.groups], "control_names": list(names or layout.default_names()),
        "crop": rule, "input_size": o.input_size, "mean": torch.from_numpy(mean), "std": torch.from_numpy(std),
        "active": torch.from_numpy(active), "group_weights": per_group, "state_dict": best,
        "validation": best_record["groups"], "provenance": {**provenance, "epochs_run": len(history),
                                                            "best_epoch": best_epoch, "seconds": round(seconds, 1)},
    })
    return {"output": str(output), "frames": len(source), "train_frames": int(len(train_idx)),
            "validation_frames": int(len(val_idx)), "epochs": len(history), "best_epoch": best_epoch,
            "validation": best_record["groups"], "seconds": seconds, "history": history, "crop": rule,
            "times": times}
