"""A set of 3D Gaussians (a Gaussian-splatting avatar), as every renderer and deformer takes it.

Frames and units: world coordinates in the avatar's units (metres for the demo avatar), world
y up and the avatar facing +z unless a scene says otherwise.  Fields hold *activated* values,
the form renderers consume (the PLY file stores the raw ones, see :mod:`.ply`):

    means      (G, 3)      centres, world units
    quats      (G, 4)      unit quaternions, (w, x, y, z), rotating the Gaussian's axes into the world
    scales     (G, 3)      standard deviations along the Gaussian's own axes, world units (> 0)
    opacities  (G,)        in (0, 1)
    sh         (G, K, 3)   spherical-harmonic colour coefficients, K = (degree + 1)^2, DC first;
                           colour(d) = 0.5 + sum_k sh[:, k] * Y_k(d) (the 3DGS convention), clipped at 0

Arrays are numpy (the CPU path) or torch tensors (deformers and the GPU path); :meth:`to_numpy`
and :meth:`to_torch` convert.  All fields share one backend, dtype float32.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np

from ...core.errors import InputError

SH_C0 = 0.28209479177387814  # Y_0^0


@dataclasses.dataclass
class Gaussians:
    """G Gaussians with activated parameters; see the module docstring for shapes and units."""

    means: Any
    quats: Any
    scales: Any
    opacities: Any
    sh: Any

    @property
    def count(self) -> int:
        return int(self.means.shape[0])

    @property
    def sh_degree(self) -> int:
        return int(round(math.sqrt(int(self.sh.shape[1])))) - 1

    def validate(self, source: str = "avatar") -> "Gaussians":
        """InputError naming ``source`` unless the shapes agree and K is a square (degree 0..3)."""
        g = int(self.means.shape[0])
        expected = {"means": (g, 3), "quats": (g, 4), "scales": (g, 3), "opacities": (g,)}
        for name, shape in expected.items():
            if tuple(getattr(self, name).shape) != shape:
                raise InputError(f"{name} has shape {tuple(getattr(self, name).shape)}, expected {shape}",
                                 source=source)
        k = int(self.sh.shape[1]) if len(self.sh.shape) == 3 else -1
        if len(self.sh.shape) != 3 or self.sh.shape[0] != g or self.sh.shape[2] != 3 or k not in (1, 4, 9, 16):
            raise InputError(f"sh has shape {tuple(self.sh.shape)}, expected ({g}, K, 3) with K in 1, 4, 9, 16",
                             source=source)
        return self

    def to_numpy(self) -> "Gaussians":
        def conv(a):
            if isinstance(a, np.ndarray):
                return np.ascontiguousarray(a, dtype=np.float32)
            return a.detach().to("cpu").float().contiguous().numpy()

        return Gaussians(*(conv(getattr(self, f.name)) for f in dataclasses.fields(self)))

    def to_torch(self, device: str = "cpu") -> "Gaussians":
        import torch

        def conv(a):
            if isinstance(a, np.ndarray):
                return torch.from_numpy(np.ascontiguousarray(a, dtype=np.float32)).to(device)
            return a.to(device=device, dtype=torch.float32)

        return Gaussians(*(conv(getattr(self, f.name)) for f in dataclasses.fields(self)))

    def bounding_box(self) -> tuple[np.ndarray, np.ndarray]:
        """(min, max) of the centres, (3,) float64 each."""
        means = self.to_numpy().means if not isinstance(self.means, np.ndarray) else self.means
        return means.min(axis=0).astype(np.float64), means.max(axis=0).astype(np.float64)
