"""Shared helpers for the device-layer tests: profiles, emulator processes, URLs."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from contextlib import contextmanager
from pathlib import Path

from lenticalib.core.profile import PanelProfile

REPO = Path(__file__).resolve().parents[1]
VIAS = ("serial", "hid", "usb")


def profile_a() -> PanelProfile:
    return PanelProfile(views=32, slant=0.1835, period=19.47, offset=7.3, reference_view=16.0,
                        width=3840, height=2160, subpixel_order="RGB")


def profile_b() -> PanelProfile:
    """Another calibration of the same panel as :func:`profile_a` (the emulator's default panel,
    3840x2160 RGB, 32 views: a controller refuses profiles for another panel)."""
    return PanelProfile(views=32, slant=-0.2871234567, period=17.123456789, offset=3.25, reference_view=16.0,
                        width=3840, height=2160, subpixel_order="RGB",
                        uncertainty={"slant": 1e-5, "period": 2e-4, "offset": 0.01, "reference_view": 0.0})


def same_constants(a: PanelProfile, b: PanelProfile) -> bool:
    return a.routing_key() == b.routing_key()


@contextmanager
def emulator_process(*args: str, env: dict | None = None):
    """Run ``lenticalib emulate ARGS``; yield (process, url) once it printed its URL."""
    full_env = {**os.environ, **(env or {})}
    proc = subprocess.Popen([sys.executable, "-m", "lenticalib.cli", "emulate", *args], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, env=full_env, cwd=REPO)
    try:
        url = proc.stdout.readline().strip()
        if not url:
            raise RuntimeError(f"emulator did not start: {proc.stderr.read()}")
        yield proc, url
    finally:
        if proc.poll() is None:
            proc.terminate()
        try:
            proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
        proc.stdout.close()
        proc.stderr.close()


def wait_exit(proc, timeout: float = 10.0) -> int:
    deadline = time.monotonic() + timeout
    while proc.poll() is None and time.monotonic() < deadline:
        time.sleep(0.01)
    return proc.poll()


@contextmanager
def no_hang(seconds: int):
    """Fail the test (AssertionError) instead of hanging when the block runs past ``seconds``."""
    def expire(signum, frame):
        raise AssertionError(f"still running after {seconds} s: hung")

    old = signal.signal(signal.SIGALRM, expire)
    signal.alarm(seconds)
    try:
        yield
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, old)
