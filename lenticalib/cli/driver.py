"""``lenticalib driver distill|predict``: the student driver, trained per subject.

    distill --frames VIDEO|DIR --controls FILE -o student.pt [--layout RIG] [--crop auto|x,y,w,h]
            [--epochs E] [--minutes M] [--device cpu|cuda] [--backbone-weights FILE] [--input-size S]
                                   train a student on the subject's frames and teacher controls
    predict student.pt --frames VIDEO|DIR -o controls.csv [--device cpu|cuda]
                                   the controls of every frame, as a file --controls reads

Calls :func:`lenticalib.render.student.distill.distill_student` and
:func:`lenticalib.render.student.predict.predict_controls`; every input is checked before the
frames are read.
"""

from __future__ import annotations

import argparse

FLAGS = {"frames": "--frames", "controls": "--controls", "output": "-o", "rig": "--layout", "crop": "--crop",
         "epochs": "--epochs", "minutes": "--minutes", "device": "--device", "backbone_weights": "--backbone-weights",
         "input_size": "--input-size", "batch": "--batch", "patience": "--patience", "student": "STUDENT"}


def add_arguments(parser: argparse.ArgumentParser) -> None:
    sub = parser.add_subparsers(dest="driver_command", metavar="STEP")
    sub.required = True
    d = sub.add_parser("distill", help="train a student driver on a subject's frames and teacher controls",
                       description="train the LentiAvatar student driver (MobileNetV3-Small and a two-layer head) "
                                   "to predict the avatar's controls from camera frames")
    d.add_argument("--frames", required=True, metavar="VIDEO|DIR", help="the training video, or a folder of frames")
    d.add_argument("--controls", required=True, metavar="FILE", help="the teacher controls of those frames (.npz, "
                   ".csv, .jsonl): one sample per frame, or timed samples covering the video")
    d.add_argument("-o", "--output", required=True, metavar="FILE", help="the student to write (student.pt)")
    d.add_argument("--layout", metavar="RIG", help="the avatar's rig .npz, for its control layout (default: the "
                   "70-value default layout)")
    d.add_argument("--crop", default=None, metavar="auto|x,y,w,h", help="the face's box in the frames (pixels), or "
                   "auto: follow the face (the MTCNN face detector, shipped with lenticalib's dependencies); "
                   "default auto")
    d.add_argument("--epochs", type=int, default=30, metavar="E", help="at most E epochs (early stopping; default 30)")
    d.add_argument("--minutes", type=float, metavar="M", help="a time budget: as many epochs (at most E) as fit in "
                   "M minutes, reading the frames included")
    d.add_argument("--batch", type=int, default=32, help="batch size (default 32)")
    d.add_argument("--patience", type=int, default=6, help="epochs without improvement before stopping (default 6)")
    d.add_argument("--input-size", type=int, default=224, metavar="S", help="network input S x S (default 224)")
    d.add_argument("--device", default="cpu", help="torch device: cpu (default) or cuda")
    d.add_argument("--backbone-weights", metavar="FILE", help="torchvision mobilenet_v3_small weights to start "
                   "from (a state dict file; never downloaded); default: from scratch")
    d.set_defaults(run=run_distill, flags=FLAGS)
    p = sub.add_parser("predict", help="predict the controls of frames with a student driver",
                       description="predict the controls of every frame, as a CSV that --controls reads")
    p.add_argument("student", metavar="STUDENT", help="the student (from 'driver distill')")
    p.add_argument("--frames", required=True, metavar="VIDEO|DIR", help="a video or a folder of frames")
    p.add_argument("-o", "--output", required=True, metavar="FILE", help="controls CSV to write")
    p.add_argument("--device", default="cpu", help="torch device: cpu (default) or cuda")
    p.set_defaults(run=run_predict, flags=FLAGS)


def run_distill(args: argparse.Namespace) -> int:
    from ..render.student.distill import DistillOptions, distill_student
    from .shared.progress import staged_bars

    options = DistillOptions(epochs=args.epochs, batch=args.batch, input_size=args.input_size, patience=args.patience,
                             device=args.device, minutes=args.minutes)

    def report(record: dict) -> None:
        parts = []
        for group, e in record["groups"].items():
            parts.append(f"{group} {group_error(group, e)} ({100 * e['share_of_range']:.1f} %)")
        print(f"epoch {record['epoch']:3d}  loss {record['training_loss']:.4f} / {record['validation_loss']:.4f} "
              "(training / validation)  " + ", ".join(parts)
              + f"  [{record['seconds']:.0f} s]", flush=True)
        if "planned_epochs" in record:
            print(f"the time budget holds {record['planned_epochs']} epochs", flush=True)

    with staged_bars() as stage:
        summary = distill_student(args.frames, args.controls, args.output, rig=args.layout, crop=args.crop,
                                  backbone_weights=args.backbone_weights, options=options, stage=stage,
                                  on_epoch=report)
    print(f"wrote {summary['output']}: best epoch {summary['best_epoch']} of {summary['epochs']}, "
          f"{summary['train_frames']} training and {summary['validation_frames']} held-out frames, "
          f"{summary['seconds']:.0f} s")
    return 0


def group_error(group: str, entry: dict) -> str:
    """A group's held-out mean error with the README's unit: the jaw in rad (its control's unit),
    the translation in mm (the rig's metres x 1000), the other rotations in deg, the rest (weights)
    as they are."""
    if group == "jaw":
        return f"{entry['mae']:.4f} rad"
    if group == "translation":
        return f"{entry['mae'] * 1000:.2f} mm"
    if "mae_deg" in entry:
        return f"{entry['mae_deg']:.2f} deg"
    return f"{entry['mae']:.4f}"


def run_predict(args: argparse.Namespace) -> int:
    from ..render.student.predict import predict_controls
    from .shared.progress import progress_bar

    with progress_bar(0, "predicting") as bar:
        summary = predict_controls(args.student, args.frames, args.output, device=args.device, step=bar.update)
    print(f"wrote {summary['output']}: {summary['frames']} frames, {summary['ms_per_frame']:.1f} ms a frame "
          f"(median: crop and network)")
    return 0
