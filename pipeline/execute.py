"""Running trials: one trial in a worker (`run_one`), and the executor that spreads them.

The executor takes plain-data trials, runs them longest first and yields each result as soon as
it is there, so the driver can write it to the cache at once: an interrupted run loses only the
trials in flight. Locally it is a `concurrent.futures.ProcessPoolExecutor` of spawned workers with
one BLAS/OpenMP/numba thread each; Ctrl-C stops every worker at once. Cluster backends plug in
here (`backends`).
"""
from __future__ import annotations

import multiprocessing
import os
import signal
import time
import traceback
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from contextlib import contextmanager

import numpy as np

import gbmodel

THREAD_VARS = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS",
               "NUMBA_NUM_THREADS", "VECLIB_MAXIMUM_THREADS")


def run_one(trial: dict) -> dict:
    """Run one trial: plain data in, plain data out, errors returned as text.

    status: ok (a learning curve), diverged (the error became non-finite: a result, with the
    epoch), or failed (an exception; not cached, so the next run tries again)."""
    start = time.perf_counter()
    try:
        from .plan import code_fingerprint

        mine = code_fingerprint(trial["spec"]["learner"]["name"])
        if trial.get("code", mine) != mine:  # code changed since the plan, or another node's
            raise RuntimeError(f"this process's gbmodel code has fingerprint {mine}, the trial's "
                               f"key names {trial['code']}: the code changed since the plan "
                               "(or differs on this node); run the command again")
        spec = gbmodel.TrialSpec.from_dict(trial["spec"])
        seed = np.random.SeedSequence(trial["seed"]["entropy"],
                                      spawn_key=tuple(trial["seed"]["spawn_key"]))
        res = gbmodel.run_trial(spec, np.random.default_rng(seed))
        out = dict(status="ok", epoch=res.epoch, samples=res.epoch * res.samples_per_epoch,
                   size=res.size, abs_error=res.abs_error, rel_error=res.rel_error, M=res.M,
                   snapshots=res.snapshots, largest_jump=res.largest_jump)
    except gbmodel.Diverged as err:
        out = dict(status="diverged", error=str(err), epoch=err.epoch)
    except Exception as err:  # recorded and reported; the other trials go on
        out = dict(status="failed", error=f"{type(err).__name__}: {err}",
                   traceback=traceback.format_exc())
    out["key"], out["seconds"] = trial["key"], time.perf_counter() - start
    return out


@contextmanager
def single_threaded_children():
    """Children inherit the environment: one BLAS/OpenMP/numba thread each."""
    old = {k: os.environ.get(k) for k in THREAD_VARS}
    os.environ.update({k: "1" for k in THREAD_VARS})
    try:
        yield
    finally:
        for k, v in old.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v


def _ignore_sigint():
    """Workers leave Ctrl-C to the parent, which stops them all at once."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)


def local(todo: list[dict], workers: int, fn=run_one):
    """Yield (trial, fn(trial)) as trials finish, on `workers` spawned processes (in this
    process when one worker suffices). `todo` is run in its order (longest first)."""
    if workers == 1 or len(todo) <= 1:
        for t in todo:
            yield t, fn(t)
        return
    with single_threaded_children():
        pool = ProcessPoolExecutor(min(workers, len(todo)),
                                   mp_context=multiprocessing.get_context("spawn"),
                                   initializer=_ignore_sigint)
    try:
        pending = {pool.submit(fn, t): t for t in todo}
        while pending:
            done, _ = wait(pending, return_when=FIRST_COMPLETED)
            for fut in done:
                yield pending.pop(fut), fut.result()
    finally:
        # idle workers after the last result; on Ctrl-C, an error or a dropped generator: now
        for proc in list(getattr(pool, "_processes", {}).values()):
            proc.terminate()
        pool.shutdown(wait=True, cancel_futures=True)


def results(todo: list[dict], workers: int, backend: str = "local", address=None, fn=run_one,
            options=None, logs=None):
    """Yield (trial, result) for every trial of `todo` on the chosen backend: `local`, or a
    cluster engine of pipeline.backends (optional extras; options and logs: its settings)."""
    if backend == "local":
        yield from local(todo, workers, fn)
        return
    from . import backends  # imports an engine only when it is asked for

    yield from backends.run(backend, todo, workers, fn=fn, address=address, options=options,
                            logs=logs)


def warm_up(trials: list[dict]) -> None:
    """Compile (or load from numba's cache) each learner's kernels once, in this process, before
    fanning out: a tiny trial per distinct body and learner."""
    seen = set()
    for t in trials:
        spec = t["spec"]
        what = (spec["body"]["name"], spec["learner"]["name"], spec["learner"].get("fast"))
        if what in seen:
            continue
        seen.add(what)
        tiny = dict(spec, epochs=2, snapshots=[], growth=dict(spec["growth"], period=0))
        run_one(dict(t, spec=tiny))
