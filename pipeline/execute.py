"""Running trials on this machine: the local pool that spreads them (one trial in a worker:
pipeline.worker).

The pool takes plain-data trials, runs them longest first and yields each result as soon as
it is there, so the driver can write it to the cache at once: an interrupted run loses only the
trials in flight. Short trials travel to a worker in batches (batches), long ones alone. Locally it is a `concurrent.futures.ProcessPoolExecutor` of spawned workers with
one BLAS/OpenMP/numba thread each. Ctrl-C, SIGTERM and SIGHUP reach the driver only (workers
ignore them, pipeline.worker.quiet_worker), which kills every worker at once (stop_pools), so
neither a worker nor multiprocessing's resource tracker outlives it; a worker whose driver died
(kill -9) is killed by the kernel (PR_SET_PDEATHSIG). It is engine=local's run
(pipeline.engines.local); the cluster engines are the other modules of pipeline.engines.
"""
from __future__ import annotations

import multiprocessing
import os
import sys
import types
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from contextlib import contextmanager

from .worker import (THREAD_VARS, quiet_worker, run_batch, run_one,  # noqa: F401
                     single_threaded_children)

_POOLS: set = set()  # the pools of this process that are running


def stop_pools() -> None:
    """Kill the workers of every running pool of this process and wait for them: what a stage
    does when it is stopped (pipeline.cli.finish), wherever the signal found the driver."""
    for pool in list(_POOLS):
        _stop(pool)


def _stop(pool) -> None:
    for proc in list((getattr(pool, "_processes", None) or {}).values()):
        proc.kill()  # workers ignore SIGTERM (quiet_worker): SIGKILL, they hold no files
    pool.shutdown(wait=True, cancel_futures=True)
    _POOLS.discard(pool)


def cpus() -> int:
    """The CPUs this process may run on (its affinity mask: a cluster job's share)."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not Linux
        return os.cpu_count() or 1


def capped(workers: int, trials: int) -> int:
    """Local workers: at most one per trial and one per CPU (more would only share the CPUs and
    cost each worker's memory); a note says so when the CPUs cap what was asked."""
    n = max(1, min(workers, trials))
    if n > cpus():
        print(f"note: workers={workers}: this machine has {cpus()} CPUs; running {cpus()} "
              "workers", file=sys.stderr)
        n = cpus()
    return n


def in_launcher_worker() -> bool:
    """True in a process that a launcher's pool started (joblib's loky workers under
    `hydra/launcher=joblib`): the launcher runs the jobs in parallel already, and such a worker
    cannot start a pool of its own (its start method, `loky`, is unknown to its children), so its
    trials run one after the other in it."""
    return multiprocessing.parent_process() is not None or \
        multiprocessing.get_start_method(allow_none=True) not in (None, "spawn", "fork", "forkserver")


def pooled(trials: int, workers: int) -> bool:
    """Whether local() runs `trials` trials on a pool of worker processes (else in this one)."""
    return min(workers, trials, cpus()) > 1 and not in_launcher_worker()


def local(todo: list[dict], workers: int, fn=run_one):
    """Yield (trial, fn(trial)) as trials finish, on `workers` spawned processes (at most one per
    CPU; in this process when one worker suffices). `todo` is run in its order (longest first).
    With fn=run_one, every kernel the trials need is loaded (or compiled) first, by warm_up's
    tiny trials: on a pool in its first worker, before the others start (they then load them
    from numba's cache, and the driver, which only writes results, loads none); in this process
    here (a trial's measured CPU time then holds no compile)."""
    workers = capped(workers, len(todo))
    if not pooled(len(todo), workers):
        if fn is run_one:
            warm_up(todo)
        for t in todo:
            yield t, fn(t)
        return
    pool = ProcessPoolExecutor(workers, mp_context=multiprocessing.get_context("spawn"),
                               initializer=quiet_worker, initargs=(os.getpid(),))
    _POOLS.add(pool)
    try:
        if fn is run_one:  # one worker is started for it; the others when the batches come
            with _starting_workers(fn):
                warm = pool.submit(run_batch, fn, warm_trials(todo))
            warm.result()
        with _starting_workers(fn):
            pending = {pool.submit(run_batch, fn, b): b for b in batches(todo, workers)}
        while pending:
            done, _ = wait(pending, return_when=FIRST_COMPLETED)
            for fut in done:
                yield from zip(pending.pop(fut), fut.result())
    finally:
        # idle workers after the last result; on a signal, an error or a dropped generator: now
        _stop(pool)


@contextmanager
def _starting_workers(fn):
    """Around the submits, where the pool starts its spawned workers (not where it is made):
    each worker inherits one BLAS/OpenMP/numba thread (single_threaded_children; two workers
    with a BLAS thread per CPU each would share two CPUs four ways) and a bare __main__
    (_no_main_module)."""
    with single_threaded_children(), _no_main_module(fn):
        yield


@contextmanager
def _no_main_module(fn):
    """A spawned worker imports the driver's __main__ module before it runs anything
    (multiprocessing's preparation): for `python -m pipeline.simulate` the whole stage, Hydra,
    OmegaConf and the config (about 0.3 s of CPU per worker more than what a trial imports),
    none of which a worker uses. Within this block workers are started with a bare __main__
    instead, unless `fn` itself lives in __main__ (a script's own function, which a worker
    finds there)."""
    main = sys.modules.get("__main__")
    if main is None or getattr(fn, "__module__", None) == "__main__":
        yield
        return
    sys.modules["__main__"] = types.ModuleType("__main__")
    try:
        yield
    finally:
        sys.modules["__main__"] = main


BATCH_SHARE = 16  # a batch holds at most 1/BATCH_SHARE of one worker's share of the work
MAX_BATCH = 64  # trials


def batches(todo: list[dict], workers: int) -> list[list[dict]]:
    """`todo` in order, cut into batches that one worker task runs: consecutive trials while
    their estimated cost (pipeline.plan.cost) stays within 1/BATCH_SHARE of a worker's share,
    at most MAX_BATCH. Short trials then share one task's pickling and round trip; a long trial
    is a batch of its own, so the workers stay balanced and a stopped run loses little."""
    costs = _costs(todo)
    limit = sum(costs) / (workers * BATCH_SHARE)
    out, batch, total = [], [], 0.0
    for t, c in zip(todo, costs):
        if batch and (total + c > limit or len(batch) == MAX_BATCH):
            out.append(batch)
            batch, total = [], 0.0
        batch.append(t)
        total += c
    return out + [batch] if batch else out


def costs_of(trials: list[dict]) -> dict:
    """Trial key -> pipeline.plan.cost of each trial (_costs)."""
    return dict(zip((t["key"] for t in trials), _costs(trials)))


def _costs(trials: list[dict]) -> list[float]:
    """pipeline.plan.cost of each trial, computed once per spec object and start (cost hashes
    the whole spec, about 60 us; the trials of a condition share their spec)."""
    from .plan import cost

    out, seen = [], {}
    for t in trials:
        start = t.get("start")
        what = (id(t["spec"]), None if start is None else start.get("epoch"))
        c = seen.get(what)
        if c is None:
            c = seen[what] = cost(t)
        out.append(c)
    return out


def warm_up(trials: list[dict]) -> None:
    """Compile (or load from numba's cache) each learner's kernels once, in this process, before
    fanning out: a tiny trial per distinct body and learner (warm_trials)."""
    for t in warm_trials(trials):
        run_one(t)


def warm_trials(trials: list[dict]) -> list[dict]:
    """A tiny trial (two epochs, no growth, no snapshot) per distinct body and learner of
    `trials`: running them loads every kernel the trials need. Their results are not kept."""
    seen, out = set(), []
    for t in trials:
        spec = t["spec"]
        what = (spec["body"]["name"], spec["learner"]["name"], spec["learner"].get("fast"))
        if what in seen:
            continue
        seen.add(what)
        tiny = dict(spec, epochs=2, snapshots=[], growth=dict(spec["growth"], period=0))
        out.append({**{k: t[k] for k in ("key", "seed", "code") if k in t}, "spec": tiny})
    return out
