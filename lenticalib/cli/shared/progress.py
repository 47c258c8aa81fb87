"""Progress display for long CLI steps: tqdm on stderr when it is installed and stderr is a terminal.

:func:`progress_bar` (one bar), :func:`staged_bars` (one bar per stage of a library call) and
:func:`compile_notice` (one line when numba compiles a kernel: a first run's silent half minute);
all of them show nothing when stderr is not a terminal.
"""

from __future__ import annotations

import contextlib
import sys


class _Bar:
    def __init__(self, total: int, desc: str, unit: str = "step"):
        self._bar = None
        if sys.stderr.isatty():
            try:
                from tqdm import tqdm
            except ImportError:  # tqdm is a declared dependency; degrade quietly if absent
                tqdm = None
            if tqdm is not None:
                self._bar = tqdm(total=total, desc=desc, unit=unit, leave=False, file=sys.stderr)

    def wrap(self, items):
        for item in items:
            yield item
            self.update()

    def update(self, message: str | None = None) -> None:
        if self._bar is not None:
            if message:
                self._bar.set_postfix_str(message, refresh=False)
            self._bar.update(1)

    def set_total(self, total: int) -> None:
        if self._bar is not None and self._bar.total != total:
            self._bar.total = total
            self._bar.refresh()

    def close(self) -> None:
        if self._bar is not None:
            self._bar.close()


@contextlib.contextmanager
def progress_bar(total: int, desc: str, unit: str = "step"):
    bar = _Bar(total, desc, unit)
    try:
        yield bar
    finally:
        bar.close()


@contextlib.contextmanager
def staged_bars():
    """A ``stage(name, steps)`` callback for a library function with several stages: each call closes
    the bar of the stage before and opens one for ``steps`` steps, returning its ``update``."""
    bars: list[_Bar] = []

    def stage(name: str, steps: int):
        if bars:
            bars.pop().close()
        bars.append(_Bar(steps, name))
        return bars[-1].update

    try:
        yield stage
    finally:
        for bar in bars:
            bar.close()


def _say(message: str) -> None:
    """One line on stderr, above any progress bar."""
    try:
        from tqdm import tqdm
    except ImportError:
        print(message, file=sys.stderr, flush=True)
    else:
        tqdm.write(message, file=sys.stderr)


@contextlib.contextmanager
def compile_notice(message: str):
    """Print ``message`` once on stderr (a terminal only) when numba starts compiling a kernel
    inside the block; kernels loaded from numba's disk cache (``cache=True``) compile nothing,
    so a later run says nothing."""
    try:
        from numba.core import event
    except ImportError:  # numba is a declared dependency; nothing to announce without it
        event = None
    if event is None or not sys.stderr.isatty():
        yield
        return
    said: list[bool] = []

    class Notice(event.Listener):
        def on_start(self, ev) -> None:
            if not said:
                said.append(True)
                _say(message)

        def on_end(self, ev) -> None:
            pass

    with event.install_listener("numba:compile", Notice()):
        yield
