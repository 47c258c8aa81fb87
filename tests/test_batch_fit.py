"""``lenticalib batch fit``: a fleet of small simulated panels (640x360, 8 views, a 1200x900 camera)
and a folder of broken photos, fitted on a real Dask cluster (a ``dask scheduler`` and two
``dask worker`` processes on 127.0.0.1, one killed mid-fit) and on a local one (interrupted with
Ctrl-C, then resumed), checked against the truth and against ``lenticalib fit`` one by one."""

import contextlib
import json
import math
import os
import shutil
import signal
import subprocess
import sys
import time
import types
from pathlib import Path

import pytest

from lenticalib.calib.routing.compare import compare_profiles
from lenticalib.calib.fleet.identity import FitOptions, input_identity
from lenticalib.calib.fleet.run import check_workers_see
from lenticalib.core.errors import InputError
from lenticalib.core.figures import read_figure_record
from lenticalib.core.profile import load_profile

from .cli_support import ERROR_PREFIX, REPO, one_error_line, refused, run_main

SEEDS = (1, 2, 3)
W, H, VIEWS, CAMERA = 640, 360, 8, (1200, 900)
MAX_RMS, MAX_WORST = 0.05, 0.15  # views: the fit's accuracy against the truth (tests/test_calib.py)
DASK = Path(sys.executable).with_name("dask")
LIFETIME = "600s"  # a worker ends itself after this, whatever happens to the test
DEADLINE_S = 300.0  # for any one wait of these tests (a run on two busy cores takes about a minute)
VOLATILE = ("created", "command", "seconds")  # provenance keys that differ between two runs of one fit


@pytest.fixture(scope="module")
def fleet(tmp_path_factory):
    """Three simulated panels (seeds 1-3, ``panel-N/`` with its ``truth.json``) and ``broken/``: panel
    1's capture set with one photo that is not an image."""
    from lenticalib.calib.patterns.calibration_patterns import design_patterns
    from lenticalib.core.pattern_sets import write_patterns
    from lenticalib.sim.capture import simulate_capture_set
    from lenticalib.sim.scene import random_scene

    root = tmp_path_factory.mktemp("fleet")
    panels = []
    for seed in SEEDS:
        folder = root / f"panel-{seed}"
        write_patterns(folder, design_patterns(W, H, VIEWS))
        simulate_capture_set(folder, random_scene(seed, width=W, height=H, resolution=CAMERA, subsamples=1))
        panels.append(folder)
    broken = root / "broken"
    broken.mkdir()
    shutil.copy2(panels[0] / "patterns.json", broken)
    shutil.copytree(panels[0] / "captures", broken / "captures")
    (broken / "captures" / "x1-0.jpg").write_bytes(b"not a photo")
    return types.SimpleNamespace(root=root, panels=panels, broken=broken)


def _env() -> dict:
    """This environment, with the repository first on the path (the workers import this lenticalib)
    and one BLAS thread per process."""
    path = os.pathsep.join(p for p in (str(REPO), os.environ.get("PYTHONPATH")) if p)
    return {**os.environ, "PYTHONPATH": path, "OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1"}


def _wait(condition, what: str, timeout: float = DEADLINE_S):
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        value = condition()
        if value:
            return value
        time.sleep(0.3)
    pytest.fail(f"timed out waiting for {what}")


@contextlib.contextmanager
def dask_cluster(folder: Path):
    """A ``dask scheduler`` and workers ``w1``, ``w2`` (one thread each, no nanny) on 127.0.0.1, as
    processes ended by their PIDs on leaving (and by their own ``--lifetime``)."""
    procs: list[subprocess.Popen] = []
    log = open(folder / "dask.log", "w")  # noqa: SIM115 -- closed below, after the processes
    start = dict(stdout=log, stderr=subprocess.STDOUT, env=_env(), cwd=folder, start_new_session=True)
    try:
        scheduler_file = folder / "scheduler.json"
        procs.append(subprocess.Popen([DASK, "scheduler", "--host", "127.0.0.1", "--port", "0", "--no-dashboard",
                                       "--scheduler-file", scheduler_file, "--idle-timeout", LIFETIME], **start))
        _wait(lambda: scheduler_file.is_file() and scheduler_file.stat().st_size, "the scheduler", 120)
        address = json.loads(scheduler_file.read_text())["address"]
        workers = {}
        for name in ("w1", "w2"):
            workers[name] = subprocess.Popen([DASK, "worker", address, "--name", name, "--host", "127.0.0.1",
                                              "--nthreads", "1", "--no-nanny", "--no-dashboard", "--lifetime", LIFETIME,
                                              "--death-timeout", "60", "--local-directory", folder / name], **start)
            procs.append(workers[name])
        yield types.SimpleNamespace(address=address, workers=workers)
    finally:
        for proc in reversed(procs):
            if proc.poll() is None:
                os.kill(proc.pid, signal.SIGKILL)
            proc.wait(timeout=60)
        log.close()


def _interruptible():
    """In the child before it starts: Ctrl-C (SIGINT) delivered and handled as a shell would start
    it.  A child inherits an ignored or blocked SIGINT from the process that starts it; this
    session's full runs (pytest -n 2) saw the Ctrl-C test's run finish untouched (exit 3) where it
    passed alone, and the test process's own signal state is recorded in that test's failure."""
    signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def _batch(*argv) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-m", "lenticalib", "batch", "fit", *map(str, argv)], cwd=REPO,
                            env=_env(), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            preexec_fn=_interruptible)


def _finish(proc: subprocess.Popen) -> tuple[int, str, str]:
    out, err = proc.communicate(timeout=DEADLINE_S)
    return proc.returncode, out, err


def _summary(out: Path) -> dict:
    return json.loads((out / "summary.json").read_text())


def _rows(summary: dict) -> dict:
    return {row["name"]: row for row in summary["panels"]}


def _differences(a, b, where: str = "") -> list[str]:
    """Where the JSON values ``a`` and ``b`` differ, floats compared to 1e-6 relative: a fit in a Dask
    worker (one BLAS thread) and one in this process differ in the last bits of their sums (1e-12
    relative in the constants, 1e-9 in the jackknife's sigmas, themselves 1e-5 of the constants)."""
    if isinstance(a, float) and isinstance(b, (int, float)) or isinstance(b, float) and isinstance(a, (int, float)):
        return [] if math.isclose(a, b, rel_tol=1e-6, abs_tol=1e-12) else [f"{where}: {a!r} != {b!r}"]
    if isinstance(a, dict) and isinstance(b, dict):
        if set(a) != set(b):
            return [f"{where}: keys {sorted(set(a) ^ set(b))}"]
        return [d for k in a for d in _differences(a[k], b[k], f"{where}.{k}")]
    if isinstance(a, list) and isinstance(b, list):
        if len(a) != len(b):
            return [f"{where}: {len(a)} != {len(b)} items"]
        return [d for i, (x, y) in enumerate(zip(a, b)) for d in _differences(x, y, f"{where}[{i}]")]
    return [] if a == b else [f"{where}: {a!r} != {b!r}"]


def _stable(document: dict) -> dict:
    """A profile's or report summary's JSON without what differs between two runs of one fit (when,
    by which command, in how many seconds, the paths written)."""
    doc = json.loads(json.dumps(document))
    for holder in (doc, doc.get("profile") or {}):
        prov = holder.get("provenance") or {}
        for key in VOLATILE:
            prov.pop(key, None)
            (prov.get("quality") or {}).pop(key, None)
    for key in ("seconds", "output", "report"):
        doc.pop(key, None)
    (doc.get("quality") or {}).pop("seconds", None)
    return doc


def _check_against_truth(panel_dir: Path, capture: Path) -> None:
    diff = compare_profiles(load_profile(panel_dir / "profile.json"), load_profile(capture / "truth.json"))
    assert diff.rms <= MAX_RMS and diff.worst <= MAX_WORST and diff.order_match, (panel_dir, diff)


@pytest.mark.slow
def test_a_cluster_fits_the_fleet_despite_a_lost_worker_and_a_second_run_fits_nothing(fleet, tmp_path):
    from distributed import Client

    out = tmp_path / "out"
    argv = [*fleet.panels, fleet.broken, "-o", out]
    with dask_cluster(tmp_path) as cluster, Client(cluster.address, timeout=60) as client:
        client.wait_for_workers(2, timeout=120)
        address = {info["name"]: a for a, info in client.scheduler_info()["workers"].items()}

        def executing(dask_worker):
            return [str(ts.key) for ts in dask_worker.state.executing]

        batch = _batch(*argv, "--scheduler", cluster.address, "--workers", 2)
        try:
            # kill w1 while it fits a good panel (task keys are fit-panel-INDEX-...; index 3 is the broken one)
            keys = _wait(lambda: [k for k in client.run(executing, workers=[address["w1"]]).get(address["w1"], [])
                                  if k.split("-")[2] in "012"], "w1 to fit a panel")
            os.kill(cluster.workers["w1"].pid, signal.SIGKILL)
            killed = fleet.panels[int(keys[0].split("-")[2])].name
            code, stdout, stderr = _finish(batch)
        finally:
            if batch.poll() is None:
                batch.kill()
                batch.wait()
        assert code == 3, (stdout, stderr)  # not every panel is ok: the broken one failed
        summary = _summary(out)
        rows = _rows(summary)
        assert list(rows) == [p.name for p in fleet.panels] + ["broken"]
        assert summary["counts"] == {"ok": 3, "untrusted": 0, "failed": 1, "fitted": 3, "reused": 0}
        assert summary["cluster"] == {"scheduler": cluster.address, "workers": 2}
        for capture in fleet.panels:
            row = rows[capture.name]
            assert row["status"] == "ok" and row["error"] is None and row["fitted"], row
            _check_against_truth(out / capture.name, capture)
            assert row["identity"] == input_identity(capture, FitOptions())
        # the task w1 was running when it died ran again, to the end, on w2
        assert rows[killed]["worker"].endswith(f":{cluster.workers['w2'].pid}"), rows[killed]
        bad = rows["broken"]
        assert bad["status"] == "failed" and bad["profile"] is None
        assert bad["error"].startswith(f"{fleet.broken / 'captures' / 'x1-0.jpg'}: not a readable image"), bad
        assert f"broken: failed: {bad['error']}" in stdout.splitlines()
        assert sorted(p.name for p in (out / "broken").iterdir()) == ["batch.json"]
        csv_lines = (out / "summary.csv").read_text().splitlines()
        assert [line.split(",")[:2] for line in csv_lines[1:]] == [[n, r["status"]] for n, r in rows.items()]
        figure = read_figure_record(out / "fleet.png")
        assert figure["title"].startswith("Fleet of 4 panels") and "1 failed" in figure["title"]
        assert [a["ylabel"] for a in figure["axes"]][:3] == ["period (subpixels)", "slant (pixels per row)",
                                                             "offset (subpixels)"]
        for key, entry in summary["quantities"].items():
            assert figure["numbers"][key]["median"] == entry["median"]
            assert figure["numbers"][key]["outliers"] == sorted(entry["outliers"])

        # the same command again, on the worker left: every done panel is kept, untouched; the broken one is tried again
        before = {p.name: ((out / p.name).stat().st_ino, (out / p.name / "profile.json").stat().st_mtime_ns)
                  for p in fleet.panels}
        code, stdout, stderr = _finish(_batch(*argv, "--scheduler", cluster.address, "--workers", 1))
    assert code == 3, (stdout, stderr)
    again = _summary(out)
    assert again["counts"] == {"ok": 3, "untrusted": 0, "failed": 1, "fitted": 0, "reused": 3}
    assert all(not row["fitted"] for row in again["panels"])
    assert {p.name: ((out / p.name).stat().st_ino, (out / p.name / "profile.json").stat().st_mtime_ns)
            for p in fleet.panels} == before
    assert "0 fitted now, 3 already done" in stdout


@pytest.mark.slow
def test_a_local_run_gives_what_fit_gives_and_ctrl_c_keeps_the_finished_panels(fleet, tmp_path):
    captures = [*fleet.panels[:2], fleet.broken]
    out = tmp_path / "out"
    batch = _batch(*captures, "-o", out, "--workers", 1)
    def written():  # the good panels written so far (the cluster picks the order, not the command line)
        return [p for p in fleet.panels[:2] if (out / p.name / "batch.json").is_file()]

    try:  # Ctrl-C once the first good panel is written (waiting for one named panel raced: when it
        # came last the run had ended, exit 3, before the Ctrl-C)
        _wait(lambda: written() or batch.poll() is not None, "the first panel")
        batch.send_signal(signal.SIGINT)
        code, stdout, stderr = _finish(batch)
    finally:
        if batch.poll() is None:
            batch.kill()
            batch.wait()
    parent_state = (signal.getsignal(signal.SIGINT), signal.SIGINT in signal.pthread_sigmask(signal.SIG_BLOCK, []))
    assert code == 130 and stderr.strip().splitlines()[-1] == "lenticalib: interrupted", (code, stderr, parent_state)
    assert not (out / "summary.json").exists()
    kept = written()[0]
    first = out / kept.name
    assert json.loads((first / "batch.json").read_text())["row"]["status"] == "ok"
    _check_against_truth(first, kept)
    # no half-written panel: a panel folder is there whole (with its record) or not at all
    assert all((p / "batch.json").is_file() for p in out.iterdir() if not p.name.startswith("."))

    code, stdout, stderr = _finish(_batch(*captures, "-o", out, "--workers", 1))
    assert code == 3, (stdout, stderr)
    rows = _rows(_summary(out))
    assert not rows[kept.name]["fitted"]  # kept from the interrupted run
    assert [rows[p.name]["status"] for p in fleet.panels[:2]] == ["ok", "ok"]
    code, stdout, stderr = _finish(_batch(*fleet.panels[:2], "-o", out, "--workers", 1, "--json"))
    assert code == 0, stderr  # every panel ok (both kept, nothing fitted)
    assert json.loads(stdout) == _summary(out) and _summary(out)["counts"]["reused"] == 2

    for capture in captures:  # lenticalib fit, one by one, gives the same profiles, reports and failure
        mine = tmp_path / "fit" / capture.name
        mine.mkdir(parents=True)
        code, _, err = run_main("fit", capture, "-o", mine / "profile.json")
        panel = out / capture.name
        if capture == fleet.broken:
            assert code == 2 and one_error_line(err)[len(ERROR_PREFIX):] == rows["broken"]["error"]
            continue
        assert code == 0, err
        assert _differences(_stable(json.loads((panel / "profile.json").read_text())),
                            _stable(json.loads((mine / "profile.json").read_text()))) == []
        ours = json.loads((panel / "profile-report" / "summary.json").read_text())
        assert _differences(_stable(ours), _stable(json.loads((mine / "profile-report" / "summary.json").read_text()))) \
            == []
        assert ours["output"] == str(panel / "profile.json") and ours["report"] == str(panel / "profile-report")
        assert sorted(p.name for p in (panel / "profile-report").iterdir()) == \
            sorted(p.name for p in (mine / "profile-report").iterdir())


def _fake_set(folder: Path) -> Path:
    """A folder shaped like a capture set (``patterns.json``, ``captures/``): enough for what is
    checked before any fit."""
    (folder / "captures").mkdir(parents=True)
    (folder / "patterns.json").write_text("{}")
    for name in ("x0-0.jpg", "x0-1.jpg"):
        (folder / "captures" / name).write_bytes(name.encode() * 100)
    return folder


def test_inputs_and_outputs_are_refused_in_one_line_before_any_cluster_starts(tmp_path):
    panel = _fake_set(tmp_path / "panel-1")
    missing = tmp_path / "no-such-panel"
    refused("batch", "fit", panel, missing, "-o", tmp_path / "out", source=missing)
    twin = _fake_set(tmp_path / "elsewhere" / "panel-1")
    assert "same folder name" in refused("batch", "fit", panel, twin, "-o", tmp_path / "out", source=twin)
    refused("batch", "fit", panel, "-o", tmp_path / "no" / "out", source=tmp_path / "no")
    refused("batch", "fit", panel, "-o", panel / "results", source=panel / "results")
    foreign = tmp_path / "out" / "panel-1"
    foreign.mkdir(parents=True)
    (foreign / "notes.txt").write_text("mine")
    assert "notes.txt" in refused("batch", "fit", panel, "-o", tmp_path / "out", source=foreign)
    assert "--views" in refused("batch", "fit", panel, "-o", tmp_path / "out2", "--views", 1, source="--views")
    assert "--workers" in refused("batch", "fit", panel, "-o", tmp_path / "out2", "--workers", 0, source="--workers")
    line = refused("batch", "fit", panel, "-o", tmp_path / "out2", "--scheduler", "udp://10.0.0.1:8786",
                   source="--scheduler")
    assert "cannot reach the Dask scheduler" in line and "'dask scheduler'" in line
    assert (foreign / "notes.txt").read_text() == "mine" and not (tmp_path / "out2").exists()
    assert not (panel / "results").exists()


def test_a_worker_that_cannot_see_a_folder_is_refused_in_one_line(tmp_path):
    class Cluster:  # what Client.run returns: per worker, the folders it does not see
        def run(self, fn, paths):
            return {"tcp://10.0.0.2:4000": [], "tcp://10.0.0.3:4000": [p for p in paths if "panel-2" in p]}

    paths = [str(tmp_path / "panel-1"), str(tmp_path / "panel-2")]
    assert check_workers_see(types.SimpleNamespace(run=lambda fn, paths: {"tcp://a": [], "tcp://b": []}), paths) == 2
    with pytest.raises(InputError) as info:
        check_workers_see(Cluster(), paths)
    text = str(info.value)
    assert text.startswith(f"{paths[1]}: the Dask worker tcp://10.0.0.3:4000 cannot see this folder"), text
    assert "\n" not in text and "shared file server" in text


def test_the_identity_follows_the_photos_content_and_the_options_not_the_files_times(tmp_path):
    folder = _fake_set(tmp_path / "set")
    first = input_identity(folder, FitOptions())
    assert input_identity(shutil.copytree(folder, tmp_path / "copy"), FitOptions()) == first  # same inputs elsewhere
    photo = folder / "captures" / "x0-0.jpg"
    os.utime(photo, (1, 1))
    (folder / "notes.txt").write_text("not an input of the fit")
    assert input_identity(folder, FitOptions()) == first
    assert input_identity(folder, FitOptions(views=6)) != first
    assert input_identity(folder, FitOptions(force=True)) != first
    data = bytearray(photo.read_bytes())
    data[-3] ^= 1
    photo.write_bytes(bytes(data))
    assert input_identity(folder, FitOptions()) != first
    photo.rename(folder / "captures" / "x0-2.jpg")
    assert input_identity(folder, FitOptions()) not in (first, input_identity(folder, FitOptions(views=6)))


def test_the_fleet_summary_names_the_panels_outside_the_limits_and_the_figure_draws_them(tmp_path):
    from lenticalib.calib.routing.fit import MAX_PREDICTED_ERROR
    from lenticalib.calib.fleet.figure import write_fleet_figure
    from lenticalib.calib.fleet.summary import CSV_NAME, fleet_summary, write_summary

    def row(name, period, status="ok", worst=0.02, fitted=True, slant=0.2):
        return {"name": name, "status": status, "error": None, "fitted": fitted, "period": period,
                "period_sigma": 0.001, "slant": slant, "slant_sigma": 1e-5, "offset": 3.0, "offset_sigma": 0.02,
                "block_residual_rms_views": 0.01, "predicted_error_worst_views": worst,
                "predicted_error_centre_views": 0.01}

    rows = [row("SN1", 10.0), row("SN2", 10.001), row("SN3", 9.999, fitted=False), row("SN4", 10.0005),
            row("SN5", 10.5, slant=0.20002), row("SN6", 10.002, status="untrusted", worst=MAX_PREDICTED_ERROR + 0.05),
            {"name": "SN7", "status": "failed", "error": "no photos", "fitted": False}]
    summary = fleet_summary(rows, {"views": None, "force": False})
    assert summary["counts"] == {"ok": 5, "untrusted": 1, "failed": 1, "fitted": 5, "reused": 1}
    period = summary["quantities"]["period"]
    assert period["median"] == pytest.approx(10.00075) and period["low"] < 9.999 and 10.002 < period["high"] < 10.5
    assert period["outliers"] == ["SN5"]  # the spread is the panels' own sigma: the others are noise
    assert summary["quantities"]["slant"]["outliers"] == []  # SN5 is 2 of its own sigmas off: noise
    assert summary["quantities"]["predicted_error_worst_views"]["high"] == MAX_PREDICTED_ERROR
    assert [(o["name"], o["quantity"]) for o in summary["outliers"]] == [("SN5", "period"),
                                                                          ("SN6", "predicted_error_worst_views")]
    assert fleet_summary(rows[:2], {})["quantities"]["period"]["low"] is None  # two panels set no fleet limit
    write_summary(tmp_path, summary)
    assert (tmp_path / CSV_NAME).read_text().splitlines()[7].startswith("SN7,failed,no photos,False,,")
    record = read_figure_record(write_fleet_figure(tmp_path, summary))
    axes = {a["title"]: a for a in record["axes"]}
    assert "SN5" in axes["period"]["texts"] and "SN5" not in axes["slant"]["texts"]
    assert "SN6" in axes["predicted error at the worst corner (1-sigma)"]["texts"]
    assert "quality gate" in axes["predicted error at the worst corner (1-sigma)"]["legend"]
    assert "failed panel (no fit)" in axes["period"]["legend"]
    assert record["title"] == "Fleet of 7 panels: each constant across the panels (5 ok, 1 untrusted, 1 failed)"
