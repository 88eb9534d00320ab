"""`analysis.study` / ``fibres study``: a cohort (subjects x trials) run as independent tasks on
Dask or a local process pool, resumable, one trial's failure isolated from the others.

Method:

1. The study file is read and checked (`analysis.study_file`) and the output folder claimed
   (`analysis.out_folder`: the refusal rule and ``DIR/.fibres-lock``, one study at a time).
2. Every trial whose outputs are up to date is skipped (`analysis.study_folder.is_up_to_date`:
   same settings, same sha256 of every input listed in its ``run.json``). Only hashing happens
   here; no worker is started when nothing is left to run.
3. Per subject with trials to run, one task per muscle makes the rest-pose decomposition
   (`analysis.study_tasks.rest_bundle`); one task per trial runs ``fibres run`` into
   ``DIR/<subject>/<trial>/`` with the subject's bundles (`analysis.study_tasks.run_trial`). On
   Dask the bundles are task dependencies (computed once, moved to the workers that need them).
4. As each trial finishes: one line (not on a terminal; a bar on one), its record in
   ``DIR/study.json`` and its tables in ``DIR/study.parquet`` (`analysis.study_folder`). A study
   killed half way keeps every finished trial, and its next run skips them.

Engines. ``engine="dask"`` (the default when ``dask.distributed`` is installed): a
``LocalCluster`` of ``workers`` processes (default: one per core) with one thread each, on the
loopback (scheduler and dashboard on 127.0.0.1, free ports), or the scheduler at ``scheduler``
(``tcp://host:port``; its workers must import this package and see the same paths). Processes,
not threads: a trial is numpy code that holds the GIL between calls, a worker's crash stays its
own, and a process per core keeps BLAS to one thread (Dask's nanny sets ``OMP_NUM_THREADS=1`` etc.). A task
whose worker dies is rerun on another worker by the scheduler (``distributed.scheduler.allowed-
failures``, default 3); its half-done trial left only a hidden staging folder, which the rerun
removes (`fibres run`'s staging rule). Worker memory: LocalCluster's default limit (the machine's
memory over the workers) and each trial's own estimate (``max-memory`` option). ``engine=
"processes"`` (also the fallback without Dask, with a notice): a ``concurrent.futures``
process pool (spawned, same thread settings); a pool broken by a dead worker is rebuilt and its
unfinished trials resubmitted, at most `POOL_RETRIES` times each.
"""
from __future__ import annotations

import concurrent.futures
import contextlib
import dataclasses
import os
import sys
import time as _time
from pathlib import Path

from .errors import InputError, MissingDependencyError

__all__ = ["study", "StudyReport", "TrialOutcome", "ENGINES", "POOL_RETRIES", "dask_available"]

ENGINES = ("dask", "processes")
#: resubmissions of a trial whose pool worker died (the process-pool engine)
POOL_RETRIES = 2
#: thread settings of every worker process (one core per worker)
_ONE_THREAD = {k: "1" for k in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS",
                                "NUMBA_NUM_THREADS")}


@dataclasses.dataclass(frozen=True)
class TrialOutcome:
    """One trial of a study run: status ``"ok"``, ``"skipped"`` (up to date) or ``"failed"``."""
    subject: str
    trial: str
    folder: str
    status: str
    seconds: float = 0.0
    error: str | None = None
    kind: str | None = None
    warnings: tuple = ()


@dataclasses.dataclass(frozen=True)
class StudyReport:
    """What `study` did: every trial's outcome (study-file order), the engine, the wall time."""
    out: Path
    engine: str
    trials: tuple
    seconds: float
    dashboard: str | None = None

    @property
    def failed(self) -> tuple:
        return tuple(t for t in self.trials if t.status == "failed")

    def table(self) -> str:
        """The final table: subject, trial, status, time (s) and the error of a failed trial."""
        rows = [("subject", "trial", "status", "time_s", "error")]
        rows += [(t.subject, t.trial, t.status, f"{t.seconds:.1f}", t.error or "") for t in self.trials]
        widths = [max(len(r[i]) for r in rows) for i in range(4)]
        lines = ["  ".join(r[i].ljust(widths[i]) for i in range(4)) + ("  " + r[4] if r[4] else "")
                 for r in rows]
        n = {s: sum(t.status == s for t in self.trials) for s in ("ok", "skipped", "failed")}
        lines.append(f"{len(self.trials)} trials: {n['ok']} ran, {n['skipped']} up to date, "
                     f"{n['failed']} failed ({self.seconds:.1f} s, {self.engine})")
        return "\n".join(lines)


def dask_available() -> bool:
    """Whether ``dask.distributed`` can be imported (the ``musclefibres[dask]`` extra)."""
    import importlib.util

    return importlib.util.find_spec("distributed") is not None and importlib.util.find_spec("dask") is not None


def study(study_file, out, *, scheduler=None, workers=None, engine=None, force=False, quiet=True,
          log=None) -> StudyReport:
    """Run a study file (module docstring).

    Parameters
    ----------
    study_file : str or os.PathLike
        The study TOML (`analysis.study_file`).
    out : str or os.PathLike
        The study's output folder DIR.
    scheduler : str, optional, keyword-only
        Address of a running Dask scheduler (``tcp://127.0.0.1:8786``); default a LocalCluster.
    workers : int, optional, keyword-only
        Worker processes of the LocalCluster or the pool (default: the number of cores).
    engine : {"dask", "processes"}, optional, keyword-only
        Default "dask" when installed, else "processes" (with a notice).
    force : bool, keyword-only
        Write into DIR even where `fibres run` would refuse it (`analysis.out_folder`).
    quiet : bool, keyword-only
        No progress lines (errors are still in the report).
    log : callable, optional, keyword-only
        Receives each progress line (default: print to stderr).

    Returns
    -------
    StudyReport
    """
    from . import study_folder as folder
    from .out_folder import OutFolderLock, check_out_folder
    from .output_files import prepare_out_dir
    from .study_file import load_study

    t_start = _time.perf_counter()
    say = (lambda line: None) if quiet else (log or (lambda line: print(line, file=sys.stderr, flush=True)))
    if workers is not None and (isinstance(workers, bool) or int(workers) < 1):
        raise InputError(f"--workers must be >= 1, got {workers}", where="--workers",
                         fix="Give a whole number of worker processes >= 1.")
    engine = _choose_engine(engine, scheduler, say)
    spec = load_study(study_file)
    check_out_folder(out, force=force)
    out = prepare_out_dir(out).resolve()
    outcomes = {}
    with OutFolderLock(out):
        record = folder.read_record(out)
        hashes = folder.Hashes()
        pending = []
        for trial in spec.trials:
            if folder.is_up_to_date(out, trial, record, hashes):
                outcomes[trial.label] = TrialOutcome(trial.subject, trial.trial, trial.folder, "skipped")
            else:
                pending.append(trial)
        record = {"tool": "musclefibres", "study": str(spec.file),
                  "trials": {t.label: record["trials"][t.label] for t in spec.trials
                             if t.label in outcomes}}
        say(f"fibres study: {len(spec.trials)} trials of {len(spec.subjects)} subjects: "
            f"{len(spec.trials) - len(pending)} up to date, {len(pending)} to run")
        for trial in spec.trials:   # an up-to-date trial missing from the dataset: add it
            if trial.label in outcomes and not folder.has_partitions(out, trial):
                folder.publish_partitions(out, trial)
        dashboard = None
        if pending:
            runner = _DaskRunner(scheduler, workers) if engine == "dask" else _PoolRunner(workers)
            with runner:
                dashboard = runner.describe(say)
                bar = _Progress(len(pending), quiet=quiet, say=say)
                try:
                    for trial, result in runner.run(pending, out):
                        outcome = TrialOutcome(trial.subject, trial.trial, trial.folder, result["status"],
                                               float(result.get("seconds", 0.0)), result.get("error"),
                                               result.get("kind"), tuple(result.get("warnings", ())))
                        outcomes[trial.label] = outcome
                        record["trials"][trial.label] = folder.record_entry(trial, result)
                        if outcome.status == "ok":
                            folder.publish_partitions(out, trial)
                        else:
                            folder.drop_partitions(out, trial)
                        folder.write_record(out, record)
                        bar.done(trial, outcome)
                finally:
                    bar.close()
        folder.write_record(out, record)
        folder.prune_dataset(out, {t.folder for t in spec.trials
                                   if outcomes.get(t.label) and outcomes[t.label].status != "failed"})
    ordered = tuple(outcomes[t.label] for t in spec.trials)
    return StudyReport(out=out, engine=engine, trials=ordered, seconds=_time.perf_counter() - t_start,
                       dashboard=dashboard)


def _choose_engine(engine, scheduler, say) -> str:
    if engine is not None and engine not in ENGINES:
        raise InputError(f"unknown engine {engine!r}", where="--engine", fix=f"Use one of: {', '.join(ENGINES)}.")
    have = dask_available()
    if scheduler is not None:
        if engine == "processes":
            raise InputError("a scheduler address needs the Dask engine", where="--scheduler",
                             fix="Leave out --engine processes, or leave out --scheduler.")
        if not have:
            raise MissingDependencyError("--scheduler needs Dask: pip install 'musclefibres[dask]'")
        return "dask"
    if engine == "dask" and not have:
        raise MissingDependencyError("the Dask engine needs Dask: pip install 'musclefibres[dask]'")
    if engine is None and not have:
        say("fibres study: Dask is not installed: running the trials in a local process pool "
            "(pip install 'musclefibres[dask]' for Dask and clusters)")
        return "processes"
    return engine or "dask"


class _Progress:
    """One line per finished trial (not on a terminal), a tqdm bar on a terminal."""

    def __init__(self, total, *, quiet, say):
        self.total, self.n, self.say, self.bar = total, 0, say, None
        if not quiet and sys.stderr.isatty():
            from tqdm import tqdm

            self.bar = tqdm(total=total, desc="fibres study", unit="trial", file=sys.stderr, leave=False)

    def done(self, trial, outcome):
        self.n += 1
        text = f"{outcome.status} ({outcome.seconds:.1f} s)"
        if outcome.error:
            text += f": {outcome.error}"
        line = f"fibres study: [{self.n}/{self.total}] {trial.label}: {text}"
        if self.bar is not None:
            if outcome.status == "failed":
                self.bar.write(line, file=sys.stderr)
            self.bar.update(1)
        else:
            self.say(line)

    def close(self):
        if self.bar is not None:
            self.bar.close()


def _muscles_of(trial) -> list:
    """The muscles whose rest bundles a trial can use ([] if the fibre model cannot be read:
    the trial then reports that itself)."""
    from .study_tasks import _muscle_names

    try:
        return _muscle_names(trial.spec, trial.options)
    except Exception:   # noqa: BLE001 - reported by the trial
        return []


def _rest_options(trial) -> dict:
    return {k: trial.options.get(k) for k in ("fibres", "resolution", "template", "slicing")}


def _subject_groups(pending) -> dict:
    """Trials grouped by (fibre model, rest options): the trials that share rest bundles."""
    groups = {}
    for trial in pending:
        key = (str(trial.spec), tuple(sorted(_rest_options(trial).items())))
        groups.setdefault(key, []).append(trial)
    return groups


class _DaskRunner:
    """Trials on Dask: a LocalCluster (processes, one thread each, loopback) or a scheduler."""

    def __init__(self, scheduler, workers):
        import logging

        from distributed import Client, LocalCluster

        self.cluster = None
        if scheduler is None:
            kw = {} if workers is None else {"n_workers": int(workers)}
            self.cluster = LocalCluster(processes=True, threads_per_worker=1, host="127.0.0.1",
                                        dashboard_address="127.0.0.1:0", silence_logs=logging.ERROR, **kw)
            self.client = Client(self.cluster)
        else:
            try:
                self.client = Client(scheduler, timeout="20s")
            except (OSError, TimeoutError, ValueError) as exc:
                raise InputError(f"cannot reach the Dask scheduler ({exc})", where="--scheduler",
                                 fix="Start it (dask scheduler) or check the address tcp://HOST:PORT.") from None

    def describe(self, say):
        info = self.client.scheduler_info()
        n = len(info.get("workers", {}))
        link = self.client.dashboard_link if "dashboard" in info.get("services", {}) else None
        where = "LocalCluster" if self.cluster is not None else f"scheduler {self.client.scheduler.address}"
        say(f"fibres study: Dask {where}, {n} workers; dashboard: {link or 'not available (pip install bokeh)'}")
        return link

    def run(self, pending, out):
        import uuid

        from distributed import as_completed

        from .study_tasks import rest_bundle, run_trial

        tag = uuid.uuid4().hex[:8]
        futures = {}
        for (spec, _), trials in _subject_groups(pending).items():
            opts = _rest_options(trials[0])
            rest = [self.client.submit(rest_bundle, spec, opts, m, key=f"rest-{m}-{tag}-{len(futures)}-{k}",
                                       pure=False) for k, m in enumerate(_muscles_of(trials[0]))]
            for trial in trials:
                fut = self.client.submit(run_trial, trial, str(out), *rest, pure=False,
                                         key=f"trial-{trial.folder}-{tag}")
                futures[fut] = trial
        for fut in as_completed(list(futures)):
            trial = futures.pop(fut)
            try:
                result = fut.result()
            except Exception as exc:   # noqa: BLE001 - e.g. KilledWorker: this trial only
                result = {"status": "failed", "kind": "internal", "seconds": 0.0,
                          "error": " ".join(f"worker failure: {type(exc).__name__}: {exc}".split())}
            fut.release()
            yield trial, result

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        with contextlib.suppress(Exception):
            self.client.close()
        if self.cluster is not None:
            with contextlib.suppress(Exception):
                self.cluster.close()
        return False


class _PoolRunner:
    """Trials in a `concurrent.futures` process pool (spawned workers, one thread each)."""

    def __init__(self, workers):
        self.workers = int(workers) if workers else (os.cpu_count() or 1)
        self.saved = {k: os.environ.get(k) for k in _ONE_THREAD}
        os.environ.update(_ONE_THREAD)        # inherited by the spawned workers
        self.pool = self._new_pool()

    def _new_pool(self):
        import multiprocessing

        return concurrent.futures.ProcessPoolExecutor(max_workers=self.workers,
                                                      mp_context=multiprocessing.get_context("spawn"))

    def describe(self, say):
        say(f"fibres study: local process pool, {self.workers} workers")
        return None

    def run(self, pending, out):
        from concurrent.futures.process import BrokenProcessPool

        from .study_tasks import rest_bundle, run_trial

        waiting, running, tries = {}, {}, {}
        for (spec, _), trials in _subject_groups(pending).items():
            opts = _rest_options(trials[0])
            rest = [self.pool.submit(rest_bundle, spec, opts, m) for m in _muscles_of(trials[0])]
            for trial in trials:
                waiting[trial.label] = (trial, rest)
        while waiting or running:
            for label, (trial, rest) in list(waiting.items()):
                if all(f.done() for f in rest):
                    bundles = [f.result() for f in rest if not f.exception()]
                    running[self.pool.submit(run_trial, trial, str(out), *bundles)] = (trial, bundles)
                    del waiting[label]
            outstanding = list(running) + [f for _, rest in waiting.values() for f in rest if not f.done()]
            done, _ = concurrent.futures.wait(outstanding, return_when=concurrent.futures.FIRST_COMPLETED)
            broken = False
            for fut in [f for f in done if f in running]:
                trial, bundles = running.pop(fut)
                try:
                    yield trial, fut.result()
                except BrokenProcessPool:
                    broken = True
                    tries[trial.label] = tries.get(trial.label, 0) + 1
                    if tries[trial.label] > POOL_RETRIES:
                        yield trial, {"status": "failed", "kind": "internal", "seconds": 0.0,
                                      "error": f"its worker process died {tries[trial.label]} times"}
                    else:
                        waiting[trial.label] = (trial, [_done(b) for b in bundles])
            if broken or any(f.exception() is not None and isinstance(f.exception(), BrokenProcessPool)
                             for f in done if f not in running):
                self.pool.shutdown(wait=False, cancel_futures=True)
                self.pool = self._new_pool()
                for label, (trial, rest) in list(waiting.items()):   # lost rest bundles: go without
                    waiting[label] = (trial, [f if f.done() and not f.exception() else _done((None, None))
                                              for f in rest])
                for fut, (trial, bundles) in list(running.items()):
                    del running[fut]
                    waiting[trial.label] = (trial, [_done(b) for b in bundles])

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.pool.shutdown(wait=exc[0] is None, cancel_futures=True)
        for k, v in self.saved.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v
        return False


def _done(value):
    """A finished future holding ``value``."""
    fut = concurrent.futures.Future()
    fut.set_result(value)
    return fut
