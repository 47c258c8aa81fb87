"""``fit_fleet``: the whole of ``lenticalib batch fit`` as one library call, on a Dask cluster.

One task per capture folder (:func:`.task.fit_panel`), scheduled by ``dask.distributed``: with no
``scheduler``, on a local cluster of ``workers`` processes (default: one per core, one thread
each); with ``scheduler`` (``tcp://HOST:PORT``), on the workers of a running cluster, which must
see the capture folders and the output folder at the same paths as this process (a shared file
server), checked on every worker before any task starts.  Scheduling, retries (``retries`` for a
task that raised) and lost workers (their tasks run again on another worker, up to the
scheduler's ``distributed.scheduler.allowed-failures`` times) are Dask's; lenticalib supplies the
task, the inputs' identity (:mod:`.identity`) and the summary (:mod:`.summary`, :mod:`.figure`).

Everything that can be checked is checked before the cluster starts (the capture folders, one
output folder name per panel, the output folder and each panel folder in it,
:mod:`lenticalib.core.files.outputs`); an error names the argument (``source="scheduler"`` ...) or the
path.  A panel whose fit fails is a row and does not stop the others.  Each panel folder is
written whole (:func:`lenticalib.core.files.outputs.staged_folder`), so Ctrl-C (or a killed worker)
leaves every finished panel intact; the next run with the same inputs fits nothing that is done
(:func:`.identity.is_done`) and picks up the rest.  ``OUT/summary.json``, ``OUT/summary.csv`` and
``OUT/fleet.png`` are written when every panel has its row.
"""

from __future__ import annotations

import contextlib
import dataclasses
import os
import uuid
from pathlib import Path
from typing import Any, Callable, Iterator

from ...core.errors import InputError, LenticalibError
from ...core.files.outputs import check_output_file, check_output_folder
from .figure import FIGURE_NAME, write_fleet_figure
from .identity import FitOptions
from .summary import CSV_NAME, SUMMARY_NAME, fleet_summary, write_summary
from .task import PANEL_CONTENTS, failed_row, fit_panel, missing_folders

RETRIES = 1  # Dask's retries of a task that raised (not a fit's refusal: that is a row)
CONNECT_TIMEOUT_S = 20.0  # reaching the scheduler
WORKERS_TIMEOUT_S = 60.0  # waiting for the workers asked for to join
MAX_WORKERS = 1024
SHARED_PATHS = ("the Dask workers must see the capture folders and the output folder at the same paths as this "
                "machine (a shared file server mounted at the same place)")
SCHEDULER_HOW = ("start one with 'dask scheduler' and its workers with 'dask worker ADDRESS', or leave `scheduler` "
                 "out for a local cluster")


@dataclasses.dataclass
class FleetRun:
    """What :func:`fit_fleet` did: ``rows`` (one per capture folder, in the order given; see
    :mod:`.summary`), ``summary`` (the ``summary.json`` document), the paths written, and the
    ``cluster`` it ran on (``scheduler`` address, ``workers``)."""

    rows: list[dict[str, Any]]
    summary: dict[str, Any]
    summary_path: Path
    csv_path: Path
    figure_path: Path
    cluster: dict[str, Any]

    @property
    def all_ok(self) -> bool:
        """Whether every panel's fit is trusted (status ok)."""
        return all(r["status"] == "ok" for r in self.rows)


def plan_panels(captures: list[str | os.PathLike], out: str | os.PathLike) -> list[tuple[str, str]]:
    """(capture folder, panel folder) per capture folder, both absolute, once the outputs can be
    written (module docstring); InputError naming the path at fault otherwise.  Writes nothing."""
    if not captures:
        raise InputError("no capture folder given", source="captures", hint="give one capture folder per panel")
    folders = [os.path.abspath(c) for c in captures]
    out_abs = os.path.abspath(out)
    for given, folder in zip(captures, folders):
        if not os.path.isdir(folder):
            what = "is not a folder" if os.path.exists(folder) else "does not exist"
            raise InputError(what, source=str(given), hint="give the capture folder of a panel (patterns.json, "
                                                           "captures/)")
    check_output_folder(out, "batch output folder", inputs=folders)
    for given, folder in zip(captures, folders):  # one not made yet, inside a capture folder
        if out_abs.startswith(folder.rstrip(os.sep) + os.sep):
            raise InputError(f"is inside {given}, one of this command's inputs", source=str(out),
                             hint="give the results a folder outside the capture folders")
    names: dict[str, str] = {}
    for given, folder in zip(captures, folders):
        name = Path(folder).name
        if name in names:
            raise InputError(f"has the same folder name as {names[name]}: both panels would be written to "
                             f"{Path(out) / name}", source=str(given),
                             hint="give every panel's capture folder a name of its own (its serial number)")
        names[name] = str(given)
    plan = [(folder, os.path.join(out_abs, Path(folder).name)) for folder in folders]
    if os.path.isdir(out_abs):
        for folder, panel in plan:
            check_output_folder(panel, "panel folder", PANEL_CONTENTS, inputs=[folder])
        for name in (SUMMARY_NAME, CSV_NAME, FIGURE_NAME):
            check_output_file(Path(out_abs) / name, "fleet summary", example=name, inputs=folders)
    return plan


@contextlib.contextmanager
def dask_client(scheduler: str | None, workers: int | None) -> Iterator[Any]:
    """A ``distributed.Client``: of a local cluster of ``workers`` processes (default one per core),
    or of the running cluster at ``scheduler``, once ``workers`` (default 1) of its workers have
    joined.  Closed (the local cluster shut down) on leaving."""
    import logging

    from distributed import Client, LocalCluster  # lazy: dask is imported only when a fleet runs

    if workers is not None and not 1 <= workers <= MAX_WORKERS:
        raise InputError(f"{workers} workers is out of range", source="workers", hint=f"use 1..{MAX_WORKERS}")
    cluster = None
    if scheduler is None:
        cluster = LocalCluster(n_workers=workers or os.cpu_count() or 1, threads_per_worker=1, processes=True,
                               dashboard_address=None, silence_logs=logging.ERROR)
        client = Client(cluster)
    else:
        try:
            client = Client(scheduler, timeout=CONNECT_TIMEOUT_S)
        except (OSError, TimeoutError, ValueError) as exc:
            reason = " ".join(str(exc).split()) or type(exc).__name__
            raise InputError(f"cannot reach the Dask scheduler ({reason})", source="scheduler",
                             hint=SCHEDULER_HOW) from None
    try:
        if cluster is None:
            try:
                client.wait_for_workers(workers or 1, timeout=WORKERS_TIMEOUT_S)
            except TimeoutError:
                have = len(client.scheduler_info().get("workers", {}))
                raise InputError(f"has {have} workers; {workers or 1} did not join in {WORKERS_TIMEOUT_S:g} s",
                                 source=scheduler, hint="start workers with 'dask worker ADDRESS', or ask "
                                 "for fewer `workers`") from None
        yield client
    finally:
        client.close()
        if cluster is not None:
            cluster.close()


def check_workers_see(client, paths: list[str]) -> int:
    """The number of workers, once every worker of ``client`` sees each of ``paths`` as a folder;
    InputError naming the first one a worker cannot see otherwise."""
    seen = client.run(missing_folders, paths)
    for address, missing in sorted(seen.items()):
        if missing:
            raise InputError(f"the Dask worker {address} cannot see this folder", source=missing[0],
                             hint=SHARED_PATHS)
    return len(seen)


def fit_fleet(captures: list[str | os.PathLike], out: str | os.PathLike, *, scheduler: str | None = None,
              workers: int | None = None, options: FitOptions | None = None, command: str | None = None,
              progress: Callable[[str], None] | None = None,
              progress_total: Callable[[int], None] | None = None) -> FleetRun:
    """Fit every panel of ``captures`` into ``out`` on a Dask cluster (module docstring).

    ARGUMENTS: ``captures``: capture folders, one per panel (their names name the panels and
    their folders in ``out``); ``out``: the output folder (created; its parent must exist);
    ``scheduler``: a Dask scheduler's address (None: a local cluster); ``workers``: the local
    cluster's processes, or how many workers of ``scheduler`` to wait for; ``options``: the fit
    options (:class:`~.identity.FitOptions`); ``command``: the command line for each profile's
    provenance; ``progress``: called with a panel's name as it is done; ``progress_total``: once,
    with the number of panels.

    RETURNED VALUE: a :class:`FleetRun`.  Raises InputError before any task starts.
    """
    options = (options or FitOptions()).checked()
    plan = plan_panels(captures, out)
    out_path = Path(os.path.abspath(out))
    with dask_client(scheduler, workers) as client:
        count = check_workers_see(client, [c for c, _ in plan] + [str(out_path.parent if not out_path.exists()
                                                                      else out_path)])
        out_path.mkdir(exist_ok=True)
        if progress_total is not None:
            progress_total(len(plan))
        rows = run_tasks(client, plan, options, command, progress)
        cluster = {"scheduler": scheduler or "local", "workers": count}
    summary = {**fleet_summary(rows, options.to_dict()), "cluster": cluster}
    summary_path, csv_path = write_summary(out_path, summary)
    figure_path = write_fleet_figure(out_path, summary)
    return FleetRun(rows, summary, summary_path, csv_path, figure_path, cluster)


def run_tasks(client, plan: list[tuple[str, str]], options: FitOptions, command: str | None,
              progress: Callable[[str], None] | None) -> list[dict[str, Any]]:
    """Submit one :func:`.task.fit_panel` per (capture, panel) of ``plan`` and gather the rows, in
    ``plan``'s order, as they complete.  A task that raised (after its retries) or whose workers
    were lost too often is a failed row.  Ctrl-C cancels the tasks not finished and re-raises."""
    from distributed import as_completed  # lazy: dask is imported only when a fleet runs

    token = uuid.uuid4().hex[:8]
    futures = {client.submit(fit_panel, capture, panel, options, command, key=f"fit-panel-{i}-{token}",
                             pure=False, retries=RETRIES): i
               for i, (capture, panel) in enumerate(plan)}
    rows: list[dict[str, Any] | None] = [None] * len(plan)
    try:
        for future in as_completed(futures):
            i = futures[future]
            capture, panel = plan[i]
            try:
                rows[i] = future.result()
            except LenticalibError as exc:
                rows[i] = failed_row(Path(panel).name, capture, str(exc))
            except Exception as exc:  # noqa: BLE001 -- a bug or a lost worker: this panel's row, not the fleet's end
                reason = " ".join(str(exc).split())
                kind = type(exc).__name__
                if kind == "KilledWorker":
                    reason = f"the workers running it were lost too often ({reason})"
                rows[i] = failed_row(Path(panel).name, capture, f"{kind}: {reason}" if reason else kind)
            if progress is not None:
                progress(Path(panel).name)
    except BaseException:
        client.cancel(list(futures))
        raise
    return [r for r in rows if r is not None]
