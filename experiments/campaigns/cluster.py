"""Campaigns on Dask: run a campaign's cases in one process, on a local cluster of worker
processes or on an existing Dask cluster, with the same result.

A *case* here is the smallest independently seeded piece of a campaign — for ``wbc fuzz`` one
stack structure's ticks, one robot's ticks or a slice of the constructor calls, for ``wbc
audit`` one level × backend × robot cell. A case is a JSON-ready ``dict`` with at least a
``"key"`` (unique in the campaign: what ``--case KEY`` reruns) and a ``"seed"`` (the entropy of
its random generator, derived from the campaign's seed and the case's place, never from the
worker that runs it). :func:`run_cases` runs ``work(context, case, deadline)`` on every case
and returns the results **in case order**, so that a campaign's result does not depend on where
or in which order its cases ran.

Where (:func:`run_cases`'s ``workers`` / ``scheduler``):

* neither: in this process, one case after the other (the campaigns' behaviour before Dask);
* ``workers=N``: a :class:`distributed.LocalCluster` of ``N`` worker processes of one thread on
  ``127.0.0.1`` (started and stopped here);
* ``scheduler="tcp://host:8786"``: the workers of an existing Dask cluster (each must have wbc
  installed, and the user's ``--robot`` / ``--stack`` files at the same paths).

Cases are sent in batches (:func:`batch_size`: about four batches per worker thread, at most
:data:`MAX_BATCH` cases), never more batches in flight than the workers have threads, so a batch
starts when it is sent and its time limit (``time_limit`` [s] per case) runs from then.

Nothing is lost:

* a case that raises is recorded as a failure (``"raised"``) — the campaigns catch their own
  cases' errors, so this is an exception outside them (e.g. a controller that cannot be built);
* a batch whose worker dies is re-run by Dask elsewhere (its other cases with it); each case's
  attempts are counted (the scheduler's count of workers that died running it);
* a batch that Dask gives up on (its workers died more than :data:`ALLOWED_FAILURES` times:
  ``KilledWorker``)
  or that passes its time limit (its worker is then restarted) is split into single cases and
  re-run; a single case that does so is recorded as a failure (``"killed_worker"`` or
  ``"hang"``) with its seed;
* finished cases are written to ``DIR/NAME.partial.json`` (at most every
  :data:`PARTIAL_EVERY_S` seconds, and when the run stops, Ctrl-C included); a run of the same
  campaign (the same ``identity``) starts from them instead of starting over; the file is
  removed when the run ends normally (every case finished or failed, or the deadline passed).

A time limit needs a process to kill: in this process (no cluster) a hanging case hangs the
campaign, as before.
"""

from __future__ import annotations

import json
import logging
import math
import os
import sys
import time
import warnings
from collections import deque
from collections.abc import Callable, Sequence
from pathlib import Path

from wbc.errors import InvalidValueError, UnknownNameError, WbcError

from ..machine import describe_machine
from ..progress import report_progress

TIME_LIMIT_S = 600.0  # default time limit of one case on a cluster [s]
MAX_BATCH = 32  # cases per batch at most
BATCHES_PER_THREAD = 4  # batches per worker thread: load balance against per-batch overhead
PARTIAL_EVERY_S = 2.0  # the partial file is rewritten at most this often [s]
PROGRESS_EVERY_S = 2.0  # a progress line at most this often [s] (none for a shorter run)
ALLOWED_FAILURES = 1  # on a local cluster: a batch whose worker dies is re-run once whole,
#                       then case by case (a remote cluster keeps its own setting, default 3)
INSTALL_HINT = 'pip install ".[cluster]"'


class Finished:
    """What :func:`run_cases` returns.

    Attributes:
        results: per case (in case order) the ``work`` result, or ``None`` when the case did
            not finish (it failed, or the deadline passed before it ran).
        failures: the cases that raised, hung or killed their workers, in case order: dicts
            with ``"index"``, ``"key"``, ``"seed"``, ``"failure"`` (``"raised"``, ``"hang"``,
            ``"killed_worker"``), ``"message"`` and ``"attempts"``.
        attempts: ``key -> attempts`` of the cases run more than once (a worker died, a batch
            was split).
        cluster: ``{"workers", "scheduler", "machine", "batch_cases", "attempts"}`` — the
            worker processes (``None`` in this process), the scheduler's address, the distinct
            machines the cases ran on (each with its workers' addresses), the cases per batch.
    """

    def __init__(self, results: list, failures: list[dict], attempts: dict[str, int],
                 cluster: dict):
        self.results, self.failures, self.attempts, self.cluster = (results, failures,
                                                                    attempts, cluster)


def batch_size(cases: int, threads: int) -> int:
    """Cases per batch: about :data:`BATCHES_PER_THREAD` batches per worker thread (so a slow
    batch does not leave the others idle at the end), at most :data:`MAX_BATCH`."""
    return max(1, min(MAX_BATCH, math.ceil(cases / max(1, threads * BATCHES_PER_THREAD))))


def run_cases(work: Callable, cases: Sequence[dict], context, *, name: str,
              out: Path | None = None, identity: dict | None = None,
              workers: int | None = None, scheduler: str | None = None,
              time_limit: float = TIME_LIMIT_S, deadline: float | None = None,
              progress: bool = True, batch_cases: int | None = None) -> Finished:
    """Run ``work(context, case, deadline)`` on every case; see the module docstring.

    Args:
        work: a module-level function (the workers import it by name) returning a JSON-ready
            result; it stops early, marking its result, when ``time.time()`` passes
            ``deadline`` (epoch seconds, or ``None``).
        cases: JSON-ready dicts, each with a unique ``"key"`` and a ``"seed"``.
        context: what every case needs besides itself (sent to each worker once per batch).
        name: the campaign's name: the partial file is ``out/NAME.partial.json``.
        out: the output folder (``None``: no partial file).
        identity: JSON-ready description of the campaign: a partial file resumes only the
            campaign of the same identity (and the same keys).
        workers: a local cluster of this many processes; ``scheduler``: an existing cluster's
            address (at most one of the two).
        time_limit: the time limit of one case on a cluster [s] (> 0).
        progress: print a progress line on stderr (at most every :data:`PROGRESS_EVERY_S` s).
        batch_cases: cases per batch on a cluster (default :func:`batch_size`).

    Raises:
        InvalidValueError: both ``workers`` and ``scheduler``, ``workers < 1``, a bad time limit
            or batch size, or duplicate keys.
        WbcError: dask's ``distributed`` is not installed, the cluster cannot be reached, or the
            workers cannot run the campaign (an exception outside every case).
    """
    if workers is not None and scheduler is not None:
        raise InvalidValueError("give --workers or --scheduler, not both")
    if workers is not None and (isinstance(workers, bool) or int(workers) != workers
                                or workers < 1):
        raise InvalidValueError(f"workers must be an integer >= 1, got {workers!r}")
    if not (isinstance(time_limit, (int, float)) and math.isfinite(time_limit)
            and time_limit > 0):
        raise InvalidValueError(f"time limit must be a number > 0 [s], got {time_limit!r}")
    if batch_cases is not None and (isinstance(batch_cases, bool) or int(batch_cases)
                                    != batch_cases or batch_cases < 1):
        raise InvalidValueError(f"batch_cases must be an integer >= 1, got {batch_cases!r}")
    keys = [case["key"] for case in cases]
    if len(set(keys)) != len(keys):
        raise InvalidValueError(f"{name}: case keys must be unique")
    state = _State(name, list(cases), out, identity, progress)
    try:  # the partial file is written however the run stops (Ctrl-C, a lost scheduler)
        if workers is None and scheduler is None:
            state.cluster = {"workers": None, "scheduler": None,
                             "machine": [{"workers": ["in-process"], **describe_machine()}],
                             "batch_cases": 1}
            _run_here(work, context, state, deadline)
        else:
            _run_on_dask(work, context, state, deadline, workers, scheduler, time_limit,
                         batch_cases)
    finally:
        state.save(force=True)
    state.finish()
    return state.finished()


# ---------------------------------------------------------------------------------------------
# what a worker runs


def run_batch(work: Callable, context, batch: list[tuple[int, dict]],
              deadline: float | None) -> list[tuple[int, str, object]]:
    """Run the cases of ``batch`` (``(index, case)`` pairs): ``(index, "done", result)`` or
    ``(index, "raised", message)`` per case run — none after the deadline."""
    rows: list[tuple[int, str, object]] = []
    for index, case in batch:
        if deadline is not None and time.time() > deadline:
            break
        try:
            # through JSON: a result is the same whether it was computed here, on a worker or
            # read back from a partial file
            rows.append((index, "done", json.loads(json.dumps(work(context, case, deadline),
                                                              default=_plain))))
        except Exception as exc:  # a case's own failure: recorded, the campaign goes on
            rows.append((index, "raised", f"{type(exc).__name__}: {exc}"[:500]))
    return rows


def _plain(value):
    tolist = getattr(value, "tolist", None)  # numpy arrays and scalars
    return tolist() if callable(tolist) else str(value)


# ---------------------------------------------------------------------------------------------
# bookkeeping: results in case order, the partial file, the progress line


class _State:
    """A run's results in case order, its failures and attempts, its partial file and its
    progress line."""

    def __init__(self, name: str, cases: list[dict], out: Path | None, identity: dict | None,
                 progress: bool) -> None:
        self.name, self.cases, self.progress = name, cases, progress
        self.index = {case["key"]: i for i, case in enumerate(cases)}
        self.results: list = [None] * len(cases)
        self.failures: dict[int, dict] = {}
        self.attempts: dict[int, int] = {}
        self.cluster: dict = {}
        self.identity = {"name": name, "identity": identity, "keys": list(self.index)}
        self.path: Path | None = None if out is None else Path(out) / f"{name}.partial.json"
        self.saved_at = time.monotonic()
        self.dirty = False
        self.started = time.monotonic()
        self.shown = 0.0
        self._resume()

    def _resume(self) -> None:
        """Take the finished cases of a partial file of the same campaign."""
        if self.path is None or not self.path.is_file():
            return
        try:
            data = json.loads(self.path.read_text())
        except (OSError, ValueError):
            data = None
        if not isinstance(data, dict) or data.get("campaign") != self.identity:
            print(f"wbc {self.name}: {self.path} is of another campaign: starting over",
                  file=sys.stderr)
            return
        for key, result in data.get("results", {}).items():
            self.results[self.index[key]] = result
        for failure in data.get("failures", []):
            self.failures[self.index[failure["key"]]] = failure
        for key, n in data.get("attempts", {}).items():
            self.attempts[self.index[key]] = int(n)
        done = sum(r is not None for r in self.results) + len(self.failures)
        print(f"wbc {self.name}: resuming from {self.path} ({done} of {len(self.cases)} cases "
              "finished)", file=sys.stderr)

    def pending(self) -> list[tuple[int, dict]]:
        return [(i, case) for i, case in enumerate(self.cases)
                if self.results[i] is None and i not in self.failures]

    def record(self, rows, attempts: int = 1) -> bool:
        """Store a batch's rows; ``False`` when a case stopped at the deadline."""
        going = True
        for index, kind, value in rows:
            self.attempts[index] = self.attempts.get(index, 0) + attempts
            if kind == "done":
                self.results[index] = value
                going = going and not (isinstance(value, dict) and value.get("stopped"))
            else:
                self.fail(index, kind, value, add_attempt=False)
        self.dirty = True
        self.save()
        self.show(rows[-1][0] if rows else None)
        return going

    def fail(self, index: int, kind: str, message: str, add_attempt: bool = True) -> None:
        if add_attempt:
            self.attempts[index] = self.attempts.get(index, 0) + 1
        case = self.cases[index]
        self.failures[index] = {"index": index, "key": case["key"], "seed": case["seed"],
                                "failure": kind, "message": message,
                                "attempts": self.attempts.get(index, 1)}
        self.dirty = True

    def retried(self, index: int, attempts: int) -> None:
        self.attempts[index] = self.attempts.get(index, 0) + attempts

    def save(self, force: bool = False) -> None:
        if self.path is None or not self.dirty:
            return
        if not force and time.monotonic() - self.saved_at < PARTIAL_EVERY_S:
            return
        data = {"campaign": self.identity,
                # a case cut short by the deadline is not finished: a rerun runs it whole
                "results": {self.cases[i]["key"]: r for i, r in enumerate(self.results)
                            if r is not None and not (isinstance(r, dict) and r.get("stopped"))},
                "failures": [self.failures[i] for i in sorted(self.failures)],
                "attempts": {self.cases[i]["key"]: n for i, n in self.attempts.items()}}
        self.path.parent.mkdir(parents=True, exist_ok=True)
        scratch = self.path.with_name(self.path.name + ".tmp")
        scratch.write_text(json.dumps(data))
        os.replace(scratch, self.path)  # atomic: an interrupted write leaves the old file
        self.saved_at, self.dirty = time.monotonic(), False

    def show(self, last: int | None, final: bool = False) -> None:
        now = time.monotonic()
        if not self.progress or (not final and now - self.shown < PROGRESS_EVERY_S):
            return
        if not final and self.shown == 0.0 and now - self.started < PROGRESS_EVERY_S:
            return  # a short campaign prints nothing
        if final and self.shown == 0.0:
            return
        self.shown = now
        done = sum(r is not None for r in self.results) + len(self.failures)
        what = self.cases[last]["key"] if last is not None else "done"
        report_progress(done, len(self.cases), f"{self.name}: {what}")

    def finish(self) -> None:
        """The run ended without an exception (complete, or its deadline passed): its result
        is the campaign's, the partial file goes."""
        self.show(None, final=True)
        if self.path is not None and self.path.exists():
            self.path.unlink()

    def finished(self) -> Finished:
        keys = [case["key"] for case in self.cases]
        return Finished(self.results, [self.failures[i] for i in sorted(self.failures)],
                        {keys[i]: n for i, n in sorted(self.attempts.items()) if n > 1},
                        {**self.cluster, "attempts": {keys[i]: n for i, n in
                                                      sorted(self.attempts.items()) if n > 1}})


# ---------------------------------------------------------------------------------------------
# in this process


def _run_here(work, context, state: _State, deadline) -> None:
    for index, case in state.pending():
        if deadline is not None and time.time() > deadline:
            break
        if not state.record(run_batch(work, context, [(index, case)], deadline)):
            break


# ---------------------------------------------------------------------------------------------
# on Dask


def _distributed():
    try:
        import distributed
    except ImportError:
        raise WbcError(f"--workers and --scheduler run on Dask: install its distributed package "
                       f"({INSTALL_HINT})") from None
    return distributed


def _connect(workers, scheduler):
    """``(client, cluster or None)``."""
    distributed = _distributed()
    import dask

    if scheduler is not None:
        try:
            client = distributed.Client(scheduler, timeout=30)
        except (OSError, TimeoutError) as err:
            raise WbcError(f"--scheduler {scheduler}: cannot connect: {err}") from None
        return client, None
    # one task per worker thread at a time (the scheduler otherwise sends a thread a second
    # task to queue, whose time limit would then run while it waits)
    with dask.config.set({"distributed.scheduler.worker-saturation": 1.0,
                          "distributed.scheduler.allowed-failures": ALLOWED_FAILURES}), \
            warnings.catch_warnings():
        # no dashboard; the scheduler's own HTTP routes take another port if 8787 is taken
        warnings.filterwarnings("ignore", message="Port .* is already in use")
        # each worker (and each restarted one) imports the campaigns before its first case,
        # so that a case's time limit does not count the import
        cluster = distributed.LocalCluster(n_workers=int(workers), processes=True,
                                           threads_per_worker=1, host="127.0.0.1",
                                           dashboard_address=None,
                                           silence_logs=logging.CRITICAL,
                                           preload=[__name__])
        client = distributed.Client(cluster)
    return client, cluster


def _suspicious(dask_scheduler, keys):
    """On the scheduler: how many workers died running each task."""
    return {key: getattr(dask_scheduler.tasks.get(key), "suspicious", 0) for key in keys}


def _machines(client) -> list[dict]:
    """The distinct machines of the workers, each with its workers' addresses."""
    described = client.run(describe_machine)
    machines: list[dict] = []
    for address, machine in sorted(described.items()):
        for entry in machines:
            if {k: v for k, v in entry.items() if k != "workers"} == machine:
                entry["workers"].append(address)
                break
        else:
            machines.append({"workers": [address], **machine})
    return machines


def _run_on_dask(work, context, state: _State, deadline, workers, scheduler,
                 time_limit, batch_cases) -> None:
    distributed = _distributed()
    client, cluster = _connect(workers, scheduler)
    try:
        if workers is not None:
            client.wait_for_workers(int(workers), timeout=120)
        else:
            client.wait_for_workers(1, timeout=60)
        threads = sum(client.nthreads().values())
        state.cluster = {"workers": len(client.nthreads()), "scheduler": scheduler,
                         "machine": _machines(client)}
        pending = state.pending()
        size = batch_cases or batch_size(len(pending), threads)
        state.cluster["batch_cases"] = size
        queue = deque(pending[i:i + size] for i in range(0, len(pending), size))
        running: dict = {}  # future -> (batch, time limit's end [monotonic s])
        going = True
        while running or (queue and going):
            while going and queue and len(running) < threads:
                batch = queue.popleft()
                future = client.submit(run_batch, work, context, batch, deadline, pure=False)
                running[future] = (batch, time.monotonic() + time_limit * len(batch))
            wait = min(end for _, end in running.values()) - time.monotonic()
            try:
                distributed.wait(list(running), timeout=min(max(0.05, wait), 5.0),
                                 return_when="FIRST_COMPLETED")
            except TimeoutError:
                pass
            finished = [f for f in running if f.done()]
            died = _died(client, finished)
            for future in finished:
                batch, _ = running.pop(future)
                deaths = died.get(future.key, 0)
                if future.status == "finished":
                    going = state.record(future.result(), 1 + deaths) and going
                    continue
                if future.status == "cancelled":  # not by us: the scheduler was lost
                    raise WbcError(f"the Dask cluster dropped a batch (scheduler lost?); the "
                                   f"finished cases are kept: rerun the same command to "
                                   f"complete the {state.name} campaign")
                error = future.exception()
                if type(error).__name__ == "KilledWorker":
                    _retry(state, queue, batch, "killed_worker",
                           f"its worker died {max(deaths, 1)} times running it",
                           max(deaths, 1))
                else:  # not a case's failure (run_batch catches those): the workers' own
                    raise WbcError(f"the workers cannot run the {state.name} campaign: "
                                   f"{type(error).__name__}: {error}")
            going = going and (deadline is None or time.time() < deadline)
            now = time.monotonic()
            for future in [f for f, (_, end) in running.items() if end <= now and
                           not f.done()]:
                batch, _ = running.pop(future)
                _stop(client, future)
                _retry(state, queue, batch, "hang",
                       f"not finished within its time limit of {time_limit:g} s", 1)
            state.save()
    finally:
        client.close()
        if cluster is not None:
            cluster.close()


def _died(client, futures) -> dict:
    """``key -> workers that died running it`` of finished futures (0 when the scheduler does
    not say)."""
    if not futures:
        return {}
    try:
        return client.run_on_scheduler(_suspicious, keys=[f.key for f in futures])
    except Exception:  # a scheduler that runs no client code: attempts unknown, counted once
        return {}


def _stop(client, future) -> None:
    """Cancel a running batch and end the process of the worker running it (a thread cannot
    be stopped): its nanny starts a new one, as for a worker that died."""
    on = [w for w, keys in client.processing().items() if future.key in keys]
    client.cancel(future)
    for worker in on:
        try:
            client.run(_exit_process, workers=[worker], on_error="ignore")
        except Exception:  # the worker died before it answered: what was asked
            pass


def _exit_process() -> None:
    """On a worker (its event loop, not the hung thread): end the process at once."""
    os._exit(1)


def _retry(state: _State, queue: deque, batch: list, kind: str, message: str,
           attempts: int) -> None:
    """A batch that killed its workers or hung: each of its cases again on its own (first in
    the queue); a single case is a failure."""
    if len(batch) == 1:
        index = batch[0][0]
        state.retried(index, attempts - 1)
        state.fail(index, kind, message)
        return
    for index, _ in batch:
        state.retried(index, attempts)
    queue.extendleft([[item] for item in reversed(batch)])


def reproduction(command: str, options: dict, key: str) -> str:
    """A one-line shell command rerunning the case ``key`` in one process: ``command`` (e.g.
    ``"wbc fuzz"``) with ``options`` (``--name value``; ``None`` values left out, lists
    repeated) and ``--case KEY``."""
    import shlex

    parts = [command]
    for option, value in options.items():
        for item in value if isinstance(value, (list, tuple)) else [value]:
            if item is not None:
                parts += [option, shlex.quote(str(item))]
    return " ".join(parts + ["--case", shlex.quote(key)])


# ---------------------------------------------------------------------------------------------
# a campaign's inputs on the workers

_CACHE: dict = {}  # per process: what the current campaign built once (its token's)


def run_campaign(work: Callable, cases: list[dict], *, name: str, robots, build,
                 identity: dict, only: str | None, keys_hint: str, out: Path | None,
                 workers: int | None, scheduler: str | None, time_limit: float,
                 seconds: float | None, progress: bool) -> tuple[list[dict], Finished]:
    """What ``wbc fuzz`` and ``wbc audit`` share around :func:`run_cases`: keep the one case
    ``only`` names (``--case``; an unknown key raises :class:`~wbc.UnknownNameError` showing
    ``keys_hint``), stop starting cases after ``seconds`` [s], build the :func:`context`, and run;
    a case rerun alone leaves the campaign's partial file alone. Returns the cases run and
    their :class:`Finished`."""
    if only is not None:
        cases = [case for case in cases if case["key"] == only]
        if not cases:
            raise UnknownNameError(f"no case {only!r} in this {name} campaign (keys look like "
                                   f"{keys_hint})")
    deadline = None if seconds is None else time.time() + seconds
    shared = context(robots, build, identity,
                     on_cluster=workers is not None or scheduler is not None)
    finished = run_cases(work, cases, shared, name=name, out=None if only else out,
                         identity=identity, workers=workers, scheduler=scheduler,
                         time_limit=time_limit, deadline=deadline, progress=progress)
    return cases, finished


def context(robots, build, identity: dict, on_cluster: bool) -> dict:
    """What every case of ``wbc fuzz`` / ``wbc audit`` needs besides itself: the robots
    (``(name, load)`` pairs) and the user's stack ``build`` (or ``None``). On a cluster the
    user's stack travels as its ``module:function`` (imported on the worker from this working
    directory), not as the function, whose module the worker could not import by name."""
    token = f"{json.dumps(identity, sort_keys=True, default=str)}/{os.getpid()}/{time.time()}"
    spec = getattr(build, "spec", None)
    if on_cluster and spec is not None:
        if spec.rpartition(":")[0].endswith(".py"):  # a file: by its absolute path
            path, _, function = spec.rpartition(":")
            spec = f"{os.path.abspath(path)}:{function}"
        return {"token": token, "robots": robots, "build": None, "stack": (spec, os.getcwd())}
    return {"token": token, "robots": robots, "build": build, "stack": None}


def cached(context: dict, what: str, make: Callable):
    """``make()`` once per process and campaign (``context["token"]``)."""
    if _CACHE.get("token") != context["token"]:
        _CACHE.clear()
        _CACHE["token"] = context["token"]
    if what not in _CACHE:
        _CACHE[what] = make()
    return _CACHE[what]


def user_inputs(context: dict):
    """``(robots, build)`` of a :func:`context` (the user's stack imported once per
    process)."""
    if context["stack"] is None:
        return context["robots"], context["build"]

    def load():
        from wbc.experiments.benchmarks.user_inputs import load_stack

        spec, cwd = context["stack"]
        sys.path.insert(0, cwd)  # the driver's working directory, where the module is
        try:
            return load_stack(spec)
        finally:
            sys.path.remove(cwd)

    return context["robots"], cached(context, "build", load)
