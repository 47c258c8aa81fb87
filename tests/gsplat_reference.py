"""gsplat's pure-torch forward pass, the golden model of the ``cpu`` renderer (tests only, CPU).

Projection, SH colour, tile intersection and tile offsets are gsplat's own torch twins of its CUDA
kernels (``gsplat/cuda/_torch_impl.py``: ``_quat_scale_to_covar_preci``, ``_fully_fused_projection``,
``_spherical_harmonics``, ``_isect_tiles``, ``_isect_offset_encode``), in float32 as gsplat runs.
Compositing is written here: gsplat's torch ``_rasterize_to_pixels`` needs its CUDA
``rasterize_to_indices_in_range`` and nerfacc, so this is ``RasterizeToPixels3DGSFwd.cu`` restated
as tensor operations per tile (alpha = min(0.999, o exp(-sigma)); skipped if sigma < 0 or
alpha < 1/255; the pixel stops before the Gaussian that would take T to <= 1e-4), with a
cumulative product over the tile's depth-sorted list instead of a loop: a different structure from
the numba kernel's, on purpose.
"""

from __future__ import annotations

import math

import numpy as np


def render_reference(gaussians, viewmats, Ks, width, height, background=None, tile_size=16):
    """(N, H, W, 4) float32 numpy, RGB over ``background`` and alpha, OpenCV ``Ks`` (shifted here)."""
    import torch
    from gsplat.cuda._torch_impl import (_fully_fused_projection, _isect_offset_encode, _isect_tiles,
                                         _quat_scale_to_covar_preci, _spherical_harmonics)

    g = gaussians.to_torch("cpu")
    vms = torch.as_tensor(np.asarray(viewmats), dtype=torch.float32)
    ks = torch.as_tensor(np.asarray(Ks), dtype=torch.float32).clone()
    ks[:, 0, 2] += 0.5  # OpenCV pixel centres -> gsplat's (j + 0.5, i + 0.5)
    ks[:, 1, 2] += 0.5
    n_cam, count = vms.shape[0], g.count
    covars, _ = _quat_scale_to_covar_preci(g.quats, g.scales, True, False, triu=False)
    radii, means2d, depths, conics, _ = _fully_fused_projection(
        g.means, covars, vms, ks, width, height, eps2d=0.3, near_plane=0.01, far_plane=1e10)
    campos = torch.inverse(vms)[:, :3, 3]
    dirs = g.means[None, :, :] - campos[:, None, :]
    shs = g.sh[None].expand(n_cam, -1, -1, -1)
    colours = torch.clamp_min(_spherical_harmonics(g.sh_degree, dirs, shs) + 0.5, 0.0)  # (C, N, 3)

    tiles_x, tiles_y = math.ceil(width / tile_size), math.ceil(height / tile_size)
    _, isect_ids, flatten_ids = _isect_tiles(means2d, radii, depths, tile_size, tiles_x, tiles_y)
    offsets = _isect_offset_encode(isect_ids, n_cam, tiles_x, tiles_y).reshape(-1)
    ends = torch.cat([offsets[1:], torch.tensor([len(flatten_ids)], dtype=offsets.dtype)])

    xy = means2d.reshape(-1, 2)
    con = conics.reshape(-1, 3)
    opac = g.opacities[None].expand(n_cam, -1).reshape(-1)
    col = colours.reshape(-1, 3)
    bg = torch.zeros(3) if background is None else torch.as_tensor(np.asarray(background), dtype=torch.float32)
    out = np.empty((n_cam, height, width, 4), dtype=np.float32)
    for tile in range(n_cam * tiles_y * tiles_x):
        cam, rest = divmod(tile, tiles_y * tiles_x)
        ty, tx = divmod(rest, tiles_x)
        ys = torch.arange(ty * tile_size, min((ty + 1) * tile_size, height))
        xs = torch.arange(tx * tile_size, min((tx + 1) * tile_size, width))
        py, px = torch.meshgrid(ys.float() + 0.5, xs.float() + 0.5, indexing="ij")
        ids = flatten_ids[offsets[tile]:ends[tile]].long()  # front to back
        assert bool(((ids // count) == cam).all())
        dx = xy[ids, 0][None, :] - px.reshape(-1, 1)  # (P, M), gsplat's delta = mean - pixel
        dy = xy[ids, 1][None, :] - py.reshape(-1, 1)
        c = con[ids]
        sigma = 0.5 * (c[:, 0] * dx * dx + c[:, 2] * dy * dy) + c[:, 1] * dx * dy
        alpha = torch.clamp_max(opac[ids] * torch.exp(-sigma), 0.999)
        alpha = torch.where((sigma >= 0) & (alpha >= 1.0 / 255.0), alpha, torch.zeros(()))
        stopped = torch.cumsum((torch.cumprod(1.0 - alpha, dim=1) <= 1e-4).int(), dim=1) > 0
        alpha = torch.where(stopped, torch.zeros(()), alpha)
        trans_after = torch.cumprod(1.0 - alpha, dim=1)
        trans_before = torch.cat([torch.ones(len(trans_after), 1), trans_after[:, :-1]], dim=1)
        rgb = (alpha * trans_before) @ col[ids]  # (P, 3)
        t_final = trans_after[:, -1] if len(ids) else torch.ones(len(rgb))
        rgba = torch.cat([rgb + t_final[:, None] * bg, (1.0 - t_final)[:, None]], dim=1)
        out[cam, ys[0]:ys[-1] + 1, xs[0]:xs[-1] + 1] = rgba.reshape(len(ys), len(xs), 4).numpy()
    return out
