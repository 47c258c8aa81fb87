"""Progress display for long CLI steps: tqdm on stderr when it is installed and stderr is a terminal."""

from __future__ import annotations

import contextlib
import sys


class _Bar:
    def __init__(self, total: int, desc: str):
        self._bar = None
        if sys.stderr.isatty():
            try:
                from tqdm import tqdm
            except ImportError:  # tqdm is a declared dependency; degrade quietly if absent
                tqdm = None
            if tqdm is not None:
                self._bar = tqdm(total=total, desc=desc, unit="step", leave=False, file=sys.stderr)

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
def progress_bar(total: int, desc: str):
    bar = _Bar(total, desc)
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
