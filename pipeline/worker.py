"""One trial in a worker process, whichever engine started it: plain data in and out."""
from __future__ import annotations

import ctypes
import os
import signal
import time
import traceback


def run_one(trial: dict) -> dict:
    """status ok, diverged (a result, with the epoch) or failed (an error as text, not cached)."""
    start, cpu = time.perf_counter(), time.process_time()
    import numpy as np  # here: importing the pool loads no numerical core

    import gbmodel

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
        from . import checkpoint
        from .warm import recovering  # a damaged numba cache is removed, the trial rerun
        resume = trial.get("resume")  # a continuation's only (a stand-in run_trial takes none)
        learner = trial["spec"]["learner"]["name"]
        extra = {} if resume is None else {"resume": checkpoint.checkpoint(resume, learner)}
        views = trial.get("views", ())  # trials whose learning is this one's first epochs
        if views:
            extra["views"] = tuple(gbmodel.TrialSpec.from_dict(v["spec"]) for v in views)
        res = recovering(lambda: gbmodel.run_trial(spec, np.random.default_rng(seed), **extra))
        code_fingerprint(trial["spec"]["learner"]["name"])  # what it imported was hashed
        out = _result(res, checkpoint.final_state(res) if trial.get("keep_state") else None)
        if views:  # each view's result, its CPU counted in this trial's
            out["views"] = {v["key"]: dict(_result(r), key=v["key"], seconds=0.0, cpu=0.0)
                            for v, r in zip(views, res.views)}
    except gbmodel.Diverged as err:
        out = dict(status="diverged", error=str(err), epoch=err.epoch)
        if trial.get("views"):  # the views' learning stopped here: each runs on its own
            out["views"] = {v["key"]: dict(run_one(view(trial, v)), cpu=0.0)
                            for v in trial["views"]}
    except Exception as err:  # recorded and reported; the other trials go on
        out = dict(status="failed", error=f"{type(err).__name__}: {err}",
                   traceback=traceback.format_exc())
    out["key"], out["seconds"] = trial["key"], time.perf_counter() - start
    out["cpu"] = time.process_time() - cpu  # this worker's CPU seconds (one thread)
    return out


def _result(res, final=None) -> dict:
    """A TrialResult (or a Diverged) as the plain data the driver caches."""
    import gbmodel

    if isinstance(res, gbmodel.Diverged):
        return dict(status="diverged", error=str(res), epoch=res.epoch)
    return dict(status="ok", epoch=res.epoch, samples=res.epoch * res.samples_per_epoch,
                size=res.size, abs_error=res.abs_error, rel_error=res.rel_error, M=res.M,
                heldout_abs_error=res.heldout_abs_error, uniform_abs_error=res.uniform_abs_error,
                path_abs_error=res.path_abs_error, snapshots=res.snapshots,
                largest_jump=res.largest_jump, final=final)


def view(trial: dict, v: dict) -> dict:
    """The trial a view of `trial` stands for (its key and spec), run on its own."""
    return {**{k: x for k, x in trial.items() if k not in ("views", "keep_state")}, **v}


def run_batch(fn, trials: list[dict]) -> list[dict]:
    return [fn(t) for t in trials]


PR_SET_PDEATHSIG = 1  # linux/prctl.h


def _alive(pid: int | None) -> bool:
    try:
        if pid is not None:
            os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # another user's
        pass
    return True


DRIVER = "GBGROWTH_POOL_DRIVER"  # the pid of the driver, in its pool's environment (execute)


def driver() -> int | None:
    return int(os.environ.get(DRIVER) or 0) or None


def die_with_parent(parent: int | None = None) -> None:
    """Linux: this process is killed when its parent dies (a worker's: the driver, or the fork
    server, which dies with the driver), and ends at once if `parent` (else the one it has now)
    is gone already."""
    parent = os.getppid() if parent is None else parent
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        libc.prctl(PR_SET_PDEATHSIG, int(signal.SIGKILL), 0, 0, 0)
    except (OSError, AttributeError):  # not Linux: the driver's stop_pools still stops us
        return
    if os.getppid() != parent:  # gone before prctl took effect
        os._exit(1)


def quiet_worker(fingerprints: dict | None = None) -> None:
    """A pool worker ignores the signals the driver handles, and dies with its parent
    (die_with_parent); it takes the driver's code fingerprints where its files are the driver's
    (fingerprint.trust)."""
    from .stop import ignore

    ignore()
    die_with_parent()
    if not _alive(driver()):  # (a fork server's worker: its parent is the server)
        os._exit(1)
    if fingerprints:
        try:
            from .fingerprint import trust

            trust(fingerprints)
        except Exception:  # noqa: BLE001 (a broken import is run_one's to report, per trial)
            pass

