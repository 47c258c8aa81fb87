"""Transport faults the emulated controller can inject (``lenticalib emulate --help``).

Every fault is drawn from one seeded random stream, so a run with the same options and the
same host traffic misbehaves identically.  Rates are probabilities per frame.
"""

from __future__ import annotations

import dataclasses
import random

from ...core.errors import InputError


@dataclasses.dataclass
class FaultPlan:
    """Which faults to inject and how often.

    drop_rate         a request is lost before the firmware sees it, or a reply is lost
                      (each drawn separately)
    corrupt_rate      one byte of a request or reply is flipped (the CRC catches it)
    duplicate_rate    a reply is sent twice
    delay_rate        a reply is held back by ``delay_s`` seconds
    stale_rate        an earlier reply is sent again before the real one: the last reply to
                      the same command (an older SEQ, other contents) when there was one,
                      else the previous reply
    disconnect_after  the link goes away after this many request frames (None: never)
    power_cut_after   the power fails after this many flash operations (None: never)
    torn              the power cut interrupts the operation halfway instead of after it
    babble            the controller talks unasked: whenever no reply is ready, noise is (a
                      device streaming reports of its own, so the host's input never drains)
    short_rate        (Looking Glass unit) an answer is cut short
    wrong_page_rate   (Looking Glass unit) an answer echoes and carries another page than asked

    For the emulated Looking Glass unit (:mod:`.looking_glass`) ``drop_rate`` is the chance that
    a page request gets no answer, ``delay_rate`` the chance that its answer comes ``delay_s`` late.
    """

    drop_rate: float = 0.0
    corrupt_rate: float = 0.0
    duplicate_rate: float = 0.0
    delay_rate: float = 0.0
    delay_s: float = 0.2
    stale_rate: float = 0.0
    disconnect_after: int | None = None
    power_cut_after: int | None = None
    torn: bool = False
    babble: bool = False
    short_rate: float = 0.0
    wrong_page_rate: float = 0.0
    seed: int = 0

    def __post_init__(self):
        for name in ("drop_rate", "corrupt_rate", "duplicate_rate", "delay_rate", "stale_rate", "short_rate",
                     "wrong_page_rate"):
            value = getattr(self, name)
            if not 0.0 <= value <= 1.0:
                raise InputError(f"must be a probability between 0 and 1, got {value}", source=name)
        if not 0.0 <= self.delay_s <= 60.0:
            raise InputError(f"must be 0..60 seconds, got {self.delay_s}", source="delay_s")
        for name in ("disconnect_after", "power_cut_after"):
            value = getattr(self, name)
            if value is not None and value < 1:
                raise InputError(f"must be at least 1, got {value}", source=name)
        self.random = random.Random(self.seed)

    def hit(self, rate: float) -> bool:
        return rate > 0.0 and self.random.random() < rate

    def corrupt(self, data: bytes) -> bytes:
        out = bytearray(data)
        index = self.random.randrange(len(out))
        out[index] ^= 1 << self.random.randrange(8)
        return bytes(out)

    def noise(self, size: int) -> bytes:
        """``size`` bytes the controller sends unasked (``babble``)."""
        return self.random.randbytes(size)
