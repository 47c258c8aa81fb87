"""An avatar to render: a static 3DGS PLY, a rig file, or a rig driven by a plug-in driver.

``load_avatar(path, driver=None)``:

    *.ply   a static Gaussian-splatting scene (:mod:`.ply`); controls are ignored
    *.npz   a lenticalib rig (:mod:`.rig_file`), deformed by its own rig (``driver=None`` or "rig")
            or by a plug-in driver ``module:callable`` (:mod:`.drivers`) that gets the controls

:meth:`Avatar.pose` turns one frame's controls into Gaussians on the renderer's device: numpy
for the ``cpu`` renderer, torch on the GPU for ``gsplat``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ...core.errors import InputError
from .gaussians import Gaussians


class Avatar:
    """``kind`` ("static" or "animated"), ``layout`` (the control layout, None when static),
    ``source`` (the file), ``rig`` (the :class:`~.rig.Rig` of a rig file, whatever drives it;
    None when static) and :meth:`pose`."""

    def __init__(self, kind: str, source: str, static: Gaussians | None = None, driver=None, layout=None,
                 neutral: np.ndarray | None = None, rig=None):
        self.kind = kind
        self.rig = rig
        self.source = source
        self._static = static
        self._driver = driver
        self.layout = layout
        self.neutral = neutral

    @property
    def control_dim(self) -> int | None:
        return None if self.layout is None else self.layout.dim

    def pose(self, controls: np.ndarray | None, device: str = "cpu", as_torch: bool = False) -> Gaussians:
        """The posed Gaussians for ``controls`` (D,) (ignored when static), numpy unless ``as_torch``."""
        if self.kind == "static":
            return self._static.to_torch(device) if as_torch else self._static
        import torch

        vector = self.neutral if controls is None else np.asarray(controls, dtype=np.float32)
        out = self._driver(torch.as_tensor(vector, dtype=torch.float32, device=device), torch.device(device))
        return out if as_torch else out.to_numpy()

    def bounding_box(self) -> tuple[np.ndarray, np.ndarray]:
        """(min, max) of the Gaussian centres in the neutral pose (world units)."""
        return self.pose(None).bounding_box()


def load_avatar(path: str | Path, driver: str | None = None) -> Avatar:
    """The avatar in ``path``; InputError (one line, naming the file) for anything else."""
    p = Path(path)
    if not p.is_file():
        raise InputError("no such avatar file", source=str(p),
                         hint="give a 3DGS .ply or a lenticalib rig .npz (python tools/make_demo_avatar.py demo.npz)")
    suffix = p.suffix.lower()
    if suffix == ".ply":
        if driver not in (None, "rig"):
            raise InputError("a driver needs an animated avatar (a rig .npz), not a static .ply", source="driver")
        from .ply import load_ply

        return Avatar("static", str(p), static=load_ply(p).validate(str(p)))
    if suffix == ".npz":
        from .drivers import load_driver
        from .rig_file import load_rig

        rig = load_rig(p)
        loaded = load_driver(driver or "rig", rig=rig)
        layout = loaded.layout or rig.layout
        return Avatar("animated", str(p), driver=loaded, layout=layout,
                      neutral=np.zeros(layout.dim, dtype=np.float32), rig=rig)
    raise InputError(f"avatar files must be .ply (static 3DGS) or .npz (a lenticalib rig), not {suffix or 'no suffix'!r}",
                     source=str(p), hint="python tools/make_demo_avatar.py demo.npz makes the demo avatar")
