"""The saved student driver (``student.pt``): everything prediction needs, and where it came from.

A ``torch.save`` of plain data (read back with ``weights_only=True``: no pickled code):

    format, format_version   "lenticalib.student-driver", 1
    layout                   [[group, size], ...]: the control layout it predicts (a rig with
                             another layout refuses it)
    control_names            (D,) the components' names
    crop                     the crop rule (:mod:`.crop`)
    input_size               S: the network's input is S x S
    mean, std                (D,) float32 tensors: the teacher controls' statistics;
                             controls = mean + std * output
    active                   (D,) bool tensor: components that varied in training (the others
                             are their mean)
    group_weights            {group: weight} of the loss
    state_dict               the network's weights (:mod:`.model`)
    validation               per-group error on the held-out frames at the best epoch
    provenance               inputs (with SHA-256), options, epochs, seconds, lenticalib version

READING.  A student file is a file like any other: :func:`load_student` checks the zip first
(:data:`.model.WEIGHTS_ZIP`: at most 32 MiB inflated, 1024 members, a 1 MiB pickle, from the
central directory, before torch inflates anything), then every field, each refusal one InputError
naming the file and the field (``s.pt: field 'input_size' is 200000, expected ...``):

    layout         1..MAX_GROUPS pairs [identifier, whole number >= 1], D = the sum <= MAX_CONTROLS
    control_names  D strings of at most MAX_NAME characters
    crop           :func:`.crop.check_crop_rule`: finite box within +-16384 px, or the "auto" rule
    input_size     a whole number MIN_INPUT_SIZE..MAX_INPUT_SIZE (32..512)
    mean, std      float tensors of shape (D,), finite in float32; std > 0
    active         a bool tensor of shape (D,)
    state_dict     names -> tensors that fit the network exactly (shapes), finite once loaded
    group_weights, validation, provenance   optional; objects (dicts) nested at most
                   MAX_DEPTH levels

so that nothing a file says reaches OpenCV, torch or numpy as a size unchecked.
"""

from __future__ import annotations

import os

from ...core.files.atomic import write_bytes_atomic
from ...core.files.documents import FORMATS, check_envelope
from ...core.errors import InputError
from ...core.files.fields import short_repr
from ..avatar.rig import ControlLayout
from .crop import check_crop_rule
from .model import MAX_CONTROLS, MAX_INPUT_SIZE, MIN_INPUT_SIZE, build_student, load_weights

DOCUMENT = FORMATS["lenticalib.student-driver"]
HINT = "make one with 'lenticalib driver distill'"
REQUIRED = ("layout", "control_names", "crop", "input_size", "mean", "std", "active", "state_dict")
MAX_GROUPS = 256  # control groups in a layout
MAX_NAME = 200  # characters of a group or component name
MAX_DEPTH = 64  # nesting of the informative fields (as of any JSON document lenticalib reads)


class Student:
    """A loaded, checked student: ``layout``, ``control_names``, ``crop``, ``input_size``, ``mean``,
    ``std``, ``active`` (numpy (D,)), ``network`` (eval mode, CPU), ``record`` (the whole file's dict)."""

    def __init__(self, record: dict, network, *, layout: ControlLayout, control_names: tuple[str, ...], crop: dict,
                 input_size: int, mean, std, active):
        self.record = record
        self.layout = layout
        self.control_names = control_names
        self.crop = crop
        self.input_size = input_size
        self.mean, self.std, self.active = mean, std, active
        self.network = network

    def check_layout(self, layout: ControlLayout, source: str) -> None:
        """InputError naming ``source`` when ``layout`` is not the one the student predicts."""
        if tuple(layout.groups) != tuple(self.layout.groups):
            raise InputError(f"the student predicts controls {self.layout.describe()}, the avatar takes "
                             f"{layout.describe()}", source=source,
                             hint="distil a student with this avatar's rig (its control layout)")


def save_student(path: str | os.PathLike, record: dict) -> None:
    """Write ``record`` (module docstring) atomically."""
    import io

    import torch

    buf = io.BytesIO()
    torch.save({**DOCUMENT.envelope(), **record}, buf)
    write_bytes_atomic(path, buf.getvalue())


class _Fields:
    """The field checks of one student file: each failure one InputError naming the file and field."""

    def __init__(self, record: dict, source: str):
        self.record = record
        self.source = source

    def bad(self, field: str, message: str) -> InputError:
        return InputError(f"field '{field}' {message}", source=self.source, hint=HINT)

    def layout(self) -> ControlLayout:
        pairs = self.record["layout"]
        if not isinstance(pairs, (list, tuple)) or not 1 <= len(pairs) <= MAX_GROUPS:
            raise self.bad("layout", f"is {short_repr(pairs)}, expected 1..{MAX_GROUPS} [group, size] pairs")
        groups = []
        for k, pair in enumerate(pairs):
            if not (isinstance(pair, (list, tuple)) and len(pair) == 2 and isinstance(pair[0], str)
                    and pair[0].isidentifier() and len(pair[0]) <= MAX_NAME
                    and isinstance(pair[1], int) and not isinstance(pair[1], bool) and 1 <= pair[1] <= MAX_CONTROLS):
                raise self.bad(f"layout[{k}]", f"is {short_repr(pair, 40)}, expected [group name, size "
                               f"1..{MAX_CONTROLS}]")
            groups.append((pair[0], int(pair[1])))
        dim = sum(size for _, size in groups)
        if dim > MAX_CONTROLS:
            raise self.bad("layout", f"adds up to {dim} controls, more than a student predicts ({MAX_CONTROLS})")
        try:
            return ControlLayout(tuple(groups))
        except InputError as exc:  # a repeated group name
            raise self.bad("layout", exc.message) from None

    def names(self, dim: int) -> tuple[str, ...]:
        names = self.record["control_names"]
        if not isinstance(names, (list, tuple)) or len(names) != dim:
            raise self.bad("control_names", f"is {short_repr(names)}, expected {dim} names (one per control)")
        for k, name in enumerate(names):
            if not isinstance(name, str) or not 0 < len(name) <= MAX_NAME:
                raise self.bad(f"control_names[{k}]", f"is {short_repr(name)}, expected a name of 1..{MAX_NAME} "
                               "characters")
        return tuple(names)

    def input_size(self) -> int:
        size = self.record["input_size"]
        if isinstance(size, bool) or not isinstance(size, int) or not MIN_INPUT_SIZE <= size <= MAX_INPUT_SIZE:
            raise self.bad("input_size", f"is {short_repr(size)}, expected a whole number "
                           f"{MIN_INPUT_SIZE}..{MAX_INPUT_SIZE} (pixels a side)")
        return size

    def vector(self, field: str, dim: int, kind: str):
        """numpy (dim,): float32, finite (``kind`` "float"), or bool (``kind`` "bool")."""
        import numpy as np
        import torch

        t = self.record[field]
        want = "a bool tensor" if kind == "bool" else "a float tensor"
        if not isinstance(t, torch.Tensor) or t.layout != torch.strided:
            raise self.bad(field, f"is {short_repr(t, 40) if not isinstance(t, torch.Tensor) else 'a special tensor'}"
                           f", expected {want} of shape ({dim},)")
        if tuple(t.shape) != (dim,):
            raise self.bad(field, f"has shape {tuple(t.shape)}, expected ({dim},) (one per control)")
        if kind == "bool":
            if t.dtype != torch.bool:
                raise self.bad(field, f"is a tensor of {t.dtype}, expected {want}")
            return t.numpy().astype(bool)
        if not t.is_floating_point():
            raise self.bad(field, f"is a tensor of {t.dtype}, expected {want}")
        with np.errstate(over="ignore", invalid="ignore"):
            v = t.detach().to(torch.float64).numpy().astype(np.float32)
        if not np.isfinite(v).all():
            k = int(np.argmin(np.isfinite(v)))
            raise self.bad(f"{field}[{k}]", f"is {t[k].item()!r}, not a finite float32")
        return v

    def documents(self) -> None:
        """The optional informative fields: dicts nested at most MAX_DEPTH levels."""
        for field in ("group_weights", "validation", "provenance"):
            if field not in self.record:
                continue
            value = self.record[field]
            if not isinstance(value, dict):
                raise self.bad(field, f"is {short_repr(value)}, expected an object (a dict)")
            stack, seen = [(value, 1)], 0
            while stack:
                node, depth = stack.pop()
                seen += 1
                if depth > MAX_DEPTH or seen > 1_000_000:
                    raise self.bad(field, f"is nested more than {MAX_DEPTH} levels deep or holds over a "
                                   "million values")
                children = node.values() if isinstance(node, dict) else node if isinstance(node, (list, tuple)) else ()
                stack.extend((child, depth + 1) for child in children)


def load_student(path: str | os.PathLike) -> Student:
    """The student in ``path``, every field checked (module docstring), its network built and
    loaded; one InputError naming the file (and the field) otherwise."""
    import numpy as np
    import torch

    source = str(path)
    if not os.path.lexists(path):
        raise InputError("no such student file", source=source, hint=HINT)
    record = load_weights(path, "student file", HINT)
    check_envelope(record, DOCUMENT, source)
    missing = [k for k in REQUIRED if k not in record]
    if missing:
        raise InputError(f"the student file lacks {', '.join(missing)}", source=source, hint=HINT)
    fields = _Fields(record, source)
    layout = fields.layout()
    names = fields.names(layout.dim)
    crop = check_crop_rule(record["crop"], source)
    input_size = fields.input_size()
    mean = fields.vector("mean", layout.dim, "float")
    std = fields.vector("std", layout.dim, "float")
    if not (std > 0).all():
        k = int(np.argmin(std > 0))
        raise fields.bad(f"std[{k}]", f"is {float(std[k])!r}, expected a standard deviation > 0")
    active = fields.vector("active", layout.dim, "bool")
    fields.documents()
    state = record["state_dict"]
    if not isinstance(state, dict) or not all(isinstance(k, str) and isinstance(v, torch.Tensor) for k, v in state.items()):
        raise fields.bad("state_dict", "is not a dict of names to tensors")
    network = build_student(layout.dim)
    try:
        network.load_state_dict(state)  # strict: every name, and every shape, must fit the network
    except (RuntimeError, TypeError, ValueError, AttributeError, NotImplementedError):
        raise fields.bad("state_dict", "does not fit the student's network (names or shapes)") from None
    for name, value in network.state_dict().items():
        if value.is_floating_point() and not bool(torch.isfinite(value).all()):
            raise fields.bad(f"state_dict.{name}", "holds values that are not finite")
    network.eval()
    return Student(record, network, layout=layout, control_names=names, crop=crop, input_size=input_size,
                   mean=mean, std=std, active=active)
