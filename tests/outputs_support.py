"""Test helper: read-only folders that stay read-only for root too.

Root ignores permission bits, so under root (CI containers) a ``chmod 555`` folder is writable and
``os.access`` says so.  The ``read_only`` fixture makes a folder ``0o555`` and, when the tests run
as root, has ``os.access`` deny writing there as it would for any other user (nothing else is
changed: the command under test runs for real).  The mode is restored at teardown.
"""

from __future__ import annotations

import os
from pathlib import Path

import pytest


@pytest.fixture
def read_only(monkeypatch):
    """``read_only(path)`` creates ``path`` if needed, makes it read-only and returns it."""
    frozen: list[Path] = []
    real_access = os.access

    def access(target, mode, *args, **kwargs):
        if mode & os.W_OK and any(Path(target).resolve() == f for f in frozen):
            return False
        return real_access(target, mode, *args, **kwargs)

    if os.geteuid() == 0:
        monkeypatch.setattr(os, "access", access)

    def make(path: Path) -> Path:
        path.mkdir(parents=True, exist_ok=True)
        path.chmod(0o555)
        frozen.append(path.resolve())
        return path

    yield make
    for path in frozen:
        path.chmod(0o755)
