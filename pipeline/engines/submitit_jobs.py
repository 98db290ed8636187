"""submitit's jobs for engine=slurm and engine=submitit_local: the trials in shards (an array
job each) balanced by estimated cost, `workers` at once. A job spools each finished trial (Shard);
a job that ended without a result, or that squeue no longer lists for `lost_s`, fails its
unfinished trials instead of hanging the run. Files: <paths.out>/logs/submitit/."""
from __future__ import annotations

import getpass
import logging
import os
import pickle
import shutil
import subprocess
import time
import traceback
from pathlib import Path

from ..errors import ConfigError
from . import THREAD_VARS, call, failed

LOCAL_POLL_S = 0.5
# a job that ended without its result file: how long to look for the file before calling the
# job's trials failed (the job writes it before it exits; this covers a shared file system's lag)
RESULT_GRACE_S = 5.0


class Shard:
    """A submitit job: one shard's trials in turn, each finished result (ok or diverged) spooled
    at once under its key (an atomic rename): the driver sees trials one by one, a lost job hands
    over what it finished, a requeued one (SIGTERM, or SIGUSR2: checkpoint) skips them."""

    def __init__(self, fn, spool: str):
        self.fn, self.spool = fn, spool

    def __call__(self, trials: list[dict]) -> list[dict]:
        os.environ.update({k: "1" for k in THREAD_VARS})  # for anything started from here on
        out = []
        for t in trials:
            result = spooled(self.spool, t["key"])
            if result is None:
                result = call(self.fn, t)
                if result.get("status") in ("ok", "diverged"):
                    spool(self.spool, t["key"], result)
            out.append(result)
        return out

    def checkpoint(self, trials: list[dict]):
        """submitit calls this on SIGUSR2 (time limit near): requeue the same shard."""
        from submitit.helpers import DelayedSubmission

        return DelayedSubmission(self, trials)


def spool_path(folder, key: str) -> Path:
    return Path(folder) / f"{key}.pkl"


def spool(folder, key: str, result: dict) -> None:
    path = spool_path(folder, key)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    with open(tmp, "wb") as fh:
        pickle.dump(result, fh, protocol=pickle.HIGHEST_PROTOCOL)
        fh.flush()
        os.fsync(fh.fileno())
    os.replace(tmp, path)


def spooled(folder, key: str) -> dict | None:
    """The spooled result of trial `key`, or None (none yet, or unreadable)."""
    try:
        with open(spool_path(folder, key), "rb") as fh:
            return pickle.load(fh)
    except (OSError, EOFError, pickle.UnpicklingError):
        return None


# --- sharding ----------------------------------------------------------------------------------

def shards(todo: list[dict], n: int, cost=None) -> list[list[dict]]:
    """`todo` in at most n non-empty shards of about equal cost (LPT: longest first, to the
    least loaded shard), each in the order of `todo`, the costliest first."""
    if isinstance(n, bool) or not isinstance(n, int) or n < 1:
        raise ValueError(f"shards: n={n!r} must be an int >= 1")
    cost = cost or (lambda t: 1.0)  # (the stage gives pipeline.plan.cost)
    costs = [float(cost(t)) for t in todo]
    n = min(n, len(todo))
    loads, members = [0.0] * n, [[] for _ in range(n)]
    for i in sorted(range(len(todo)), key=lambda i: -costs[i]):  # stable: ties keep todo order
        s = min(range(n), key=lambda s: (loads[s], s))
        loads[s] += costs[i]
        members[s].append(i)
    order = sorted(range(n), key=lambda s: (-loads[s], s))
    return [[todo[i] for i in sorted(members[s])] for s in order]


# --- submitting and watching -------------------------------------------------------------------

def signal_delay(opts: dict) -> int:
    """Seconds before --time at which SLURM sends SIGUSR2: engine.signal_delay_s, else at most a
    tenth of the limit (SLURM may signal 60 s early: timeout_min=2 was cut at ~38 s)."""
    if opts.get("signal_delay_s") is not None:
        return int(opts["signal_delay_s"])
    return max(1, min(90, int(opts["timeout_min"]) * 6))


def job_parameters(opts: dict, workers: int, cluster: str, figure: str) -> dict:
    """What the driver passes to submitit's executor.update_parameters."""
    setup = [f"export {k}=1" for k in THREAD_VARS] + list(opts["setup"])
    params = dict(name=f"gbgrowth-{figure}", timeout_min=int(opts["timeout_min"]),
                  cpus_per_task=1, tasks_per_node=1, nodes=1)
    params[f"{cluster}_setup"] = setup
    if cluster == "slurm":
        params.update(mem_gb=opts["mem_gb"], slurm_partition=opts["partition"],
                      slurm_array_parallelism=workers, slurm_signal_delay_s=signal_delay(opts))
        for key in ("account", "qos", "gres", "constraint"):
            if opts.get(key) is not None:
                params[f"slurm_{key}"] = opts[key]
        if opts.get("extra"):
            params["slurm_additional_parameters"] = dict(opts["extra"])
    return params


def queued_jobs() -> set[str] | None:
    """The ids of this user's jobs squeue lists (array tasks one by one); None if it fails."""
    try:
        out = subprocess.run(["squeue", "-h", "-r", "-o", "%i", "-u", getpass.getuser()],
                             capture_output=True, text=True, timeout=60, check=True).stdout
    except (OSError, subprocess.SubprocessError):
        return None
    return set(out.split())


def results(todo: list[dict], workers: int, fn, cluster: str, opts: dict, logs=None,
            cost=None):
    """Yield each trial's result as its job spools it, a failed or lost job's others as failed.
    cluster: slurm or local (submitit's); opts: the engine's settings as a dict."""
    import submitit

    if cluster == "slurm" and shutil.which("sbatch") is None:
        raise ConfigError("engine=slurm: sbatch not found; submit from a SLURM login node, or use "
                          "engine=submitit_local (or ray) on this machine")
    n = opts["shards"] or workers
    if cluster == "local":
        n = min(n, workers)  # every local job starts at once
    parts = shards(todo, n, cost)
    folder = Path(logs) if logs else Path.cwd() / "outputs" / "logs" / "submitit"
    folder.mkdir(parents=True, exist_ok=True)
    executor = submitit.AutoExecutor(folder=str(folder / "%j"), cluster=cluster)
    executor.update_parameters(**job_parameters(opts, workers, cluster,
                                                todo[0]["figure"]))
    jobs = executor.map_array(Shard(fn, str(folder / "spool")), parts)
    poll = LOCAL_POLL_S if cluster == "local" else float(opts["poll_s"])
    slurm = cluster == "slurm"  # a local job's watcher asks no one (its update() raises)
    once = OnceFilter("Bypassing sacct error")  # no accounting: say so once, not every poll
    logging.getLogger("submitit").addFilter(once)
    try:
        yield from watch(jobs, parts, folder / "spool", poll=poll,
                         lost_s=float(opts.get("lost_s", 0.0)),
                         queued=queued_jobs if slurm else None,
                         refresh=jobs[0].watcher.update if slurm else None)
    finally:
        logging.getLogger("submitit").removeFilter(once)


class OnceFilter(logging.Filter):
    """Lets the first log record containing `text` through, drops the ones after it."""
    def __init__(self, text: str):
        super().__init__()
        self.text, self.seen = text, False

    def filter(self, record: logging.LogRecord) -> bool:
        if self.text not in record.getMessage():
            return True
        seen, self.seen = self.seen, True
        return not seen


def watch(jobs, parts, spool_dir, poll: float, lost_s: float, queued=None, refresh=None):
    """Yield (trial, result) of `jobs` (one per part) until each ended, was lost or handed over
    all its trials. Every `poll` s: `refresh` (sacct), the spool, and `queued` (squeue): a job
    not listed for `lost_s` s is lost (without accounting submitit never calls it done)."""
    pending = {job: {t["key"]: t for t in part} for job, part in zip(jobs, parts)}
    keys = {job: list(left) for job, left in pending.items()}
    gone_since: dict = {}
    no_result: dict = {}
    try:
        while pending:
            if refresh is not None:
                refresh()  # the driver's poll_s, not submitit's back-off
            listed = queued() if queued else None
            now = time.monotonic()
            for job, left in list(pending.items()):
                for key in list(left):  # kept in the spool while the job lives (a requeue)
                    result = spooled(spool_dir, key)
                    if result is not None:
                        yield left.pop(key), result
                if left and listed is not None and job.job_id not in listed and not job.done():
                    gone_since.setdefault(job, now)
                    if now - gone_since[job] < lost_s:
                        continue
                    job.cancel(check=False)
                    yield from lost(job, left, spool_dir,
                                    f"job {job.job_id} ended without a result (not in squeue "
                                    f"for {lost_s:.0f} s, state {job.state})")
                elif left and not job.done():
                    gone_since.pop(job, None)
                    continue
                elif left and not job.paths.result_pickle.exists():
                    # ended (sacct: FAILED, CANCELLED...) without a result: wait RESULT_GRACE_S for
                    # a slow shared file system, without holding up the other jobs (submitit's
                    # result() would block 15 s)
                    since = no_result.setdefault(job, now)
                    if now - since < RESULT_GRACE_S:
                        continue
                    yield from lost(job, left, spool_dir, f"job {job.job_id} {job.state} without "
                                    f"a result (its log: {job.paths.stderr})")
                elif left:
                    yield from ended(job, left, spool_dir)
                del pending[job]
                for key in keys[job]:
                    spool_path(spool_dir, key).unlink(missing_ok=True)
            if pending:
                time.sleep(poll)
    finally:
        for job in pending:  # Ctrl-C, an error or a dropped generator: cancel the rest
            try:
                job.cancel(check=False)
            except Exception:  # noqa: BLE001 - already finished or gone
                pass


def ended(job, left: dict, spool_dir):
    """The results of a job that ended, for its trials not yet handed over (`left`)."""
    try:
        results = job.result()
        by_key = {r["key"]: r for r in results}
        missing = set(left) - set(by_key)
        if missing:
            raise RuntimeError(f"job {job.job_id} returned no result for {len(missing)} trials")
    except Exception as err:  # noqa: BLE001 - failed, timed out, cancelled, lost
        yield from lost(job, left, spool_dir, f"job {job.job_id} {job.state}: "
                        f"{type(err).__name__}: {err}", traceback.format_exc())
        return
    for key, trial in left.items():
        yield trial, by_key[key]


def lost(job, left: dict, spool_dir, error: str, tb: str | None = None):
    """A job that failed or was lost: what it spooled, and its other trials as failed."""
    for key, trial in left.items():
        result = spooled(spool_dir, key)
        yield trial, result if result is not None else failed(trial, error, tb=tb)
