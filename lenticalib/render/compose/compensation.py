"""Crosstalk pre-compensation: the views to send so that each eye sees what it should.

Frames and units: views ``(N, H, W, 3)``, sRGB-encoded uint8 (or float in [0, 1]); the
computation is in linear light.  ``M`` is the measured mixing matrix (``crosstalk.json``):
an eye at the centre of view ``i``'s zone sees ``s_i = sum_j M[i][j] e_j`` of what the views
``e`` send at the same place of the picture (per colour).

Problem, at every pixel and colour of the views (``t`` the intended views, lifted by the black
lift ``b``: ``t = b + (1 - b) v``, so that darkening a neighbour's leak is possible):

    minimise ||M e - t||^2 + lam ||e - t||^2   subject to 0 <= e <= 1

``M`` is circulant (a panel whose optics do not vary across it, measured through its centre;
a general matrix is replaced by its diagonal means), so everything is a circular filter along
the view axis: the unconstrained solution ``e = C t`` with ``C = (M^T M + lam I)^-1 (M^T + lam I)``
(its taps precomputed once per matrix, truncated where they fall below ``TAP_FLOOR``), then
clipped to [0, 1] and improved by ``iterations`` projected-gradient steps of the bounded problem
(step ``1 / ||M^T M + lam I||``), each a filter too.  Applied per frame by a numba kernel that
walks the pixels in cache-sized chunks (:meth:`Compensator.apply`), or on the GPU by torch
(:meth:`Compensator.apply_torch`, circular 1-D convolution along the views).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
from numba import njit, prange, types
from numba.extending import overload

from ...core.colour import srgb_decode_lut, srgb_encode8
from ...core.crosstalk_document import measured_for, mixing_matrix, read_crosstalk_document
from ...core.errors import InputError
from ...core.identity import check_same_panel

TAP_FLOOR = 2e-3
DEFAULT_REGULARISATION = 0.02
DEFAULT_ITERATIONS = 2
_LEVELS = 4096  # linear -> sRGB table resolution
_CHUNK = 2048  # pixel-channels per chunk (N x CHUNK floats stay in cache)
MIN_CONDITION = 1e-12  # smallest over largest eigenvalue of M^T M + lam I: below it the solve is singular


def circulant_row(matrix: np.ndarray) -> np.ndarray:
    """The circulant row (N,) of ``matrix`` (N, N): the mean of each wrapped diagonal, ``row[m] = mean_i M[i][i+m]``."""
    m = np.asarray(matrix, np.float64)
    n = m.shape[0]
    idx = np.arange(n)
    return np.array([m[idx, (idx + k) % n].mean() for k in range(n)])


def _circulant_taps(row: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(offsets, weights) of a circulant row, dropping taps below TAP_FLOOR (relative to the largest) and
    rescaling the rest so the filter keeps its response to an even picture (the sum of the row)."""
    n = row.size
    offsets = np.arange(n) - n * (np.arange(n) > n // 2)
    keep = np.abs(row) >= TAP_FLOOR * np.abs(row).max()
    order = np.argsort(offsets[keep])
    weights = row[keep][order]
    if abs(weights.sum()) > 1e-12:
        weights = weights * (row.sum() / weights.sum())
    return offsets[keep][order].astype(np.int64), weights.astype(np.float32)


@dataclasses.dataclass(frozen=True)
class Compensator:
    """Precomputed pre-compensation for one mixing matrix (see the module docstring).

    ``mixing``: (N,) circulant row of M; ``solve_*``: taps of C; ``normal_*``: taps of
    ``M^T M + lam I``; ``rhs_*``: taps of ``M^T + lam I``; ``step``: gradient step; ``origin``:
    what it was made from, for the output's provenance (:func:`compensator_from_file`: the
    crosstalk file and :func:`~lenticalib.core.identity.check_same_panel`'s record), or None.
    """

    views: int
    mixing: np.ndarray
    regularisation: float
    black_lift: float
    iterations: int
    solve_offsets: np.ndarray
    solve_weights: np.ndarray
    normal_offsets: np.ndarray
    normal_weights: np.ndarray
    rhs_offsets: np.ndarray
    rhs_weights: np.ndarray
    step: float
    origin: dict | None = dataclasses.field(default=None, compare=False)

    @classmethod
    def from_matrix(cls, matrix, regularisation: float = DEFAULT_REGULARISATION, black_lift: float = 0.0,
                    iterations: int = DEFAULT_ITERATIONS) -> "Compensator":
        matrix = np.asarray(matrix, np.float64)
        if matrix.ndim != 2 or matrix.shape[0] != matrix.shape[1] or matrix.shape[0] < 2:
            raise InputError(f"a mixing matrix must be N x N, got shape {matrix.shape}", source="crosstalk")
        if not (math.isfinite(regularisation) and 0.0 <= regularisation <= 10.0):
            raise InputError(f"regularisation {regularisation} is out of range", source="regularisation",
                             hint="use 0..10 (default 0.02)")
        if not (math.isfinite(black_lift) and 0.0 <= black_lift < 0.5):
            raise InputError(f"black lift {black_lift} is out of range", source="black_lift", hint="use 0..0.5")
        if not 0 <= iterations <= 50:
            raise InputError(f"{iterations} iterations is out of range", source="iterations", hint="use 0..50")
        row = circulant_row(matrix)
        n = row.size
        spectrum = np.fft.fft(row)  # eigenvalues of the circulant M (M[i][j] = row[j - i])
        lam = regularisation
        normal = np.abs(spectrum) ** 2 + lam
        if not normal.min() >= MIN_CONDITION * normal.max():  # a zero eigenvalue and no regularisation to lift it
            raise InputError(f"the mixing matrix is singular (its smallest eigenvalue is "
                             f"{np.abs(spectrum).min():.3g} of {np.abs(spectrum).max():.3g}) and regularisation "
                             f"{lam:g} cannot make it invertible", source="regularisation",
                             hint=f"use a positive regularisation, e.g. {DEFAULT_REGULARISATION:g} (the default)")
        solve = np.real(np.fft.ifft((np.conj(spectrum) + lam) / normal))
        normal_row = np.real(np.fft.ifft(normal))
        rhs_row = np.real(np.fft.ifft(np.conj(spectrum) + lam))
        so, sw = _circulant_taps(solve)
        no, nw = _circulant_taps(normal_row)
        ro, rw = _circulant_taps(rhs_row)
        return cls(n, row, float(lam), float(black_lift), int(iterations), so, sw, no, nw, ro, rw,
                   float(1.0 / normal.max()))

    # --- the model ---------------------------------------------------------------------------
    def seen(self, sent: np.ndarray, matrix: np.ndarray | None = None) -> np.ndarray:
        """What the eyes at the zone centres see: ``M @ sent`` along axis 0 (linear light, float64)."""
        m = np.asarray(matrix if matrix is not None else
                       self.mixing[(np.arange(self.views)[None, :] - np.arange(self.views)[:, None]) % self.views])
        return np.tensordot(m, np.asarray(sent, np.float64), axes=(1, 0))

    def target(self, linear: np.ndarray) -> np.ndarray:
        """The lifted intended views ``b + (1 - b) v`` (linear light)."""
        return self.black_lift + (1.0 - self.black_lift) * np.asarray(linear)

    # --- application -------------------------------------------------------------------------
    def apply_linear(self, linear: np.ndarray) -> np.ndarray:
        """float32 (N, P) linear intended views -> float32 (N, P) linear views to send, in [0, 1]."""
        linear = np.ascontiguousarray(linear, dtype=np.float32)
        if linear.ndim != 2 or linear.shape[0] != self.views:
            raise InputError(f"expected {self.views} views, got shape {linear.shape}", source="views")
        out = np.empty_like(linear)
        _compensate(linear, out, _NO_TABLE_F, _NO_TABLE_U, *self._kernel_args())
        return out

    def apply(self, views: np.ndarray) -> np.ndarray:
        """uint8 sRGB views (N, H, W, 3) -> uint8 sRGB views to send (same shape)."""
        if not (isinstance(views, np.ndarray) and views.dtype == np.uint8 and views.ndim == 4
                and views.shape[0] == self.views):
            raise InputError(f"expected {self.views} uint8 views (N, H, W, 3), got "
                             f"{getattr(views, 'dtype', type(views))} {getattr(views, 'shape', '')}", source="views")
        flat = np.ascontiguousarray(views).reshape(self.views, -1)
        out = np.empty_like(flat)
        _compensate(flat, out, decode_table(), encode_table(), *self._kernel_args())
        return out.reshape(views.shape)

    def _kernel_args(self):
        return (self.solve_offsets, self.solve_weights, self.normal_offsets, self.normal_weights,
                self.rhs_offsets, self.rhs_weights, np.float32(self.step), np.float32(self.black_lift),
                self.iterations)

    def apply_torch(self, views):
        """torch float tensor (N, ..., ) linear light on any device -> the views to send (same shape, float32).

        The same filters as :meth:`apply_linear` (circular along dim 0), as torch operations: no
        trip through host memory.
        """
        import torch

        n = self.views
        shape = views.shape
        x = views.reshape(n, -1).to(torch.float32)
        t = self.black_lift + (1.0 - self.black_lift) * x

        def filt(v, offsets, weights):
            acc = torch.zeros_like(v)
            for o, w in zip(offsets.tolist(), weights.tolist()):
                acc = acc + float(w) * torch.roll(v, shifts=-int(o), dims=0)
            return acc

        e = filt(t, self.solve_offsets, self.solve_weights).clamp_(0.0, 1.0)
        if self.iterations:
            b = filt(t, self.rhs_offsets, self.rhs_weights)
            for _ in range(self.iterations):
                e = (e - self.step * (filt(e, self.normal_offsets, self.normal_weights) - b)).clamp_(0.0, 1.0)
        return e.reshape(shape)


_DECODE = None
_ENCODE = None
_NO_TABLE_F = np.zeros(0, np.float32)
_NO_TABLE_U = np.zeros(0, np.uint8)


def decode_table() -> np.ndarray:
    """float32 (256,): linear light of each uint8 sRGB code, as the compensation reads views."""
    global _DECODE
    if _DECODE is None:
        _DECODE = srgb_decode_lut().astype(np.float32)
    return _DECODE


def encode_table() -> np.ndarray:
    """uint8 (_LEVELS,): the sRGB code of linear light ``k / (_LEVELS - 1)``, as the compensation
    writes views (index ``int(value * (_LEVELS - 1) + 0.5)``)."""
    global _ENCODE
    if _ENCODE is None:
        _ENCODE = srgb_encode8(np.arange(_LEVELS) / (_LEVELS - 1))
    return _ENCODE


@njit(cache=True, inline="always")
def _filter(src, dst, offsets, weights, n, width):
    for i in range(n):
        for p in range(width):
            dst[i, p] = 0.0
        for k in range(offsets.shape[0]):
            j = (i + offsets[k]) % n
            w = weights[k]
            for p in range(width):
                dst[i, p] += w * src[j, p]


@njit(cache=True, inline="always")
def _solve_chunk(t, e, g, b, so, sw, no, nw, ro, rw, step, iterations, n, width):
    _filter(t, e, so, sw, n, width)
    for i in range(n):
        for p in range(width):
            e[i, p] = min(max(e[i, p], 0.0), 1.0)
    if iterations > 0:
        _filter(t, b, ro, rw, n, width)
        for _ in range(iterations):
            _filter(e, g, no, nw, n, width)
            for i in range(n):
                for p in range(width):
                    e[i, p] = min(max(e[i, p] - step * (g[i, p] - b[i, p]), 0.0), 1.0)


def _load(src, decode, i, k):
    """Linear light of ``src[i, k]`` (decoded through ``decode`` when ``src`` holds integer codes)."""


def _store(out, encode, i, k, value):
    """``out[i, k] = value`` (linear), encoded through ``encode`` when ``out`` holds integer codes."""


@overload(_load, inline="always")
def _load_typed(src, decode, i, k):
    if isinstance(src.dtype, types.Integer):
        return lambda src, decode, i, k: decode[src[i, k]]
    return lambda src, decode, i, k: src[i, k]


@overload(_store, inline="always")
def _store_typed(out, encode, i, k, value):
    if isinstance(out.dtype, types.Integer):
        def store(out, encode, i, k, value):
            out[i, k] = encode[int(value * (encode.shape[0] - 1) + 0.5)]
        return store

    def store_linear(out, encode, i, k, value):
        out[i, k] = value
    return store_linear


@njit(parallel=True, cache=True, fastmath=True)
def _compensate(src, out, decode, encode, so, sw, no, nw, ro, rw, step, lift, iterations):
    """``out`` = the views to send for intended views ``src`` (N, P), chunk by chunk.

    uint8 sRGB in and out through the tables ``decode`` (256,) and ``encode`` (levels,); float
    linear light in and out (the tables unused): :func:`_load` and :func:`_store` are compiled per type.
    """
    n, total = src.shape
    chunks = (total + _CHUNK - 1) // _CHUNK
    for c in prange(chunks):
        start = c * _CHUNK
        width = min(_CHUNK, total - start)
        t = np.empty((n, _CHUNK), np.float32)
        e = np.empty((n, _CHUNK), np.float32)
        g = np.empty((n, _CHUNK), np.float32)
        b = np.empty((n, _CHUNK), np.float32)
        for i in range(n):
            for p in range(width):
                t[i, p] = lift + (1.0 - lift) * _load(src, decode, i, start + p)
        _solve_chunk(t, e, g, b, so, sw, no, nw, ro, rw, step, iterations, n, width)
        for i in range(n):
            for p in range(width):
                _store(out, encode, i, start + p, e[i, p])


def compensator_from_file(path, profile, regularisation: float = DEFAULT_REGULARISATION,
                          black_lift: float = 0.0, iterations: int = DEFAULT_ITERATIONS,
                          source: str | None = None, force: bool = False) -> Compensator:
    """A compensator from a ``crosstalk.json`` for the panel of ``profile`` (a
    :class:`~lenticalib.core.profile.PanelProfile`).

    The file must have ``profile``'s view count and, where it records the panel it was measured
    for (:func:`~lenticalib.core.crosstalk_document.measured_for`), be of that panel: a crosstalk
    file of another panel (or of another fit of it) is refused unless ``force``
    (:func:`~lenticalib.core.identity.check_same_panel`).  The compensator's ``origin`` holds the
    file and that check's record.  InputError naming ``source`` (default ``path``) otherwise.
    """
    source = str(path) if source is None else source
    data = read_crosstalk_document(path, views=profile.views, source=source)
    panel = check_same_panel(measured_for(data, source), profile, what="was measured for", source=source,
                             force=force, hint="measure the crosstalk of this panel with this profile")
    compensator = Compensator.from_matrix(mixing_matrix(data), regularisation, black_lift, iterations)
    return dataclasses.replace(compensator, origin={"crosstalk_file": source, **panel})


def compensation_study(compensator: Compensator, true_matrix: np.ndarray, linear_views: np.ndarray) -> dict:
    """How well pre-compensation works on a panel whose true mixing is ``true_matrix``.

    ARGUMENTS
    linear_views   float (N, P) intended views, linear light in [0, 1]

    RETURNED VALUE
    dict: per zone RMS of (seen - intended) without and with compensation (``rms_without``,
    ``rms_with``, lists of N; linear light), their means, and the residual crosstalk: the system
    crosstalk (light from all other views over the view's own light, a ratio) of the effective
    mixing, ``true M`` without and ``true M @ C`` with, where ``C`` is the unconstrained solution;
    ``leak_offsets`` (view offsets -N/2..N/2-1) with ``leak_without`` / ``leak_with``: the light
    from the view that far away over the own view's light, signed, mean over the views (the
    residual crosstalk is the sum of their magnitudes off 0); ``example_intended``,
    ``example_target`` (lifted by the black lift), ``example_seen_without``, ``example_seen_with``:
    one test pixel across the N zones (linear light).
    """
    n = compensator.views
    target = compensator.target(linear_views)
    sent = compensator.apply_linear(linear_views)
    seen_without = compensator.seen(linear_views, true_matrix)
    seen_with = compensator.seen(sent, true_matrix)
    rms_without = np.sqrt(np.mean((seen_without - linear_views) ** 2, axis=1))
    rms_with = np.sqrt(np.mean((seen_with - target) ** 2, axis=1))
    solve = np.zeros(n)
    for o, w in zip(compensator.solve_offsets, compensator.solve_weights):
        solve[o % n] += w
    c = solve[(np.arange(n)[None, :] - np.arange(n)[:, None]) % n]
    effective = np.asarray(true_matrix) @ c

    def residual(m):
        own = np.diag(m)
        return float(np.mean((np.abs(m).sum(axis=1) - np.abs(own)) / own))

    offsets = np.arange(-(n // 2), n - n // 2)
    rows = np.arange(n)

    def leak(m):
        return [float(np.mean(m[rows, (rows + k) % n] / np.diag(m))) for k in offsets]

    return {"rms_without": rms_without.tolist(), "rms_with": rms_with.tolist(),
            "leak_offsets": offsets.tolist(), "leak_without": leak(np.asarray(true_matrix)),
            "leak_with": leak(effective), "example_intended": np.asarray(linear_views)[:, 0].tolist(),
            "example_target": np.asarray(target)[:, 0].tolist(), "example_seen_without": seen_without[:, 0].tolist(),
            "example_seen_with": seen_with[:, 0].tolist(),
            "mean_rms_without": float(rms_without.mean()), "mean_rms_with": float(rms_with.mean()),
            "residual_crosstalk_without": residual(np.asarray(true_matrix)),
            "residual_crosstalk_with": residual(effective), "black_lift": compensator.black_lift,
            "regularisation": compensator.regularisation, "iterations": compensator.iterations}


def test_views(views: int, pixels: int = 20000, seed: int = 7) -> np.ndarray:
    """float32 (N, pixels) linear test views for a compensation study: a random mid-grey level per
    pixel and a smooth change across the views (three cycles, random phase), like a scene seen from
    N places; fixed seed."""
    rng = np.random.default_rng(seed)
    base = rng.uniform(0.1, 0.9, (1, pixels))
    phase = rng.uniform(0.0, 2.0 * np.pi, (1, pixels))
    index = np.arange(views)[:, None]
    return np.clip(base + 0.2 * np.sin(2.0 * np.pi * 3.0 * index / views + phase), 0.0, 1.0).astype(np.float32)


PREDICTION_BLACK_LIFT = 0.02  # the black lift of the compensation a crosstalk measurement predicts


def predict_compensation(matrix: np.ndarray, black_lift: float = PREDICTION_BLACK_LIFT) -> dict:
    """What pre-compensation with the measured ``matrix`` (N x N mixing) would do if the matrix is
    right: :func:`compensation_study` of its own compensator on :func:`test_views`."""
    return compensation_study(Compensator.from_matrix(matrix, black_lift=black_lift), matrix,
                              test_views(matrix.shape[0]))
