"""GPU sort of the ``gl`` renderer: per view, depth keys with their slots, a stable radix sort.

:class:`GLSorter` sorts R independent runs of n (uint32 key, uint32 value) pairs, in place in two
shader storage buffers (KEYS and VALS of :mod:`.gl_shaders`), every run in the same dispatches
(work group y = run), by key ascending; equal keys keep their order (stable), so with values in
Gaussian order, ties go by index as gsplat's sort does.

Least-significant-digit radix sort, 4 passes of 8 bits, each three compute dispatches:

histogram   each run is cut into chunks of CHUNK pairs; one invocation per chunk counts its
            digits, serially, into its own column of the run's table ``hist[digit][chunk]``
            (no atomics: every counter has one writer)
scan        one invocation per (run, digit) turns its row into exclusive offsets over the chunks
            and writes the digit's total; then one invocation per run turns its 256 totals into
            exclusive offsets: (digit, chunk) starts at total[digit] + hist[digit][chunk]
scatter     one invocation per chunk walks its pairs again in order and writes each to its
            digit's next place: stable, as every pair of a chunk follows the earlier chunks'

Serial chunks suit Mesa's llvmpipe (invocations are SIMD lanes of a few CPU threads) and keep the
sort stable without a per-work-group ranking; on a GPU the same dispatches run as they are.
Passes ping-pong through the sorter's scratch buffers, ending (after 4, or 2 for 16-bit keys) where
they started.
"""

from __future__ import annotations

from ...core.errors import InputError
from . import gl_shaders as sh

CHUNK = 1024  # pairs per invocation in the histogram and scatter dispatches
RADIX_BITS = 8
_KEYS_IN, _VALS_IN, _KEYS_OUT, _VALS_OUT, _HIST, _TOTALS = range(6, 12)

_HEAD = f"""
#version 430
layout(local_size_x = {sh.GROUP}) in;
layout(std430, binding = {_KEYS_IN}) readonly buffer KeysIn {{ uint keys_in[]; }};
layout(std430, binding = {_VALS_IN}) readonly buffer ValsIn {{ uint vals_in[]; }};
layout(std430, binding = {_KEYS_OUT}) writeonly buffer KeysOut {{ uint keys_out[]; }};
layout(std430, binding = {_VALS_OUT}) writeonly buffer ValsOut {{ uint vals_out[]; }};
layout(std430, binding = {_HIST}) buffer Hist {{ uint hist[]; }};
layout(std430, binding = {_TOTALS}) buffer Totals {{ uint totals[]; }};  // [run * DIGITS + digit]
uniform uint run_length;  // pairs per run ("length" is a built-in function's name)
uniform uint chunks;   // chunks per run
uniform uint shift;    // the digit's lowest bit
const uint CHUNK = {CHUNK}u;
const uint DIGITS = {1 << RADIX_BITS}u;
const uint MASK = {(1 << RADIX_BITS) - 1}u;
"""

# hist[(run * DIGITS + digit) * chunks + chunk]
HISTOGRAM = _HEAD + """
void main() {
    uint c = gl_GlobalInvocationID.x;
    if (c >= chunks) return;
    uint run = gl_WorkGroupID.y;
    uint table = run * DIGITS * chunks + c;
    for (uint d = 0u; d < DIGITS; ++d) hist[table + d * chunks] = 0u;
    uint base = run * run_length;
    uint end = min(c * CHUNK + CHUNK, run_length);
    for (uint i = c * CHUNK; i < end; ++i) {
        uint d = (keys_in[base + i] >> shift) & MASK;
        hist[table + d * chunks] += 1u;
    }
}
"""

SCAN_ROWS = _HEAD + """
uniform uint runs;
void main() {
    uint row = gl_GlobalInvocationID.x;  // run * DIGITS + digit
    if (row >= runs * DIGITS) return;
    uint total = 0u;
    for (uint k = row * chunks; k < row * chunks + chunks; ++k) {
        uint count = hist[k];
        hist[k] = total;
        total += count;
    }
    totals[row] = total;
}
"""

SCAN_DIGITS = _HEAD + """
uniform uint runs;
void main() {
    uint run = gl_GlobalInvocationID.x;
    if (run >= runs) return;
    uint total = 0u;
    for (uint k = run * DIGITS; k < run * DIGITS + DIGITS; ++k) {
        uint count = totals[k];
        totals[k] = total;
        total += count;
    }
}
"""

SCATTER = _HEAD + """
void main() {
    uint c = gl_GlobalInvocationID.x;
    if (c >= chunks) return;
    uint run = gl_WorkGroupID.y;
    uint table = run * DIGITS * chunks + c;
    uint base = run * run_length;
    uint end = min(c * CHUNK + CHUNK, run_length);
    for (uint i = c * CHUNK; i < end; ++i) {
        uint key = keys_in[base + i];
        uint digit = (key >> shift) & MASK;
        uint slot = table + digit * chunks;
        uint to = totals[run * DIGITS + digit] + hist[slot];
        hist[slot] += 1u;
        keys_out[base + to] = key;
        vals_out[base + to] = vals_in[base + i];
    }
}
"""


class GLSorter:
    """Stable radix sort of R runs of n (key, value) uint32 pairs in compute shaders (OpenGL 4.3)
    of ``ctx``; scratch buffers are kept between calls and grown when needed."""

    def __init__(self, ctx):
        self.ctx = ctx
        self._programs = [ctx.compute_shader(source) for source in (HISTOGRAM, SCAN_ROWS, SCAN_DIGITS, SCATTER)]
        self._scratch: dict = {}

    def _buffer(self, name: str, nbytes: int):
        buf = self._scratch.get(name)
        if buf is None or buf.size < nbytes:
            if buf is not None:
                buf.release()
            buf = self._scratch[name] = self.ctx.buffer(reserve=max(nbytes, 16))
        return buf

    def sort(self, keys, vals, length: int, runs: int, bits: int = 32) -> None:
        """Sort each of the ``runs`` runs of ``length`` pairs in ``keys`` / ``vals`` (moderngl
        buffers of uint32, run r at [r length, (r + 1) length)) stably by key.  ``bits`` 16: the
        keys are below 2**16, and only their two low digits are sorted (half the passes)."""
        if bits not in (16, 32):
            raise InputError(f"must be 16 or 32, got {bits!r}", source="bits")  # an even number of passes ends in place
        if length <= 1 or runs <= 0:
            return
        chunks = -(-length // CHUNK)
        pair = (keys, vals)
        other = (self._buffer("keys", 4 * length * runs), self._buffer("vals", 4 * length * runs))
        self._buffer("hist", 4 * runs * chunks << RADIX_BITS).bind_to_storage_buffer(_HIST)
        self._buffer("totals", 4 * runs << RADIX_BITS).bind_to_storage_buffer(_TOTALS)
        histogram, scan_rows, scan_digits, scatter = self._programs
        for prog in self._programs:
            for name, value in (("run_length", length), ("chunks", chunks), ("runs", runs)):
                if prog.get(name, None) is not None:  # a uniform a program does not use is not there
                    prog[name].value = value
        groups = -(-chunks // sh.GROUP)
        for shift in range(0, bits, RADIX_BITS):
            pair[0].bind_to_storage_buffer(_KEYS_IN)
            pair[1].bind_to_storage_buffer(_VALS_IN)
            other[0].bind_to_storage_buffer(_KEYS_OUT)
            other[1].bind_to_storage_buffer(_VALS_OUT)
            histogram["shift"].value = shift
            scatter["shift"].value = shift
            histogram.run(groups, runs)
            self.ctx.memory_barrier()
            scan_rows.run(-(-(runs << RADIX_BITS) // sh.GROUP))
            self.ctx.memory_barrier()
            scan_digits.run(-(-runs // sh.GROUP))
            self.ctx.memory_barrier()
            scatter.run(groups, runs)
            self.ctx.memory_barrier()
            pair, other = other, pair

    def release(self) -> None:
        for obj in self._programs + list(self._scratch.values()):
            obj.release()
        self._programs, self._scratch = [], {}
