"""The light of the virtual panel reaching each camera pixel: the numba ray kernel.

Radiance (:func:`render_radiance`)
    Every sensor pixel integrates an ``n x n`` grid of stratified rays over its area.  The
    pixel's four corner rays are traced exactly to the lens plane (undistortion exact on a grid
    every ``GRID_STEP`` pixels, bilinear in between: < 0.001 px); the rays inside the pixel are
    bilinear between the corners' lens-plane points.  Every ray that lands on the lens sheet
    shows its seen point (:mod:`.optics`), blurred across the lens by a Gaussian
    ``sigma_u(theta)`` (or the sum of Gaussians of another blur shape, each weighted by the
    lenticule's aperture: :meth:`.optics.PanelOptics.blur_components`).  The light of the neighbouring subpixels' open apertures is integrated
    analytically (the Gaussian CDF, from a table):

    * across x: the blur, taken along x with ``sigma_x = sigma_u / cos(phi)`` (approximation:
      the true blur runs across u; the difference is a shift along the lens axis of at most
      a few hundredths of a row);
    * along the lens: a ray stands for a stretch of the lens axis (its share of the pixel's
      footprint, a box of the same variance); the seen point runs along ``dX = 3 C_r dY``
      through rows and their black matrix; each row's open part is cut out exactly, and the
      blurred point's light is integrated exactly over its X-extent there (the integral of the
      Gaussian CDF, from a second table).  Folding that extent into the blur as a Gaussian of
      equal variance instead made a coarse camera's rays, a row or more long, see a view's core
      flatter: the crosstalk truth's eye (6 rows per ray) took a sharp panel's own-view share
      0.008 too high.

    Also: sheet scatter (a share of the light from the raster around the seen point, averaged
    over ``SCATTER_BLOCK``-pixel cells), angular fall-off and backlight non-uniformity of the
    panel, the dark bezel and the dim background.  Raster values are sRGB-decoded to linear
    light.  The result is linear light per panel primary (R, G, B) per sensor pixel.

The camera's photometric chain and the photo files are :mod:`.photo`'s.
"""

from __future__ import annotations

import functools
import math

import numpy as np
from numba import njit, prange

from ..core import sizes
from ..core.colour import srgb_decode_lut
from .camera import Camera
from .gaussian_cover import PHI_TABLE, coverage
from .scene import Scene

GRID_STEP = 4  # pixels between exactly undistorted grid points
SCATTER_BLOCK = 8  # panel pixels per cell of the scattered-light map
ROW_BLOCK = 16  # sensor rows per parallel task (corner rays are shared between adjacent rows)


@njit(cache=True, inline="always")
def _corner_ray(gx, gy, grid_step, jc, ic, rot, cam, plane):
    """Lens-plane point (x, y) of the ray through pixel corner (jc, ic); NaN if it misses."""
    fx = jc / grid_step
    fy = ic / grid_step
    j0 = min(int(fx), gx.shape[1] - 2)
    i0 = min(int(fy), gx.shape[0] - 2)
    ax = fx - j0
    ay = fy - i0
    xn = ((1 - ay) * ((1 - ax) * gx[i0, j0] + ax * gx[i0, j0 + 1])
          + ay * ((1 - ax) * gx[i0 + 1, j0] + ax * gx[i0 + 1, j0 + 1]))
    yn = ((1 - ay) * ((1 - ax) * gy[i0, j0] + ax * gy[i0, j0 + 1])
          + ay * ((1 - ax) * gy[i0 + 1, j0] + ax * gy[i0 + 1, j0 + 1]))
    dx = rot[0, 0] * xn + rot[0, 1] * yn + rot[0, 2]
    dy = rot[1, 0] * xn + rot[1, 1] * yn + rot[1, 2]
    dz = rot[2, 0] * xn + rot[2, 1] * yn + rot[2, 2]
    if dz <= 1e-9:
        return np.nan, np.nan
    t = plane / dz
    return cam[0] + t * dx, cam[1] + t * dy


@njit(cache=True, inline="always")
def _seen_light(sx, sy, h_y, sig2, weight, acc, raster, lut, chan_of_pos, table, slope, bmh, bmv, big_h, nsub,
                shifts, reach):
    """Add ``weight`` times the light seen around raster point (sx, sy) to ``acc`` (per panel primary).

    The seen point sweeps a stretch ``h_y`` rows long along the lens axis (dX = slope dY); each
    row's open aperture is cut out of it exactly, and the Gaussian blur (variance ``sig2``,
    subpixels^2) around it is integrated exactly over its X-extent there (:func:`coverage`).

    ``reach`` 0: a stripe panel (slot ``pos`` of a pixel shows channel ``chan_of_pos[pos]``).
    Otherwise a subpixel layout (:func:`_layout_seen`): every slot's aperture at its channel's
    true centre.
    """
    if reach > 0.0:
        _layout_seen(sx, sy, h_y, sig2, weight, acc, raster, lut, table, slope, bmh, bmv, big_h, nsub, shifts, reach)
        return
    half_bmh = 0.5 * bmh
    open_w = 1.0 - bmh
    s = math.sqrt(sig2)
    y0 = sy - 0.5 * h_y
    y1 = sy + 0.5 * h_y
    r_lo = max(int(math.floor(y0)), 0)
    r_hi = min(int(math.floor(y1)), big_h - 1)
    for r in range(r_lo, r_hi + 1):
        a0 = max(y0, r + 0.5 * bmv)
        a1 = min(y1, r + 1.0 - 0.5 * bmv)
        seg = a1 - a0
        if seg <= 0.0:
            continue
        wr = seg / h_y * weight
        xm = sx + (0.5 * (a0 + a1) - sy) * slope
        ext = abs(seg * slope)
        # subpixels whose aperture meets [xm - 4 s - ext/2, xm + 4 s + ext/2]
        half = 4.0 * s + 0.5 * ext
        c_lo = max(int(math.floor(xm - half - 1.0 + half_bmh)) + 1, 0)
        c_hi = min(int(math.ceil(xm + half - half_bmh)) - 1, nsub - 1)
        if c_hi < c_lo:
            continue
        px = c_lo // 3
        pos = c_lo - 3 * px
        lo = c_lo + half_bmh - xm
        for _ in range(c_lo, c_hi + 1):
            c = chan_of_pos[pos]
            value = lut[raster[r, px, c]]
            if value != 0.0:  # a dark subpixel adds nothing: its coverage is not needed
                acc[c] += wr * coverage(lo, open_w, ext, s, table) * value
            lo += 1.0
            pos += 1
            if pos == 3:
                pos = 0
                px += 1


@njit(cache=True, inline="always")
def _layout_seen(sx, sy, h_y, sig2, weight, acc, raster, lut, table, slope, bmh, bmv, big_h, nsub, shifts, reach):
    """:func:`_seen_light` on a panel with a subpixel layout.

    ``shifts`` float64 ``(2, rows, 3 columns)``: for slot ``c`` of pixel ``px`` in row ``r``, at
    ``[:, r % rows, 3 (px % columns) + c]``, its channel's centre relative to the stripe RGB
    slot's: along the row in subpixels (``1 + 3 dx - c``) and down in rows (``dy``).  The slot's
    open aperture (the stripe subpixel's, black matrix included) is centred there: it spans
    ``X`` in ``[3 px + c + shift + bmh/2, ... + 1 - bmh/2)`` and ``Y`` in
    ``[r + dy + bmv/2, r + 1 + dy - bmv/2)``; the seen stretch is cut by it exactly, as for a
    stripe.  ``reach``: the largest ``|shift|`` plus 1 (subpixels); the largest ``|dy|`` is
    found from the table.
    """
    half_bmh = 0.5 * bmh
    open_w = 1.0 - bmh
    y0 = sy - 0.5 * h_y
    y1 = sy + 0.5 * h_y
    srows = shifts.shape[1]
    scols = shifts.shape[2] // 3
    yreach = 0.0
    for i in range(srows):
        for j in range(shifts.shape[2]):
            yreach = max(yreach, abs(shifts[1, i, j]))
    seg_max = min(h_y, 1.0)
    s = math.sqrt(sig2)
    blur_reach = 4.0 * s + 0.5 * seg_max * abs(slope)  # 4 sigma plus half a row's X-extent
    r_lo = max(int(math.floor(y0 - yreach)), 0)
    r_hi = min(int(math.floor(y1 + yreach)), big_h - 1)
    for r in range(r_lo, r_hi + 1):
        srow = r % srows
        xr = sx + (r + 0.5 - sy) * slope  # the seen line at the row's centre
        spread = blur_reach + reach + (yreach + 0.5) * abs(slope)
        q_lo = max(int(math.floor(xr - spread)), 0)
        q_hi = min(int(math.ceil(xr + spread)), nsub - 1)
        for q in range(q_lo, q_hi + 1):
            px = q // 3
            c = q - 3 * px
            value = lut[raster[r, px, c]]
            if value == 0.0:  # a dark subpixel adds nothing
                continue
            col = 3 * (px % scols) + c
            dy = shifts[1, srow, col]
            a0 = max(y0, r + dy + 0.5 * bmv)
            a1 = min(y1, r + 1.0 + dy - 0.5 * bmv)
            seg = a1 - a0
            if seg <= 0.0:
                continue
            xm = sx + (0.5 * (a0 + a1) - sy) * slope
            cov = coverage(q + shifts[0, srow, col] + half_bmh - xm, open_w, abs(seg * slope), s, table)
            if cov > 0.0:
                acc[c] += seg / h_y * weight * cov * value


@njit(parallel=True, cache=True, error_model="numpy")
def _render_kernel(raster, lut, chan_of_pos, gx, gy, grid_step, rot, cam, prm, table, scatter_map, shifts, reach,
                   mix, out):
    """Linear light per panel primary for every sensor pixel into ``out`` (h, w, 3) float32.

    ``prm`` (float64): cos phi, sin phi, P_u, x0 cos phi, g, p, W, H, black matrix h, v,
    sigma0 (subpixel widths, across u), blur growth, sheet half-width, half-height, bezel
    half-width, half-height, bezel level, background level, angular falloff, scatter,
    5 backlight coefficients, subsamples n, the lenticule aperture (subpixel widths along x; 0 =
    none).  ``shifts``/``reach``: the channel offsets of a subpixel layout (reach 0 on a stripe
    panel, see :func:`_layout_seen`).  ``mix`` ``(K, 3)``: the blur's Gaussians (weight, offset,
    scale; :meth:`.optics.PanelOptics.blur_components`).
    """
    h, w = out.shape[0], out.shape[1]
    dist = -cam[2]
    n_blocks = (h + ROW_BLOCK - 1) // ROW_BLOCK
    for blk in prange(n_blocks):
        top_x = np.empty(w + 1)
        top_y = np.empty(w + 1)
        bot_x = np.empty(w + 1)
        bot_y = np.empty(w + 1)
        acc = np.zeros(3)
        i_first = blk * ROW_BLOCK
        for jc in range(w + 1):
            bot_x[jc], bot_y[jc] = _corner_ray(gx, gy, grid_step, jc, i_first, rot, cam, dist)
        for i in range(i_first, min(i_first + ROW_BLOCK, h)):
            top_x, bot_x = bot_x, top_x  # the previous row's bottom corners are this row's top
            top_y, bot_y = bot_y, top_y
            for jc in range(w + 1):
                bot_x[jc], bot_y[jc] = _corner_ray(gx, gy, grid_step, jc, i + 1, rot, cam, dist)
            _render_row(i, top_x, top_y, bot_x, bot_y, acc, raster, lut, chan_of_pos, cam, prm, table,
                        scatter_map, shifts, reach, mix, out)


@njit(cache=True, error_model="numpy")
def _render_row(i, top_x, top_y, bot_x, bot_y, acc, raster, lut, chan_of_pos, cam, prm, table, scatter_map, shifts,
                reach, mix, out):
    """Sensor row ``i`` given the lens-plane points of its top and bottom pixel corners."""
    w = out.shape[1]
    cphi, sphi, pu, x0u, gap, pitch = prm[0], prm[1], prm[2], prm[3], prm[4], prm[5]
    n_w, n_h = prm[6], prm[7]
    bmh, bmv, sigma0, growth = prm[8], prm[9], prm[10], prm[11]
    sheet_w, sheet_h, bezel_w, bezel_h = prm[12], prm[13], prm[14], prm[15]
    bezel_level, background, falloff, scatter = prm[16], prm[17], prm[18], prm[19]
    b_x, b_y, b_xx, b_yy, b_xy = prm[20], prm[21], prm[22], prm[23], prm[24]
    n = int(prm[25])
    aperture2 = prm[26] * prm[26]  # lenticule vignetting, subpixel widths squared (0: none)
    x_per_u = 3.0 / (pitch * cphi)  # subpixel widths along x per mm across the lens
    big_h = int(n_h)
    nsub = 3 * int(n_w)
    dist = -cam[2]
    ratio = gap / dist
    u_e = cam[0] * cphi - cam[1] * sphi
    v_e = cam[0] * sphi + cam[1] * cphi
    slope = 3.0 * sphi / cphi  # dX / dY along the lens axis
    y_per_v = (1.0 + ratio) * cphi / pitch  # rows of the seen point per mm of lens-plane v
    half_w_mm = 0.5 * n_w * pitch
    half_h_mm = 0.5 * n_h * pitch
    open_mean = (1.0 - bmh) * (1.0 - bmv)
    sc_h, sc_w = scatter_map.shape[0], scatter_map.shape[1]
    total = float(n * n)
    for j in range(w):
        x00, y00, x10, y10 = top_x[j], top_y[j], top_x[j + 1], top_y[j + 1]
        x01, y01, x11, y11 = bot_x[j], bot_y[j], bot_x[j + 1], bot_y[j + 1]
        if np.isnan(x00) or np.isnan(x10) or np.isnan(x01) or np.isnan(x11):
            for c in range(3):
                out[i, j, c] = background
            continue
        xc = 0.25 * (x00 + x10 + x01 + x11)
        yc = 0.25 * (y00 + y10 + y01 + y11)
        tan2 = ((xc - cam[0]) ** 2 + (yc - cam[1]) ** 2) / (dist * dist)
        cos_t = 1.0 / math.sqrt(1.0 + tan2)
        xn_ = xc / half_w_mm
        yn_ = yc / half_h_mm
        gain = (cos_t ** falloff) * (1.0 + b_x * xn_ + b_y * yn_ + b_xx * xn_ * xn_
                                     + b_yy * yn_ * yn_ + b_xy * xn_ * yn_)
        sigma_x = sigma0 * (1.0 + growth * tan2) / cphi
        sig2 = sigma_x * sigma_x
        # lens-plane v spanned by the whole pixel along its two sides
        dv_h = (x10 - x00) * sphi + (y10 - y00) * cphi
        dv_v = (x01 - x00) * sphi + (y01 - y00) * cphi
        # one ray's share: a variance-matched stretch of the lens axis, in rows
        h_y = max(math.sqrt(dv_h * dv_h + dv_v * dv_v) / n * y_per_v, 1e-6)
        acc[0] = 0.0
        acc[1] = 0.0
        acc[2] = 0.0
        grey = 0.0
        on_panel = 0.0
        sum_x = 0.0
        sum_y = 0.0
        for b in range(n):
            fy = (b + 0.5) / n
            for a in range(n):
                fx = (a + 0.5) / n
                lx = (1 - fy) * ((1 - fx) * x00 + fx * x10) + fy * ((1 - fx) * x01 + fx * x11)
                ly = (1 - fy) * ((1 - fx) * y00 + fx * y10) + fy * ((1 - fx) * y01 + fx * y11)
                if abs(lx) > sheet_w or abs(ly) > sheet_h:
                    if abs(lx) <= bezel_w and abs(ly) <= bezel_h:
                        grey += bezel_level
                    else:
                        grey += background
                    continue
                u_l = lx * cphi - ly * sphi
                v_l = lx * sphi + ly * cphi
                k = math.floor((u_l - x0u) / pu)
                u_c = x0u + (k + 0.5) * pu
                u_p = u_c + (u_c - u_e) * ratio
                v_p = v_l + (v_l - v_e) * ratio
                sx = (u_p * cphi + v_p * sphi + half_w_mm) * 3.0 / pitch
                sy = (-u_p * sphi + v_p * cphi + half_h_mm) / pitch
                on_panel += 1.0
                sum_x += sx
                sum_y += sy
                for q in range(mix.shape[0]):
                    wq = mix[q, 0]
                    mu = mix[q, 1] * sigma_x
                    vq = sig2 * mix[q, 2] * mix[q, 2]
                    if aperture2 > 0.0:
                        # Gaussian blur times the lens' Gaussian aperture weight exp(-(o + d)^2 / 2a^2)
                        # (o the seen point's offset from its lens' axis): again a Gaussian
                        o = (u_p - u_c) * x_per_u
                        den = vq + aperture2
                        wq *= math.sqrt(aperture2 / den) * math.exp(-0.5 * (o + mu) ** 2 / den)
                        mu = (mu * aperture2 - o * vq) / den
                        vq = vq * aperture2 / den
                    _seen_light(sx + mu, sy, h_y, vq, wq, acc, raster, lut, chan_of_pos, table, slope,
                                bmh, bmv, big_h, nsub, shifts, reach)
        if on_panel > 0 and scatter > 0.0:
            # scattered light: the raster around the mean seen point, wide and dim
            mx = min(max(sum_x / on_panel / (3.0 * SCATTER_BLOCK) - 0.5, 0.0), sc_w - 1.0)
            my = min(max(sum_y / on_panel / SCATTER_BLOCK - 0.5, 0.0), sc_h - 1.0)
            j0 = min(int(mx), max(sc_w - 2, 0))
            i0 = min(int(my), max(sc_h - 2, 0))
            j1 = min(j0 + 1, sc_w - 1)
            i1 = min(i0 + 1, sc_h - 1)
            ax = mx - j0
            ay = my - i0
            for c in range(3):
                sval = ((1 - ay) * ((1 - ax) * scatter_map[i0, j0, c] + ax * scatter_map[i0, j1, c])
                        + ay * ((1 - ax) * scatter_map[i1, j0, c] + ax * scatter_map[i1, j1, c]))
                acc[c] = (1.0 - scatter) * acc[c] + scatter * open_mean * sval * on_panel
        for c in range(3):
            out[i, j, c] = (acc[c] * gain + grey) / total


@functools.lru_cache(maxsize=4)
def undistortion_grid(width: int, height: int, fx: float, fy: float, cx: float, cy: float,
                       distortion: tuple, step: int) -> tuple[np.ndarray, np.ndarray]:
    """Normalized undistorted coordinates at pixel coordinates (J step - 0.5, I step - 0.5)."""
    geometry = Camera(width=width, height=height, fx=fx, fy=fy, cx=cx, cy=cy, distortion=distortion,
                      position=(0.0, 0.0, -1.0))
    gw = -(-width // step) + 2
    gh = -(-height // step) + 2
    jj, ii = np.meshgrid(np.arange(gw) * float(step) - 0.5, np.arange(gh) * float(step) - 0.5)
    xn, yn = geometry.normalized(jj, ii)
    xn.setflags(write=False)
    yn.setflags(write=False)
    return np.ascontiguousarray(xn), np.ascontiguousarray(yn)


def _scatter_map(raster: np.ndarray, lut: np.ndarray) -> np.ndarray:
    """Linear raster averaged over SCATTER_BLOCK-pixel cells and blurred: float64 (h', w', 3)."""
    import cv2

    linear = cv2.LUT(raster, lut.astype(np.float32).reshape(1, 256))
    h, w = raster.shape[:2]
    small = cv2.resize(linear, (max(1, w // SCATTER_BLOCK), max(1, h // SCATTER_BLOCK)),
                       interpolation=cv2.INTER_AREA)
    small = cv2.GaussianBlur(small, (0, 0), 1.5, borderType=cv2.BORDER_REFLECT)
    return np.ascontiguousarray(small.reshape(small.shape[0], small.shape[1], 3), dtype=np.float64)


def _kernel_params(scene: Scene) -> np.ndarray:
    o, cam = scene.optics, scene.camera
    cphi, sphi = math.cos(o.slant_angle), math.sin(o.slant_angle)
    half_w, half_h = 0.5 * o.width * o.pixel_pitch, 0.5 * o.height * o.pixel_pitch
    sheet_w, sheet_h = half_w + o.sheet_margin, half_h + o.sheet_margin
    return np.array([cphi, sphi, o.lens_pitch_u, o.x0 * cphi, o.gap, o.pixel_pitch, o.width, o.height,
                     o.black_matrix_h, o.black_matrix_v, o.blur_sigma / (o.pixel_pitch / 3.0), o.blur_growth,
                     sheet_w, sheet_h, sheet_w + o.bezel_width, sheet_h + o.bezel_width, o.bezel_level,
                     o.background_level, o.angular_falloff, o.scatter, *o.backlight, cam.subsamples,
                     o.lenticule_aperture * o.lens_pitch_u * 3.0 / (o.pixel_pitch * cphi)],
                    dtype=np.float64)


def check_raster(raster: np.ndarray, scene: Scene, source: str = "raster") -> np.ndarray:
    """The raster as C-contiguous uint8 ``(H, W, 3)``; ImageError unless it fits the scene's panel."""
    return sizes.check_raster(raster, scene.optics.width, scene.optics.height, source, "the simulated panel",
                              hint="write the patterns at the simulated panel's size with 'lenticalib patterns'")


def render_radiance(raster: np.ndarray, scene: Scene) -> np.ndarray:
    """Linear light of each panel primary reaching each sensor pixel.

    ARGUMENTS
    raster    uint8 ``(H, W, 3)`` RGB, sRGB-encoded, what the panel shows (H, W of the scene)
    scene     the panel and camera

    RETURNED VALUE
    float32 ``(h, w, 3)`` (camera sensor size), [..., c] = light of panel primary c (R, G, B);
    1.0 = a fully open white subpixel seen head-on (the black matrix makes a white panel
    about ``(1 - bm_h)(1 - bm_v)``).  Bezel and background light is grey (equal in all three).
    """
    raster = check_raster(raster, scene)
    cam = scene.camera
    lut = srgb_decode_lut()
    gx, gy = undistortion_grid(cam.width, cam.height, cam.fx, cam.fy, cam.cx, cam.cy,
                                tuple(float(v) for v in cam.distortion), GRID_STEP)
    rot = np.ascontiguousarray(cam.rotation)
    position = np.asarray(cam.position, np.float64)
    chan_of_pos = np.array([scene.optics.rho.index(pos) for pos in range(3)], dtype=np.int64)
    scatter = _scatter_map(raster, lut) if scene.optics.scatter > 0 else np.zeros((1, 1, 3))
    shifts = np.ascontiguousarray(scene.optics.channel_offsets(), dtype=np.float64)
    reach = 0.0 if scene.optics.subpixel_layout is None else float(np.abs(shifts[0]).max()) + 1.0
    out = np.empty((cam.height, cam.width, 3), dtype=np.float32)
    _render_kernel(raster, lut, chan_of_pos, gx, gy, float(GRID_STEP), rot, position,
                   _kernel_params(scene), PHI_TABLE, scatter, shifts, reach,
                   np.ascontiguousarray(scene.optics.blur_components(), dtype=np.float64), out)
    return out
