"""Shared fixtures: the hypothesis profiles and the ``lenticalib`` runners (see cli_support.py)."""

import os

import pytest
from hypothesis import HealthCheck, settings

from .cli_support import run_main, run_process

settings.register_profile("lenticalib", derandomize=True, deadline=None, print_blob=True,
                          suppress_health_check=[HealthCheck.too_slow])
settings.register_profile("ci", parent=settings.get_profile("lenticalib"), max_examples=40)
settings.load_profile("ci" if os.environ.get("CI") else "lenticalib")


@pytest.fixture
def cli():
    """``cli(*argv) -> (code, out, err)``: ``lenticalib ARGV`` in this process (:func:`run_main`)."""
    return run_main


@pytest.fixture
def cli_process():
    """``cli_process(*argv, env=None, timeout=600) -> CompletedProcess``: ``python -m lenticalib ARGV``
    as a real process in the repository root (:func:`run_process`)."""
    return run_process
