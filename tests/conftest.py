"""Shared fixtures: the hypothesis profiles, the ``lenticalib`` runners (see cli_support.py), one
virtual display (see display_support.py) and the simulated capture sets.

Tests of minutes carry ``@pytest.mark.slow``: ``pytest -m "not slow"`` is the inner loop."""

import os
from pathlib import Path

# Under pytest-xdist every core already runs a worker: one BLAS thread in each (and in the
# processes it starts), set before numpy is imported.  BLAS threads that spin while they wait
# oversubscribe the cores: two fits side by side took 26 s each with them, 23 s without.  numba's
# and OpenCV's pools keep their threads (the simulator's kernels use a core another worker leaves
# idle).  A single process (-n 0) keeps them all.
if int(os.environ.get("PYTEST_XDIST_WORKER_COUNT", "1")) > 1:
    for _name in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ.setdefault(_name, "1")

import pytest
from hypothesis import HealthCheck, settings

from .cli_support import run_main, run_process
from .display_support import SCREEN, VirtualDisplay

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


@pytest.fixture(scope="session")
def xvfb():
    """One Xvfb server of ``SCREEN`` (640x360) for the session: the presenter, ``show`` and
    ``capture`` tests.  Processes get it through ``env=xvfb.variables()``."""
    display = VirtualDisplay(*SCREEN)
    yield display
    display.close()


@pytest.fixture
def on_xvfb(xvfb, monkeypatch):
    """This process shows on the ``xvfb`` display for the test (DISPLAY set, WAYLAND_DISPLAY unset)."""
    for name, value in xvfb.variables().items():
        if value is None:
            monkeypatch.delenv(name, raising=False)
        else:
            monkeypatch.setenv(name, value)
    return xvfb


@pytest.fixture(scope="session")
def capture_set(tmp_path_factory):
    """``capture_set(scene, patterns=None, *, views=32, raw=False, keep_simulation=True) -> Path``:
    a simulated capture set, made once per session for the same arguments.

    ``patterns`` (a calibration or crosstalk pattern set; by default the calibration patterns of
    the scene's panel with ``views`` views) is written and photographed on the virtual panel of
    ``scene`` (``lenticalib.sim.capture.simulate_capture_set``; ``raw``: 16-bit linear PNGs).
    Without ``keep_simulation`` the set is what a user has: no ``simulation.json`` (``truth.json``
    stays for the test).  The folder is shared: copy it before changing it.
    """
    import json

    from lenticalib.calib.patterns.calibration_patterns import design_patterns
    from lenticalib.core.pattern_sets import write_patterns
    from lenticalib.sim.capture import simulate_capture_set

    made: dict[str, Path] = {}

    def make(scene, patterns=None, *, views: int = 32, raw: bool = False, keep_simulation: bool = True) -> Path:
        if patterns is None:
            patterns = design_patterns(scene.optics.width, scene.optics.height, views)
        key = json.dumps([scene.to_dict(), patterns.set_id, raw, keep_simulation], sort_keys=True)
        if key not in made:
            folder = tmp_path_factory.mktemp("capture-set") / "set"
            write_patterns(folder, patterns)
            simulate_capture_set(folder, scene, raw=raw)
            if not keep_simulation:
                (folder / "simulation.json").unlink()
            made[key] = folder
        return made[key]

    return make


SLOW_FIXTURES = {"demo_fit", "two_distances"}
"""Fixtures that fit a whole capture set (15-20 s each on two cores): every test using one is
``slow``, so ``-m "not slow"`` stays an inner loop of about two minutes."""


def pytest_collection_modifyitems(config, items):
    for item in items:
        if SLOW_FIXTURES & set(getattr(item, "fixturenames", ())):
            item.add_marker(pytest.mark.slow)
