"""One deadline over a whole conversation with a device, shared by every request in it.

A device that answers each request just before its timeout (or only the last resend) would
otherwise make a read of many pages take pages x attempts x timeout.  A reader runs each
operation under :meth:`Deadline.running` (seconds from its start, monotonic clock) and caps every
wait with :meth:`Deadline.wait_end`; :meth:`Deadline.passed` tells when to stop with the
reader's own one-line :class:`~lenticalib.core.errors.DeviceTimeoutError`.  Used by the panel
controller client (:mod:`lenticalib.device.client`) and the Looking Glass HID reader
(:mod:`lenticalib.device.looking_glass.hid`).
"""

from __future__ import annotations

import contextlib
import time
from collections.abc import Iterator


class Deadline:
    """The end (``time.monotonic()`` seconds) of the conversation in progress, or None between
    conversations (then nothing is capped and nothing has passed)."""

    def __init__(self) -> None:
        self.ends: float | None = None

    @contextlib.contextmanager
    def running(self, seconds: float) -> Iterator[None]:
        """Run one conversation that must end within ``seconds`` of now; a conversation started
        inside another runs under the outer one's deadline."""
        if self.ends is not None:
            yield
            return
        self.ends = time.monotonic() + seconds
        try:
            yield
        finally:
            self.ends = None

    def wait_end(self, timeout: float) -> float:
        """When a wait of ``timeout`` seconds starting now must end: now + ``timeout``, or the
        conversation's end if that comes first."""
        end = time.monotonic() + timeout
        return end if self.ends is None else min(end, self.ends)

    def passed(self) -> bool:
        """Whether the conversation in progress has run past its deadline."""
        return self.ends is not None and time.monotonic() >= self.ends
