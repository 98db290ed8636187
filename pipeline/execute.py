"""engine=local's pool: worker processes (one thread each) that run trials longest first, short
ones in batches, and yield each result as it comes. Each worker is a fork of one fork server that
loaded numpy, numba and the kernels once (pipeline/preload.py; spawned off Linux). Signals reach
the driver only, which kills every worker at once (stop_pools); a worker whose driver died is
killed by the kernel (as is the fork server: pipeline/preload.py).
"""
from __future__ import annotations

import multiprocessing
import multiprocessing.forkserver
import os
import signal
import sys
import types
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from contextlib import contextmanager, nullcontext, suppress
from pathlib import Path

from . import stop
from .engines import THREAD_VARS  # noqa: F401 (execute.THREAD_VARS)
from .worker import DRIVER, quiet_worker, run_batch, run_one

_POOLS: set = set()  # the pools of this process that are running


def stop_pools() -> None:
    """Kill the workers of every running pool of this process (a stopped stage: cli.finish)."""
    for pool in list(_POOLS):
        _stop(pool)


def _stop(pool) -> None:
    for proc in list((getattr(pool, "_processes", None) or {}).values()):
        proc.kill()  # workers ignore SIGTERM (quiet_worker): SIGKILL, they hold no files
    pool.shutdown(wait=True, cancel_futures=True)
    _POOLS.discard(pool)
    if not _POOLS:  # the fork server, after its forks (reaped by it): killed, as it may still
        # be loading the kernels, and waited for, its CPU and theirs counted here (CPython's)
        server = multiprocessing.forkserver._forkserver
        with suppress(ProcessLookupError, TypeError):
            os.kill(getattr(server, "_forkserver_pid", None), signal.SIGKILL)
        if hasattr(server, "_stop"):
            server._stop()


def cpus() -> int:
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not Linux
        return os.cpu_count() or 1


def capped(workers: int, trials: int) -> int:
    """Local workers: at most one per trial and one per CPU (a note when the CPUs cap them)."""
    n = max(1, min(workers, trials))
    if n > cpus():
        print(f"note: workers={workers}: this machine has {cpus()} CPUs; running {cpus()} "
              "workers", file=sys.stderr)
        n = cpus()
    return n


def in_launcher_worker() -> bool:
    """True in a process a launcher's pool started (joblib's loky under hydra/launcher=joblib):
    it cannot start a pool of its own, so its trials run in it one after the other."""
    return multiprocessing.parent_process() is not None or \
        multiprocessing.get_start_method(allow_none=True) not in (None, "spawn", "fork", "forkserver")


def pooled(trials: int, workers: int) -> bool:
    return min(workers, trials, cpus()) > 1 and not in_launcher_worker()


def local(todo: list[dict], workers: int, fn=run_one):
    """Yield (trial, fn(trial)) as trials finish, on `workers` processes (context()) or this
    one, in the order of `todo`. With fn=run_one the trials' kernels are loaded first
    (warm_trials: those the fork server has not) in the pool's first worker before the others
    start, or here."""
    workers = capped(workers, len(todo))
    if not pooled(len(todo), workers):
        if fn is run_one:
            warm_up(todo)
        for t in todo:
            yield t, fn(t)
        return
    from .fingerprint import known  # handed to the workers: theirs without a parse

    ctx = context()
    pool = ProcessPoolExecutor(workers, mp_context=ctx, initializer=quiet_worker,
                               initargs=(known(),))
    _POOLS.add(pool)
    try:
        if ctx.get_start_method() == "forkserver":  # up and warm before the held submits: a
            with _starting_workers(fn, held=False):  # signal meanwhile stops at once
                with stop.blocked():  # (the server starts with them blocked: preload.py)
                    multiprocessing.forkserver.ensure_running()
                noop = ctx.Process(target=int)
                noop.start()
            noop.join()
        if fn is run_one:
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
        _stop(pool)  # after the last result; on a signal, an error or a dropped generator


def context():
    """The pool's start method: forkserver, each worker forked from a server that imported
    pipeline.preload (about 0.5 s CPU a worker saved: imports, numba's registries, the kernels'
    load), on Linux, else spawn. The server starts with a pool, in _starting_workers (one thread
    each; it imports this checkout's pipeline and knows the driver), and stops with it (_stop)."""
    if sys.platform != "linux":  # (macOS has a fork server, but no parent-death signal)
        return multiprocessing.get_context("spawn")
    ctx = multiprocessing.get_context("forkserver")
    ctx.set_forkserver_preload(["pipeline.preload"])  # (no effect once the server runs)
    return ctx


@contextmanager
def single_threaded_children(more: dict | None = None):
    """Children inherit the environment: one BLAS/OpenMP/numba thread each, and `more` (restored
    after; not unittest.mock's patch.dict, whose import costs a stage 17 ms)."""
    more = dict(dict.fromkeys(THREAD_VARS, "1"), **(more or {}))
    saved = {k: os.environ.get(k) for k in more}
    os.environ.update(more)
    try:
        yield
    finally:
        for k, v in saved.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v


@contextmanager
def _starting_workers(fn, held: bool = True):
    """Around the submits, where the pool starts workers: one thread each, a bare __main__
    (not the stage, Hydra and the config: 0.3 s CPU each) unless `fn` lives in __main__, and a
    signal taken after them (stop.held: a worker started then would be unknown to the pool)."""
    main = sys.modules.get("__main__")
    bare = main is not None and getattr(fn, "__module__", None) != "__main__"
    root = str(Path(__file__).resolve().parents[1])  # this checkout's, for a fork server
    env = {DRIVER: str(os.getpid()),
           "PYTHONPATH": os.pathsep.join(filter(None, [root, os.environ.get("PYTHONPATH")]))}
    with stop.held() if held else nullcontext(), single_threaded_children(env):
        if bare:
            sys.modules["__main__"] = types.ModuleType("__main__")
        try:
            yield
        finally:
            if bare:
                sys.modules["__main__"] = main


BATCH_SHARE = 16  # a batch holds at most 1/BATCH_SHARE of one worker's share of the work
MAX_BATCH = 64  # trials


def batches(todo: list[dict], workers: int) -> list[list[dict]]:
    """`todo` in order, cut into worker tasks: consecutive trials while their cost stays within
    1/BATCH_SHARE of a worker's share, at most MAX_BATCH (a long trial alone)."""
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
    return dict(zip((t["key"] for t in trials), _costs(trials)))


def _costs(trials: list[dict]) -> list[float]:
    """pipeline.plan.cost of each trial, once per spec object and start."""
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
    """Load (or compile) the trials' kernels in this process (warm_trials)."""
    for t in warm_trials(trials):
        run_one(t)


def warm_trials(trials: list[dict]) -> list[dict]:
    """A tiny trial (two epochs, no growth) per distinct body and learner: its kernels."""
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
