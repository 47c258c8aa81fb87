"""The ``gsplat`` renderer: gsplat's CUDA rasterizer, all N views in one batched call.

Minimal, and not run by the tests here (they have no GPU): the ``cpu`` renderer reproduces the same
forward pass and is tested against gsplat's pure-torch reference.  torch and gsplat are imported
inside the functions, so this module imports without them; :func:`gsplat_unavailable` is what the
renderer registry asks before it hands the renderer out (one line, before anything is loaded).

The ``Ks`` given are OpenCV's (pixel centres at integer coordinates); gsplat samples pixel (i, j)
at (j + 0.5, i + 0.5), so cx and cy are shifted by + 0.5 before the call.
"""

from __future__ import annotations

import importlib.util

from ...core.errors import BackendUnavailableError
from ..avatar.gaussians import Gaussians
from ..gpu.torch_devices import device_unavailable
from ..cameras.view_cameras import NEAR_PLANE
from .common import EPS2D, FAR_PLANE, TILE_SIZE, check_render_inputs


def gsplat_unavailable(device: str | None = None) -> str | None:
    """Why the gsplat renderer cannot run here on torch ``device`` (one line), or None.

    Imports torch (asked only when this renderer is), finds gsplat without importing it, and
    initialises no GPU.
    """
    if importlib.util.find_spec("torch") is None:
        return "it needs torch (pip install torch)"
    import torch

    if not torch.cuda.is_available():
        return "it needs a CUDA GPU and torch sees none"
    if device is not None:
        reason = device_unavailable(device)
        if reason is not None:
            return reason
        if torch.device(device).type != "cuda":
            return f"it renders on a CUDA device, not on {device!r}"
    if importlib.util.find_spec("gsplat") is None:
        return "it needs gsplat (pip install gsplat)"
    return None


def render_gsplat(gaussians: Gaussians, viewmats, Ks, width: int, height: int, *, background=None):
    """Like :func:`lenticalib.render.renderers.cpu.render_cpu`; returns a (N, H, W, 4) float32 torch
    tensor on the GPU.  Raises BackendUnavailableError without torch, gsplat or a CUDA GPU.
    """
    viewmats, Ks, background = check_render_inputs(gaussians, viewmats, Ks, width, height, background)
    reason = gsplat_unavailable()
    if reason is not None:
        raise BackendUnavailableError(f"renderer 'gsplat' cannot run here: {reason}", source="renderer",
                                      hint="use `renderer` cpu")
    import gsplat
    import torch

    device = "cuda"
    g = gaussians.to_torch(device)
    n = viewmats.shape[0]
    ks = torch.as_tensor(Ks, dtype=torch.float32, device=device).clone()
    ks[:, 0, 2] += 0.5
    ks[:, 1, 2] += 0.5
    vms = torch.as_tensor(viewmats, dtype=torch.float32, device=device)
    backgrounds = None
    if background is not None:
        backgrounds = torch.as_tensor(background, dtype=torch.float32, device=device).expand(n, 3).contiguous()
    colours, alphas, _ = gsplat.rasterization(
        g.means, g.quats, g.scales, g.opacities, g.sh, vms, ks, width, height,
        near_plane=NEAR_PLANE, far_plane=FAR_PLANE, eps2d=EPS2D, sh_degree=g.sh_degree,
        packed=False, tile_size=TILE_SIZE, backgrounds=backgrounds, render_mode="RGB",
        rasterize_mode="classic")
    return torch.cat([colours, alphas], dim=-1)


render_gsplat.unavailable = gsplat_unavailable  # asked by the registry (lenticalib.core.plugins)
