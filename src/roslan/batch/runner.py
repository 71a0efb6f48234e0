"""Running a batch: every task once, in this process or on a Dask cluster.

Tasks whose folder holds a complete ``run.json`` of the same config are skipped, so a
batch can be resumed; a task that raised something other than a roslan error (a worker
died, an OSError) is retried. ``OUTDIR/batch.json`` tracks every task as it finishes.
"""

from __future__ import annotations

import contextlib
import logging
import os
import shutil
import time
import traceback
import warnings
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

from roslan.batch.report import BatchJournal, BatchReport, TaskProgress, TaskResult
from roslan.batch.tasks import Task, config_fingerprint
from roslan.config.base import UnitWarning, validate_model
from roslan.errors import ConfigError, RoslanError
from roslan.rundir.manifest import read_manifest, run_duration, run_messages

__all__ = ["LOCAL_CLUSTER_CONFIG", "Runner", "dry_check", "run_tasks"]

Runner = Callable[[Any, Path, bool, "Path | None"], Mapping[str, Any]]
"""``runner(config: SimConfig, outdir, overwrite, config_path) -> run.json dict``; the
default calls :func:`roslan.pipeline.run_simulation` with ``quiet=True``."""

Outcome = Mapping[str, Any] | BaseException
"""What one task gave: :func:`_execute`'s summary, or the exception it raised."""
Record = Callable[[Task, Outcome, int], None]
"""``record(task, outcome, attempts)``: file one finished task."""


def _default_runner(
    config: Any, outdir: Path, overwrite: bool, config_path: Path | None
) -> Mapping[str, Any]:
    from roslan.pipeline import run_simulation

    info: Mapping[str, Any] = run_simulation(
        config, outdir, overwrite=overwrite, quiet=True, config_path=config_path
    )
    return info


def _execute(
    config: dict[str, Any],
    base_dir: str,
    outdir: str,
    overwrite: bool,
    runner: Runner | None,
    config_file: str | None = None,
) -> dict[str, Any]:
    """The Dask task: validate, simulate, summarize. Deterministic user errors
    (RoslanError) are returned, not raised, so they are not retried; anything else
    (worker trouble, OSError...) raises and Dask retries it."""
    from roslan.config.sim import SimConfig

    t0 = time.perf_counter()
    marker = _attempts_file(Path(outdir))
    with contextlib.suppress(OSError), marker.open("a", encoding="utf-8") as fh:
        fh.write(f"{os.getpid()}\n")  # one line per attempt, read back by the driver
    try:
        with warnings.catch_warnings():  # make_tasks reported them, once per sweep
            warnings.simplefilter("ignore", UnitWarning)
            cfg = validate_model(SimConfig, config, "<task>", context={"base_dir": Path(base_dir)})
        cfg_path = Path(config_file) if config_file else None
        info = (runner or _default_runner)(cfg, Path(outdir), overwrite, cfg_path)
    except RoslanError as err:
        return {"status": "failed", "error": f"{type(err).__name__}: {err}"}
    return {
        "status": "complete",
        "wall_s": time.perf_counter() - t0,
        "duration_s": run_duration(info),
        "messages": run_messages(info),
    }


def _attempts_file(outdir: Path) -> Path:
    return outdir.parent / f".{outdir.name}.attempts"


def _settle(outdir: Path) -> int:
    """Attempts recorded for the task writing ``outdir`` (0 if none); removes the record and
    the partial folders of failed attempts (only when no live run holds OUTDIR's lock)."""
    from roslan.errors import OutputError
    from roslan.rundir.folder import clean_stale, outdir_lock

    marker = _attempts_file(outdir)
    try:
        n = len(marker.read_text(encoding="utf-8").splitlines())
        marker.unlink()
    except OSError:
        n = 0
    with contextlib.suppress(OutputError), outdir_lock(outdir):
        clean_stale(outdir)
    return n


def _existing_matches(task: Task, info: Mapping[str, Any]) -> bool:
    """True unless run.json's recorded config (the pipeline's ``model_dump(mode="json")``
    of the validated config, as our fingerprint) differs from the task's."""
    recorded = info.get("config")
    if not isinstance(recorded, Mapping):
        return True
    return config_fingerprint(recorded) == task.fingerprint


def _cluster(workers: int | None, scheduler: str | None) -> tuple[Any, Any, int | str]:
    import distributed

    dist: Any = distributed  # untyped constructors: keep mypy strict elsewhere
    Client, LocalCluster = dist.Client, dist.LocalCluster
    if scheduler:
        try:
            client = Client(scheduler, timeout="10s")
        except (OSError, TimeoutError) as err:
            msg = f"--scheduler {scheduler}: cannot connect to a Dask scheduler there ({err})"
            raise ConfigError(msg) from None
        return client, None, scheduler
    n = workers if workers is not None else (os.cpu_count() or 1)
    cluster = LocalCluster(
        n_workers=n,
        threads_per_worker=1,
        processes=True,
        host="127.0.0.1",
        dashboard_address=None,
        silence_logs=logging.CRITICAL,  # task errors are reported per task
    )
    return Client(cluster), cluster, n


def run_tasks(
    tasks: Sequence[Task],
    outdir: str | Path,
    *,
    workers: int | None = None,
    scheduler: str | None = None,
    retries: int = 2,
    overwrite: bool = False,
    runner: Runner | None = None,
    progress: bool = True,
    meta: Mapping[str, Any] | None = None,
) -> BatchReport:
    """Run every valid task once (skipping completed ones), write ``outdir/batch.json``.

    Args:
        workers: local worker processes (one thread each, loopback only); ``0`` runs the
            tasks in this process, one after the other (no Dask).
        scheduler: address of an existing Dask scheduler (``tcp://host:8786``); ``outdir``
            must then be on a file system the workers share.
        retries: extra attempts for a task that raised something other than a roslan
            error (those are deterministic: a task is pure given its config).
        overwrite: rerun tasks even when a complete ``run.json`` exists.
        runner: replaces :func:`roslan.pipeline.run_simulation` (tests, custom pipelines).
        meta: extra top-level entries of ``batch.json`` (the command, its inputs).
    """
    out = Path(outdir).resolve()
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        msg = f"-o {outdir}: cannot create the output folder: {err}"
        raise ConfigError(msg) from None
    if retries < 0:
        msg = f"--retries = {retries}: must be >= 0"
        raise ConfigError(msg)
    results: dict[str, TaskResult] = {}
    journal = BatchJournal(out, results, meta)
    todo = _plan(tasks, out, overwrite, results)
    journal.save(final=False)

    def record(task: Task, outcome: Outcome, attempts: int) -> None:
        res = results[task.name]
        res.attempts = max(attempts, _settle(out / task.name))
        if isinstance(outcome, BaseException):
            res.status = "failed"
            detail = "".join(traceback.format_exception_only(type(outcome), outcome)).strip()
            res.error = detail or type(outcome).__name__
        else:
            res.status = str(outcome["status"])
            res.error = outcome.get("error")
            res.wall_s = outcome.get("wall_s")
            res.duration_s = outcome.get("duration_s")
            res.messages = outcome.get("messages")
        journal.save()

    n_workers: int | str = 0
    with TaskProgress(progress, len(todo)) as advance:
        if todo and workers == 0 and not scheduler:
            _run_serial(todo, out, retries, runner, record, advance)
        elif todo:
            n_workers = _run_dask(todo, out, workers, scheduler, retries, runner, record, advance)
    journal.save(final=True)
    return BatchReport(out, journal.ordered(), time.perf_counter() - journal.t0, n_workers)


def _verdict(task: Task, out: Path, overwrite: bool) -> tuple[str, str | None, Any]:
    """What the batch does with ``task`` (nothing touched): ``("invalid", error, None)``,
    ``("skipped", None, run.json)`` for a complete run of the same config, ``("failed",
    error, None)`` for a complete run of another config, else ``("pending", None,
    replace)`` with whether its folder is replaced (debris of an interrupted run)."""
    if task.error is not None:
        return "invalid", task.error, None
    folder = out / task.name
    info = read_manifest(folder)
    if info is not None and not overwrite:
        if _existing_matches(task, info):
            return "skipped", None, info
        error = (
            f"{folder} holds a complete run of a different config; pass --overwrite to replace it"
        )
        return "failed", error, None
    # A folder without a complete run.json is debris of an interrupted run: replace it.
    return "pending", None, overwrite or folder.exists()


def dry_check(task: Task, outdir: str | Path, overwrite: bool = False) -> str | None:
    """``--dry-run`` of one task: None when :func:`run_tasks` would run it (or skip it as
    done), else the error it would report, with the same message: an invalid config, a
    complete run of another config in its folder, or any check of the simulation
    (:func:`roslan.pipeline.check_run`: limits, sensors, topics, free space, the scene
    and the path's clearance). Writes nothing."""
    from roslan.config.sim import SimConfig
    from roslan.pipeline import check_run

    out = Path(outdir).resolve()
    status, error, replace = _verdict(task, out, overwrite)
    if status != "pending":
        return error
    try:
        with warnings.catch_warnings():  # make_tasks reported them, once per sweep
            warnings.simplefilter("ignore", UnitWarning)
            cfg = validate_model(
                SimConfig, task.config, "<task>", context={"base_dir": task.base_dir}
            )
        check_run(cfg, out / task.name, overwrite=bool(replace), config_path=task.config_file)
    except RoslanError as err:
        return f"{type(err).__name__}: {err}"
    return None


def _plan(
    tasks: Sequence[Task], out: Path, overwrite: bool, results: dict[str, TaskResult]
) -> list[tuple[Task, bool]]:
    """File every task's result (invalid, skipped, failed for a foreign run, else pending)
    in ``results``; the pending tasks to run, with whether to replace their folder."""
    todo: list[tuple[Task, bool]] = []
    for task in tasks:
        res = TaskResult(task.name, task.index, "pending", overrides=task.overrides)
        results[task.name] = res
        status, error, extra = _verdict(task, out, overwrite)
        if status != "pending":
            res.status, res.error = status, error
            if status == "skipped":
                res.duration_s, res.messages = run_duration(extra), run_messages(extra)
            continue
        todo.append((task, bool(extra)))
        # A hidden partial folder of a killed simulation is debris too (SIGKILL skips its
        # cleanup).
        for debris in out.glob(f".{task.name}.partial-*"):
            shutil.rmtree(debris, ignore_errors=True)
    return todo


def _run_serial(
    todo: Sequence[tuple[Task, bool]],
    out: Path,
    retries: int,
    runner: Runner | None,
    record: Record,
    advance: Callable[[str], None],
) -> None:
    """Run the tasks one after the other in this process (``--workers 0``)."""
    for task, ow in todo:
        outcome: Outcome = RuntimeError("not run")
        attempts = 0
        while attempts <= retries:
            attempts += 1
            try:
                outcome = _execute(
                    task.config,
                    str(task.base_dir),
                    str(out / task.name),
                    ow,
                    runner,
                    str(task.config_file) if task.config_file else None,
                )
                break
            except Exception as err:
                outcome = err
        record(task, outcome, attempts)
        advance(task.name)


def _run_dask(
    todo: Sequence[tuple[Task, bool]],
    out: Path,
    workers: int | None,
    scheduler: str | None,
    retries: int,
    runner: Runner | None,
    record: Record,
    advance: Callable[[str], None],
) -> int | str:
    import dask

    if workers is not None and workers < 1:
        msg = f"--workers = {workers}: must be >= 1 (or 0 to run in this process)"
        raise ConfigError(msg)

    with dask.config.set(LOCAL_CLUSTER_CONFIG):
        # held for the cluster's lifetime: the nanny reads it again when it restarts a
        # worker that died
        return _run_on_cluster(todo, out, workers, scheduler, retries, runner, record, advance)


LOCAL_CLUSTER_CONFIG: dict[str, Any] = {
    # A simulation can starve its worker's event loop for minutes on a loaded machine
    # (GIL-holding rendering); the nanny already reports real process deaths, so the
    # scheduler must not also expel "silent" workers and rerun their tasks.
    "distributed.scheduler.worker-ttl": None,
    # A simulation may start helper processes, which daemonic workers cannot.
    "distributed.worker.daemon": False,
}


def _run_on_cluster(
    todo: Sequence[tuple[Task, bool]],
    out: Path,
    workers: int | None,
    scheduler: str | None,
    retries: int,
    runner: Runner | None,
    record: Record,
    advance: Callable[[str], None],
) -> int | str:
    import distributed

    as_completed: Any = distributed.as_completed
    client, cluster, n = _cluster(min(workers or (os.cpu_count() or 1), len(todo)), scheduler)
    try:
        futures = {}
        for task, ow in todo:
            fut = client.submit(
                _execute,
                task.config,
                str(task.base_dir),
                str(out / task.name),
                ow,
                runner,
                str(task.config_file) if task.config_file else None,
                key=f"roslan-sim-{task.name}-{task.fingerprint}",
                retries=retries,
                pure=False,
            )
            futures[fut] = task
        for fut in as_completed(list(futures)):
            task = futures[fut]
            try:
                outcome: Outcome = fut.result()
            except Exception as err:
                outcome = err
            record(task, outcome, 1)
            advance(task.name)
    finally:
        client.close()
        if cluster is not None:
            cluster.close()
    return n
