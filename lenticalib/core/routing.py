"""Subpixel routing: which view each panel subpixel shows, by the LentiAvatar routing rule (docs/routing.md).

The LentiAvatar routing rule (Fang, Teng and Liu; docs/routing.md): for view ``i`` of ``N``, ``s_i = s_ref - (Delta/N)(i - i_ref)``;
for row ``y`` and integer ``m``, ``b_i(y, m) = 3 C_r y + s_i + m Delta``; view ``i`` lights
subpixel ``x_s`` when ``x_s = floor(b)`` and ``frac(b) < Delta/N``.

Closed form.  Over all ``(i, m)`` the points ``b`` form one lattice of spacing ``Delta/N``:
``b_j = 3 C_r y + s_ref + (i_ref - j) Delta/N`` with ``i = j mod N``.  Writing the continuous view
coordinate of ``docs/optics.md``

    w(x_s, y) = i_ref + (3 C_r y + s_ref - x_s) * N / Delta,

view ``j mod N`` lights ``x_s`` iff ``j <= w < j + min(1, N/Delta)``.  Hence, in exact arithmetic,
subpixel ``(x_s, y)`` shows view ``floor(w) mod N`` when ``frac(w) < N/Delta`` and no view
otherwise; for ``Delta <= N`` every subpixel shows exactly one view.

Canonical arithmetic.  lenticalib evaluates that closed form in 64-bit fixed point: the phase
``z = w / N`` (cycles of N views) is held as ``Z = frac(z) * 2**64`` (uint64).  Per row the start
phase ``Z0[y]`` is rounded *up* from the exact rational value and the per-subpixel step
``K = 2**64 / Delta`` is rounded *down*, so ``Z = Z0[y] - x_s * K (mod 2**64)`` never falls below
the exact phase and exceeds it by less than ``(1 + x_s) * 2**-64`` cycles.  Exact ties (``w`` an
integer, ``frac(w) == N/Delta``) are therefore resolved exactly as exact arithmetic resolves them;
only a value within ~1e-14 view *below* a boundary can come out on the other side.

Every encoder routes by this arithmetic: the fast kernels evaluate it on the fly (same constants,
same uint64 operations), the reference encoder and the sampling tables take :func:`view_map`.  So
all of them choose the same view for every subpixel, ties included.  :func:`rule_views` (the
LentiAvatar routing rule literally, in float64) is kept only as a cross-check; on exact ties it can disagree
or light two views.
"""

from __future__ import annotations

import dataclasses
import functools
from fractions import Fraction

import numpy as np

from .profile import PanelProfile

_TWO64 = 1 << 64
_MASK32 = np.uint64(0xFFFFFFFF)
_ROWS_PER_CHUNK = 256


@dataclasses.dataclass(frozen=True)
class RoutingPlan:
    """The canonical fixed-point routing of one profile (module docstring), per-profile constants.

    The phase of slot ``s`` of pixel ``x`` in row ``y`` (``x_s = 3 x + s``), in units of
    ``2**-64`` cycles of N views, is

        Z = z0[y] - x_s * k - shift[y % shift.shape[0], 3 (x % (shift.shape[1] // 3)) + s]   (mod 2**64)

    and the slot shows view ``floor(Z * N / 2**64)``, or none when ``dark`` is not None and
    ``(Z * N) mod 2**64 >= dark``.

    ``z0`` uint64 ``(height,)``, rounded up from the exact phase; ``k`` the step per subpixel,
    ``floor(2**64 / period)``; ``shift`` uint64 ``(rows, 3 * columns)``: the slot shifts of a
    :class:`~lenticalib.core.layout.SubpixelLayout` as ``floor(e * 2**64 / period)`` (all zero,
    shape ``(1, 3)``, on a stripe panel); ``dark`` ``None`` when ``period <= N``.  For a profile
    with ``views_reversed`` the plan holds the complement (``~z0``, ``-k``, ``-shift``), which gives
    view ``N - 1 - v`` for the rule's ``v`` (off exact ties), so kernels need not know about it.
    """

    z0: np.ndarray
    k: int
    shift: np.ndarray
    dark: int | None

    @property
    def is_stripe(self) -> bool:
        """True when every slot shift is zero (``shift`` has shape ``(1, 3)`` and holds zeros)."""
        return self.shift.shape == (1, 3) and not self.shift.any()


@functools.lru_cache(maxsize=16)
def _routing_plan(key: tuple) -> RoutingPlan:
    n, slant, period, offset, i_ref, width, height, _order, layout, reversed_views = key[:10]
    p = Fraction(period)
    base = Fraction(i_ref) / n + Fraction(offset) / p
    step_y = 3 * Fraction(slant) / p
    z0 = np.empty(height, dtype=np.uint64)
    for y in range(height):
        z = base + step_y * y
        scaled = (z - (z.numerator // z.denominator)) * _TWO64  # frac(z) in [0, 1), times 2**64
        z0[y] = -((-scaled.numerator) // scaled.denominator) % _TWO64  # ceil, wrapped
    k = (_TWO64 * p.denominator // p.numerator) % _TWO64  # floor(2**64 / period), wrapped
    if layout is None:
        shift = np.zeros((1, 3), dtype=np.uint64)
    else:
        per_cell = [[(e * _TWO64 / p).__floor__() % _TWO64 for e in cell] for cell in layout.slot_shifts(slant)]
        shift = np.array(layout.per_slot(per_cell), dtype=np.uint64)
    # lit iff frac(w) < N / period; frac(w) * 2**64 is (Z * N) mod 2**64.
    ratio = Fraction(n) / p
    dark_threshold = None if ratio >= 1 else -((-ratio.numerator * _TWO64) // ratio.denominator)
    if reversed_views:
        z0 = ~z0
        k = (-k) % _TWO64
        shift = (np.uint64(0) - shift).astype(np.uint64)
    z0.setflags(write=False)
    shift.setflags(write=False)
    return RoutingPlan(z0=z0, k=k, shift=shift, dark=dark_threshold)


def routing_plan(profile: PanelProfile) -> RoutingPlan:
    """The fixed-point constants every encoder routes by (:class:`RoutingPlan`); cached per profile."""
    return _routing_plan(profile.routing_key())


def view_map(profile: PanelProfile, rows: slice | None = None) -> np.ndarray:
    """View shown by every subpixel slot, in the canonical arithmetic.

    RETURNED VALUE
    int16 array of shape ``(rows, 3 * width)``, indexed ``[y, 3 x + slot]`` with ``slot = rho(c)``
    (panel subpixel order on a stripe panel; the channel R, G, B with a subpixel layout), not
    channel order; ``-1`` where no view lights the slot (possible only when ``period > N``).
    """
    plan = routing_plan(profile)
    row_index = np.arange(profile.height)
    if rows is not None:
        row_index = row_index[rows]
    z0 = plan.z0[row_index]
    views = np.empty((z0.shape[0], profile.subpixels_per_row), dtype=np.int16)
    xs_k = np.arange(profile.subpixels_per_row, dtype=np.uint64) * np.uint64(plan.k)  # wraps mod 2**64
    n = np.uint64(profile.views)
    shift_rows = plan.shift.shape[0]
    reps = -(-profile.subpixels_per_row // plan.shift.shape[1])
    shift_full = np.tile(plan.shift, (1, reps))[:, :profile.subpixels_per_row]  # (rows of pattern, 3W)
    with np.errstate(over="ignore"):
        for start in range(0, z0.shape[0], _ROWS_PER_CHUNK):  # bounded uint64 temporaries
            stop = start + _ROWS_PER_CHUNK
            z = z0[start:stop, None] - xs_k[None, :]
            if not plan.is_stripe:
                z = z - shift_full[row_index[start:stop] % shift_rows]
            hi = (z >> np.uint64(32)) * n
            lo = (z & _MASK32) * n
            chunk = views[start:stop]
            chunk[...] = (hi + (lo >> np.uint64(32))) >> np.uint64(32)
            if plan.dark is not None:
                chunk[(z * n) >= np.uint64(plan.dark)] = -1
    return views


def slot_shift_views(profile: PanelProfile) -> np.ndarray:
    """Slot shifts of the profile in subpixels, float64 ``(rows, 3 * columns)`` (zeros on a stripe panel).

    Indexed like :attr:`RoutingPlan.shift`: ``[y % rows, 3 (x % columns) + slot]``."""
    layout = profile.subpixel_layout
    return np.zeros((1, 3)) if layout is None else layout.slot_shift_table(profile.slant)


def slot_shift_rows(profile: PanelProfile, rows) -> np.ndarray:
    """Slot shift ``e`` (subpixels) of every slot of ``rows`` (integer row indices), float64
    ``(len(rows), 3 * width)``: :func:`slot_shift_views` repeated along the row."""
    shift = slot_shift_views(profile)
    reps = -(-profile.subpixels_per_row // shift.shape[1])
    full = np.tile(shift, (1, reps))[:, :profile.subpixels_per_row]
    return full[np.asarray(rows, dtype=np.int64) % shift.shape[0]]


def view_coordinate(profile: PanelProfile, rows: np.ndarray | None = None) -> np.ndarray:
    """Continuous view coordinate ``w`` of docs/optics.md per slot, float64, shape ``(rows, 3 * width)``.

    ``w`` is evaluated at the slot's left edge ``x_s + e`` (``e`` the slot shift of a subpixel
    layout, 0 on a stripe panel), as the LentiAvatar routing rule does.  Not reduced modulo N.
    With ``views_reversed`` it is ``N - w`` (the view shown is ``floor`` of it, modulo N).
    """
    y = np.arange(profile.height, dtype=np.float64) if rows is None else np.asarray(rows, np.float64)
    xs = np.arange(profile.subpixels_per_row, dtype=np.float64)
    scale = profile.views / profile.period
    w = profile.reference_view + (3.0 * profile.slant * y[:, None] + profile.offset - xs[None, :]) * scale
    if not profile.is_stripe:
        w = w - slot_shift_rows(profile, y.astype(np.int64)) * scale
    if profile.views_reversed:
        w = profile.views - w
    return w


def rule_views(profile: PanelProfile, max_views: int = 3) -> tuple[np.ndarray, np.ndarray]:
    """Brute-force evaluation of the LentiAvatar routing rule in float64, over every view and every m.

    For each view ``i`` and each row, every ``m`` whose ``b_i(y, m)`` can land on the panel is
    evaluated literally (``floor``, ``frac``, ``< period / N``), and the lit views are recorded.

    RETURNED VALUE
    ``(count, views)``: ``count`` uint8 ``(height, 3 * width)``, how many views light each
    subpixel; ``views`` uint8 ``(max_views, height, 3 * width)``, the lit views in increasing
    order, 255 in unused slots (views beyond ``max_views`` are counted but not stored).

    The rule knows stripes only: ValueError for a profile with a subpixel layout or reversed views.
    """
    if not profile.is_stripe or profile.views_reversed:
        raise ValueError("rule_views evaluates the LentiAvatar rule of a stripe panel; "
                         "use view_map for subpixel layouts and reversed views")
    n, h, nsub = profile.views, profile.height, profile.subpixels_per_row
    delta = profile.period
    count = np.zeros((h, nsub), dtype=np.uint8)
    views = np.full((max_views, h, nsub), 255, dtype=np.uint8)
    width_frac = delta / n
    ys = np.arange(h, dtype=np.float64)
    for i in range(n):
        s_i = profile.offset - width_frac * (i - profile.reference_view)
        start = 3.0 * profile.slant * ys + s_i  # b_i(y, 0)
        m_lo = int(np.floor((-1.0 - start.max()) / delta)) - 1
        m_hi = int(np.ceil((nsub + 1.0 - start.min()) / delta)) + 1
        m = np.arange(m_lo, m_hi + 1, dtype=np.float64)
        b = start[:, None] + m[None, :] * delta
        x = np.floor(b)
        lit = ((b - x) < width_frac) & (x >= 0) & (x < nsub)
        yy, mm = np.nonzero(lit)
        xx = x[yy, mm].astype(np.int64)
        slot = count[yy, xx]
        keep = slot < max_views
        views[slot[keep], yy[keep], xx[keep]] = i
        np.add.at(count, (yy, xx), 1)
    return count, views


def tie_mask(profile: PanelProfile, tolerance: float = 1e-9) -> np.ndarray:
    """Subpixels whose ``w`` lies within ``tolerance`` views of a decision boundary.

    Boundaries are integer ``w`` and, when ``period > N``, ``frac(w) = N / period``.  On these
    exact ties float64 evaluations of the rule may legitimately disagree.  Bool ``(height, 3W)``.
    """
    w = view_coordinate(profile)
    frac = w - np.floor(w)
    ties = (frac < tolerance) | (frac > 1.0 - tolerance)
    ratio = profile.views / profile.period
    if ratio < 1.0:
        ties |= np.abs(frac - ratio) < tolerance
    return ties
