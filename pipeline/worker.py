"""What runs in a worker process, whichever engine started it: one trial, plain data in and out,
with one BLAS/OpenMP/numba thread. The local pool (pipeline.execute) and the engines
(pipeline.engines) run it; it imports only the engines' THREAD_VARS."""
from __future__ import annotations

import ctypes
import os
import signal
import time
import traceback
from contextlib import contextmanager

from .engines import THREAD_VARS


def run_one(trial: dict) -> dict:
    """Run one trial: plain data in, plain data out, errors returned as text.

    status: ok (a learning curve), diverged (the error became non-finite: a result, with the
    epoch), or failed (an exception; not cached, so the next run tries again)."""
    start, cpu = time.perf_counter(), time.process_time()
    import numpy as np  # here: the engines import this module, and naming an engine (every

    import gbmodel  # stage's config) should not load the numerical core

    try:
        from .fingerprint import code_fingerprint

        mine = code_fingerprint(trial["spec"]["learner"]["name"])
        if trial.get("code", mine) != mine:  # code changed since the plan, or another node's
            raise RuntimeError(f"this process's gbmodel code has fingerprint {mine}, the trial's "
                               f"key names {trial['code']}: the code changed since the plan "
                               "(or differs on this node); run the command again")
        spec = gbmodel.TrialSpec.from_dict(trial["spec"])
        seed = np.random.SeedSequence(trial["seed"]["entropy"],
                                      spawn_key=tuple(trial["seed"]["spawn_key"]))
        # a damaged numba cache is removed and the trial run again, from the same seed
        from .warm import recovering  # here, not at the top: importing the package imports
        # this module (the engines), and `python -m pipeline.warm` warns when it finds itself imported
        from . import checkpoint  # a continuation starts from its base's state (plain data)
        resume = trial.get("resume")  # passed only to a continuation: a plain trial calls
        # run_trial(spec, rng) as any caller does (a stand-in for it needs no resume argument)
        extra = {} if resume is None else {"resume": checkpoint.checkpoint(resume)}
        res = recovering(lambda: gbmodel.run_trial(spec, np.random.default_rng(seed), **extra))
        code_fingerprint(trial["spec"]["learner"]["name"])  # the modules the trial imported
        # (its learner's, on a process's first trial) are the code that was hashed: else
        # CodeChanged, and the trial fails rather than be cached under the other code's key
        out = dict(status="ok", epoch=res.epoch, samples=res.epoch * res.samples_per_epoch,
                   size=res.size, abs_error=res.abs_error, rel_error=res.rel_error, M=res.M,
                   heldout_abs_error=res.heldout_abs_error,
                   uniform_abs_error=res.uniform_abs_error, path_abs_error=res.path_abs_error,
                   snapshots=res.snapshots, largest_jump=res.largest_jump,
                   final=checkpoint.final_state(res) if trial.get("keep_state") else None)
    except gbmodel.Diverged as err:
        out = dict(status="diverged", error=str(err), epoch=err.epoch)
    except Exception as err:  # recorded and reported; the other trials go on
        out = dict(status="failed", error=f"{type(err).__name__}: {err}",
                   traceback=traceback.format_exc())
    out["key"], out["seconds"] = trial["key"], time.perf_counter() - start
    out["cpu"] = time.process_time() - cpu  # this worker's CPU seconds (one thread)
    return out


def run_batch(fn, trials: list[dict]) -> list[dict]:
    """fn (run_one) on each trial of a batch, in order: one task of a worker."""
    return [fn(t) for t in trials]


PR_SET_PDEATHSIG = 1  # linux/prctl.h


def quiet_worker(parent: int | None = None) -> None:
    """A pool worker's start: Ctrl-C, SIGTERM and SIGHUP are left to the driver, which stops every
    worker at once (pipeline.execute.stop_pools); and on Linux the kernel kills the worker if the
    driver dies without doing so (kill -9), so no worker waits forever for work."""
    for s in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP):
        signal.signal(s, signal.SIG_IGN)
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        libc.prctl(PR_SET_PDEATHSIG, int(signal.SIGKILL), 0, 0, 0)
    except (OSError, AttributeError):  # not Linux: the driver's stop_pools still stops us
        return
    if parent is not None and os.getppid() != parent:  # it died before prctl took effect
        os._exit(1)


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
