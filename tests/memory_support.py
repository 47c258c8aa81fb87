"""Measuring what a call allocates, for the tests that refuse too-large inputs before allocating."""

from __future__ import annotations

import tracemalloc


def peak_traced(fn) -> int:
    """Bytes allocated (numpy and Python, as tracemalloc sees them) at the peak while ``fn`` runs."""
    tracemalloc.start()
    try:
        fn()
    finally:
        peak = tracemalloc.get_traced_memory()[1]
        tracemalloc.stop()
    return peak
