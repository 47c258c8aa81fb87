"""GPU sort of the ``gl`` renderer: per view, depth keys with their slots, ties in slot order.

:class:`GLSorter` sorts N independent runs of P (uint key, uint value) pairs, P a power of two,
in place in two shader storage buffers (KEYS and VALS of :mod:`.gl_shaders`), all runs in the same
dispatches (work group y = run).  Pairs are ordered by (key, value), so equal keys keep their
values' order: with values ascending in the Gaussian's index, that is a stable sort by key.
"""

from __future__ import annotations

from . import gl_shaders as sh


class GLSorter:
    """Bitonic sort of N runs of P pairs in compute shaders (OpenGL 4.3) of ``ctx``."""

    def __init__(self, ctx):
        self.ctx = ctx
        self._bitonic = ctx.compute_shader(sh.BITONIC)

    def sort(self, keys, vals, padded: int, runs: int) -> None:
        """Sort each of the ``runs`` runs of ``padded`` pairs in ``keys`` / ``vals`` (moderngl
        buffers of uint32) ascending by (key, value)."""
        keys.bind_to_storage_buffer(sh.KEYS)
        vals.bind_to_storage_buffer(sh.VALS)
        prog = self._bitonic
        prog["padded"].value = padded
        groups = -(-(padded // 2) // sh.GROUP)
        k = 2
        while k <= padded:
            j = k // 2
            while j >= 1:
                prog["k"].value = k
                prog["j"].value = j
                prog.run(groups, runs)
                self.ctx.memory_barrier()
                j //= 2
            k *= 2

    def release(self) -> None:
        self._bitonic.release()
