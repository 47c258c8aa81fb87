"""Avatar drivers: what turns a control vector into posed Gaussians, frame by frame.

The built-in driver is a rig file's own deformer (:meth:`.rig.Rig.deform`).  Anyone with another
deformable avatar (a FLAME-based Gaussian head, say) plugs in their own as ``module:callable``.

The contract: a driver is any callable

    driver(controls, device) -> Gaussians

    controls   torch.Tensor (D,) float32 on ``device``: one frame's control vector
    device     torch.device: where the renderer wants the result
    returns    a :class:`~.gaussians.Gaussians` of float32 torch tensors on ``device``, activated
               values (means (G, 3), quats (G, 4) w x y z, scales (G, 3), opacities (G,), sh (G, K, 3)),
               G and K the same every frame

It is called once per frame from the render loop's thread and should not block for long (load
models when the module is imported or on the first call, not per frame).  Optional attributes
of the callable: ``control_dim`` (int: controls of any other length are refused before the call)
and ``control_layout`` (a :class:`~.rig.ControlLayout`, used to read control files by group name).

Specs (:func:`load_driver`):

    "rig"              the built-in: the rig's deform (needs ``rig=``)
    "module:callable"  ``import module`` and take the attribute (a dotted path such as ``pkg.mod:Obj.method``
                       is allowed); the module must be importable (installed, or on PYTHONPATH)
    "NAME"             an entry point named NAME in the ``lenticalib.avatar_drivers`` group, whose value
                       is "module:callable"

The names ("rig" and the entry points) are a registry on the package's one loader
(:mod:`lenticalib.core.plugins`), which also imports a "module:callable" spec.  A spec without a
colon that is not "rig" or a registered name, an empty module or attribute, an attribute that is
missing or not callable is an InputError; a module that fails to import is a
BackendUnavailableError; each is one line naming the spec.
"""

from __future__ import annotations

from typing import Any, Callable

from ...core.errors import InputError
from ...core.plugins import Registry, import_target
from .gaussians import Gaussians
from .rig import ControlLayout, Rig

ENTRY_POINT_GROUP = "lenticalib.avatar_drivers"
BUILTIN = "rig"


class Driver:
    """A loaded driver: ``name`` (the spec), the callable, and what it says about its controls.

    Calling it checks the control length (when ``control_dim`` is known) and that a Gaussians of
    torch tensors came back; anything else is an InputError naming the driver.
    """

    def __init__(self, name: str, func: Callable[..., Any], control_dim: int | None = None,
                 layout: ControlLayout | None = None):
        self.name = name
        self.func = func
        self.layout = layout
        self.control_dim = layout.dim if layout is not None else control_dim

    def __call__(self, controls, device) -> Gaussians:
        import torch

        if self.control_dim is not None and (controls.dim() != 1 or controls.shape[0] != self.control_dim):
            hint = f"layout: {self.layout.describe()}" if self.layout is not None else None
            raise InputError(f"controls have shape {tuple(controls.shape)}, driver {self.name!r} expects "
                             f"({self.control_dim},)", source="controls", hint=hint)
        out = self.func(controls, torch.device(device) if isinstance(device, str) else device)
        if not isinstance(out, Gaussians) or not isinstance(out.means, torch.Tensor):
            what = type(out).__name__ if not isinstance(out, Gaussians) else f"Gaussians of {type(out.means).__name__}"
            raise InputError(f"driver returned {what}, expected Gaussians of torch tensors", source=self.name,
                             hint="see the driver contract in lenticalib/render/avatar/drivers.py")
        return out


class RigDriver:
    """The built-in driver: ``rig.deform``, the rig moved to the asked device on first use there."""

    def __init__(self, rig: Rig):
        self.rig = rig
        self.control_layout = rig.layout
        self.control_dim = rig.control_dim

    def __call__(self, controls, device) -> Gaussians:
        import torch

        want, have = torch.device(device), self.rig.device
        if want.type != have.type or (want.index is not None and want.index != have.index):
            self.rig = self.rig.to(want)
        return self.rig.deform(controls)


# "rig" names the class the built-in driver is made of (RigDriver(rig)); every other name an entry
# point whose value is a driver callable
DRIVERS = Registry("driver", {BUILTIN: "lenticalib.render.avatar.drivers:RigDriver"}, ENTRY_POINT_GROUP,
                   choices="use module:callable or one of {names}")


def load_driver(spec: str | None = BUILTIN, *, rig: Rig | None = None) -> Driver:
    """The driver named by ``spec`` (module docstring), wrapped in a checking :class:`Driver`."""
    if spec is None or spec == BUILTIN:
        if rig is None:
            raise InputError("the built-in driver needs a rig", source="driver",
                             hint="give a rig file, or a driver as module:callable")
        return Driver(BUILTIN, DRIVERS.load(BUILTIN, "driver")(rig), layout=rig.layout)
    if not isinstance(spec, str) or not spec.strip():
        raise InputError(f"bad driver {spec!r}", source="driver", hint="use module:callable or 'rig'")
    target = spec if ":" in spec else DRIVERS.entries()[DRIVERS.check(spec, "driver")]
    module_name, _, attr = target.partition(":")
    if not module_name.strip() or not attr.strip() or ":" in attr:
        raise InputError(f"bad driver {spec!r}", source="driver", hint="use module:callable, e.g. mypkg.flame:drive")
    obj = import_target(target, f"driver {spec!r}", spec, hint="install it or put its folder on PYTHONPATH")
    if not callable(obj):
        raise InputError(f"{target} is a {type(obj).__name__}, not callable", source=spec,
                         hint="a driver is called as driver(controls, device)")
    layout = getattr(obj, "control_layout", None)
    dim = getattr(obj, "control_dim", None)
    if layout is not None and not isinstance(layout, ControlLayout):
        raise InputError(f"{target}.control_layout is a {type(layout).__name__}, expected a ControlLayout",
                         source=spec)
    if dim is not None and (isinstance(dim, bool) or not isinstance(dim, int) or dim < 1):
        raise InputError(f"{target}.control_dim is {dim!r}, expected a positive int", source=spec)
    return Driver(spec, obj, control_dim=dim, layout=layout)
