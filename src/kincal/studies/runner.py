"""Monte-Carlo studies that scale out: trials in tasks, any ``concurrent.futures.Executor``, a results
file that lets an interrupted study resume.

A study is a picklable function ``run(task) -> list[dict]`` (one record per trial; each trial draws
its random numbers from its own trial number, so where and in which order it runs cannot change
its result) and a list of :class:`Task`. :func:`run_tasks` submits the tasks that the results file
does not hold yet to an executor (:func:`make_executor`: a process pool or a Dask cluster) and
appends each finished task to the file as one JSON line (flushed and synced), so a study stopped at
any point resumes where it was. The first line names the study (its settings); a file of another
study is refused. Records come back sorted by trial, so the same settings give the same numbers on
one core, two, or a cluster.
"""
from __future__ import annotations

import json
import multiprocessing
import os
from concurrent.futures import Executor, ProcessPoolExecutor, as_completed
from contextlib import ExitStack, contextmanager, nullcontext
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Iterator, Sequence

TRIALS_PER_TASK = 100  # a task carries this many trials: a scheduler's per-task cost (ms) stays negligible


@dataclass(frozen=True)
class Task:
    """A batch of trials, numbered ``first`` … ``first + count - 1``."""

    first: int
    count: int

    @property
    def trials(self) -> range:
        return range(self.first, self.first + self.count)


def tasks_for(trials: int, per_task: int = TRIALS_PER_TASK) -> list[Task]:
    """``trials`` trials cut into tasks of ``per_task`` (the last may be smaller)."""
    if trials < 1 or per_task < 1:
        raise ValueError(f"trials={trials}, per_task={per_task}: both must be at least 1")
    return [Task(a, min(per_task, trials - a)) for a in range(0, trials, per_task)]


class _InProcess(Executor):
    """One worker, no process: the reference run and the smallest overhead (tasks run one by one
    as :func:`run_tasks` asks for them)."""

    def submit(self, fn, *args, **kwargs):
        raise TypeError("the in-process executor runs tasks through run_tasks only")


def _stop_workers(pool: ProcessPoolExecutor) -> None:
    """End every worker process now and wait for it: the pool's own and any still starting (not in its
    list yet). A worker started after an earlier sweep was left reading its task queue while the
    interpreter's exit waited for it: an interrupted study hung. Killed, not terminated: a worker still
    starting prints a traceback when SIGTERM meets its start-up, and a study keeps nothing in its
    workers (the results are the parent's)."""
    procs: list = list((pool._processes or {}).values())  # the pool's own processes (private, no API)
    procs += [p for p in multiprocessing.active_children() if p not in procs]
    for proc in procs:
        proc.kill()
    for proc in procs:
        proc.join(timeout=5)


@contextmanager
def make_executor(workers: int = 1, scheduler: str | None = None) -> Iterator[Executor]:
    """An executor for :func:`run_tasks`: in-process for one worker, else a process pool of
    ``workers``; with ``scheduler`` a Dask cluster (the optional extra ``kincal[dask]``): "local:N"
    for a LocalCluster of N single-threaded worker processes, or an address such as tcp://host:8786."""
    if scheduler is None:
        if workers < 1:
            raise ValueError(f"workers={workers}: give 1 or more")
        if workers == 1:
            yield _InProcess()
            return
        pool = ProcessPoolExecutor(workers, initializer=_single_thread)
        try:
            yield pool
        except BaseException:  # Ctrl-C or an error: stop the workers now, not after their tasks
            pool.shutdown(wait=False, cancel_futures=True)  # first: no task and no worker starts after the sweep
            _stop_workers(pool)
            raise
        pool.shutdown()
        return
    try:
        from distributed import Client, LocalCluster
    except ImportError:
        raise ValueError("a Dask scheduler needs the optional extra: pip install 'kincal[dask]'") from None
    cluster = (LocalCluster(n_workers=int(scheduler.split(":", 1)[1]), threads_per_worker=1, processes=True,
                            dashboard_address=None) if scheduler.startswith("local:") else nullcontext(scheduler))
    with cluster as target, Client(target) as client:
        client.run(_single_thread)
        yield client.get_executor()


def _quiet_exit(signum, frame) -> None:
    """A worker's SIGTERM: exit with 143; multiprocessing prints no traceback for SystemExit."""
    raise SystemExit(143)


def _single_thread() -> None:
    """One BLAS thread per worker process for its whole life (the workers are the parallelism);
    Ctrl-C is the main process's to handle, and SIGTERM (the main process stopping the pool) ends a
    worker quietly, unwinding as an exception does (so no lock stays held), instead of through the
    command line's handler it inherited by fork, whose exception multiprocessing prints with a
    traceback (signals can be set from a main thread only: a Dask worker runs this in another)."""
    import signal
    import threading

    from .._threads import blas_threads
    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGINT, signal.SIG_IGN)
        signal.signal(signal.SIGTERM, _quiet_exit)
    blas_threads(1).__enter__()  # left entered on purpose: the limit lasts as long as the worker


def check_results_file(path: str | os.PathLike, header: dict) -> dict[int, list[dict]]:
    """Before any work: ``path`` is absent, empty or holds results of the study ``header`` names (ValueError
    otherwise). Returns its finished tasks (a torn last line from an interruption is ignored)."""
    path, header = Path(path), json.loads(json.dumps(header))  # the header as read back from the file
    if not path.exists():
        return {}
    lines = path.read_text(encoding="utf-8").splitlines()
    if not lines:  # an empty file (made beforehand): nothing to keep, the header is written first
        return {}
    try:
        first = json.loads(lines[0])
    except json.JSONDecodeError:
        first = None
    if first != {"study": header}:
        raise ValueError(f"{path}: holds the results of another study{_differing(first, header)} (or is not a "
                         f"results file); give a new output file or remove this one")
    done = {}
    for k, line in enumerate(lines[1:], start=2):
        try:
            rec = json.loads(line)
        except json.JSONDecodeError:
            continue  # the line being written when the study stopped
        if not (isinstance(rec, dict) and isinstance(rec.get("task"), int) and isinstance(rec.get("records"), list)):
            raise ValueError(f"{path}: line {k} is not a task record of this study; give a new output file or remove "
                             f"this one")
        done[rec["task"]] = rec["records"]
    return done


def _reconciled(done: dict[int, list], tasks: Sequence[Task]) -> dict[int, list]:
    """The finished tasks of a results file against the ``tasks`` asked now: a last task of a smaller study
    (its trials the first of the task asked) is run again in full, one of a larger study gives its first trials;
    any other difference is left for :func:`_check_done` to name."""
    by_first, out = {t.first: t for t in tasks}, {}
    for first, records in done.items():
        task = by_first.get(first)
        trials = [r.get("trial") if isinstance(r, dict) else None for r in records]
        want = [] if task is None else list(task.trials)
        if task is not None and 0 < len(trials) < len(want) and trials == want[:len(trials)]:
            continue  # the later, full record of the task is appended, and read last
        out[first] = records[:len(want)] if task is not None and trials[:len(want)] == want else records
    return out


def _drop_torn_line(path: Path) -> None:
    """Cut a results file back to its last whole line (a line torn by an interruption, ignored when read, would
    otherwise be continued by the next record)."""
    if not path.exists():
        return
    raw = path.read_bytes()
    if raw and not raw.endswith(b"\n"):
        with path.open("r+b") as handle:
            handle.truncate(raw.rfind(b"\n") + 1)


def _differing(first, header: dict) -> str:
    """', run with --per-task 100' and the like: the settings in which a results file's study differs ('' when
    it is no study's file)."""
    held = first.get("study") if isinstance(first, dict) else None
    if not isinstance(held, dict) or held.get("study") != header.get("study"):
        return ""
    keys = [k for k in dict.fromkeys([*held, *header]) if held.get(k) != header.get(k)]
    flags = {"m": "--poses", "generations": "--generations", "seed": "--seed", "per_task": "--per-task"}
    said = [f"{flags[k]} {held[k]}" for k in keys if k in flags and k in held]
    return f", run with {', '.join(said)} (give the same to resume it)" if said and len(said) == len(keys) else ""


def _check_done(path: Path, done: dict[int, list], tasks: Sequence[Task]) -> None:
    """Every finished task in the file holds one record (a mapping) per trial of that task, all with
    the same keys (ValueError naming the task otherwise: the summary would cover other trials)."""
    by_first = {t.first: t for t in tasks}
    beyond = [first for first in done if first not in by_first and first > max(by_first, default=-1)]
    if beyond:
        held = max(r.get("trial", -1) for first in beyond for r in done[first] if isinstance(r, dict)) + 1
        asked = sum(len(t.trials) for t in tasks)
        raise ValueError(f"{path}: holds {held} trials of this study, more than the {asked} asked; give --trials "
                         f"{held} (or more) to use and extend it, or a new output file")
    keys = None
    for first, records in done.items():
        task = by_first.get(first)
        ok = (task is not None and all(isinstance(r, dict) for r in records)
              and [r.get("trial") for r in records] == list(task.trials))
        if ok and records:
            keys = keys or set(records[0])
            ok = all(set(r) == keys for r in records)
        if not ok:
            raise ValueError(f"{path}: the record of task {first} does not hold one result per trial of this study "
                             f"(trials {first}..); the file was changed or written by another version; give a new "
                             f"output file or remove this one")


def _append(handle, record: dict) -> None:
    handle.write(json.dumps(record, separators=(",", ":")) + "\n")
    handle.flush()
    os.fsync(handle.fileno())


def run_tasks(run: Callable[[Task], list[dict]], tasks: Sequence[Task], executor: Executor, path: str | os.PathLike,
              header: dict, progress: Callable[[int, int], None] | None = None) -> list[dict]:
    """Run the ``tasks`` the results file at ``path`` does not hold yet, appending each as it finishes;
    return every trial's record, sorted by trial. ``header``: the study's settings (JSON), checked
    against the file; ``progress(done, total)`` is called as tasks finish."""
    path = Path(path)
    done = _reconciled(check_results_file(path, header), tasks)
    _check_done(path, done, tasks)
    todo = [t for t in tasks if t.first not in done]
    tell = progress or (lambda *_: None)
    tell(len(tasks) - len(todo), len(tasks))
    with ExitStack() as stack:
        handle = None  # opened with the first finished task: a study that fails first leaves no file behind
        for task, records in _finished(run, todo, executor):
            if handle is None:
                _drop_torn_line(path)
                handle = stack.enter_context(path.open("a", encoding="utf-8"))
                if not done and path.stat().st_size == 0:
                    _append(handle, {"study": header})
            done[task.first] = records
            _append(handle, {"task": task.first, "records": records})
            tell(sum(1 for t in tasks if t.first in done), len(tasks))
    _check_done(path, done, tasks)  # the new records against the old ones' keys
    records = [r for t in tasks for r in done[t.first]]
    return sorted(records, key=lambda r: r["trial"])


def _finished(run, todo: Sequence[Task], executor: Executor):
    """(task, records) as tasks finish; pending ones are cancelled if the caller stops early."""
    if isinstance(executor, _InProcess):
        for task in todo:
            yield task, run(task)
        return
    futures = {executor.submit(run, t): t for t in todo}
    try:
        for fut in as_completed(futures):
            yield futures[fut], fut.result()
    finally:
        for fut in futures:
            fut.cancel()
