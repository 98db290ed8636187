"""The trial cache: per trial one Parquet learning curve and one JSON sidecar, checked on read.

Layout under paths.cache:
    <figure>/<key>.parquet        the learning curve (pipeline.io.CURVE)
    <figure>/<key>.json           the trial's config slice, seed, code fingerprint, status, final
                                  model and snapshots, and the SHA-256 of the Parquet file
    <figure>/<key>.lock           held (flock) by the process computing the trial
    <figure>/plans/<hash>.json    the trials of one simulate run (written once, by that run)

The key hashes the trial's config slice and its learner's code fingerprint (pipeline.plan), so a
trial is computed once and recomputed only when something it depends on changes. The curve is
written first and the sidecar last: the sidecar marks a finished trial, and its checksum proves
the curve complete. A trial that diverged is a result too (status `diverged`, no curve); a trial
that failed with an error is not cached and runs again next time. No file is written by two
runs: trial files are named by content, plan records by their own hash.
"""
from __future__ import annotations

import fcntl
import hashlib
import os
import time
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq

from . import io


def trial_paths(cache_dir, trial: dict) -> tuple[Path, Path]:
    folder = Path(cache_dir) / trial["labels"]["figure"]
    return folder / f"{trial['key']}.parquet", folder / f"{trial['key']}.json"


def check(cache_dir, trial: dict) -> tuple[dict | None, str | None]:
    """(sidecar, None) for a finished trial whose files are intact; (None, None) for one not
    run yet; (None, why) for one whose files are damaged (they are then recomputed)."""
    curve, side = trial_paths(cache_dir, trial)
    if not side.exists():
        return None, None
    try:
        s = io.read_json(side)
        if s.get("key") != trial["key"]:
            return None, f"{side.name} belongs to another trial"
        if s.get("status") == "diverged":
            return s, None
        if not curve.exists():
            return None, f"{curve.name} is missing"
        if io.sha256_file(curve) != s.get("curve_sha256"):
            return None, f"{curve.name} does not match its checksum (truncated or changed)"
    except (OSError, ValueError) as err:
        return None, str(err)
    return s, None


def write_trial(cache_dir, trial: dict, result: dict) -> None:
    """Store a finished trial: the curve first, then the sidecar with its checksum."""
    curve, side = trial_paths(cache_dir, trial)
    record = dict(trial, status=result["status"], seconds=round(result["seconds"], 3))
    if result["status"] == "diverged":
        record.update(error=result["error"], epoch=result["epoch"])
        curve.unlink(missing_ok=True)
    else:
        l = trial["labels"]
        io.write_table(curve, io.curve_table(l, result["epoch"], result["samples"],
                                             result["size"], result["abs_error"],
                                             result["rel_error"],
                                             result["heldout_abs_error"]))
        record["curve_sha256"] = io.sha256_file(curve)
        record["largest_jump"] = float(result["largest_jump"])
        M = result["M"]
        record["M"] = None if M is None else np.asarray(M).tolist()
        record["snapshots"] = {str(e): np.asarray(m).tolist()
                               for e, m in sorted(result["snapshots"].items())}
    record.pop("seconds")  # timing varies from run to run; the sidecar's bytes must not
    io.write_json(side, record)


def read_curve(cache_dir, trial: dict):
    return pq.read_table(trial_paths(cache_dir, trial)[0]).to_pandas()


class Claim:
    """An exclusive, non-blocking claim on a trial (flock on <key>.lock): two runs on one cache
    do not compute the same trial. The operating system drops the lock when its process dies,
    so a killed run leaves nothing stuck."""

    def __init__(self, cache_dir, trial: dict):
        self.path = trial_paths(cache_dir, trial)[1].with_suffix(".lock")
        self.fh = None

    def acquire(self) -> bool:
        self.path.parent.mkdir(parents=True, exist_ok=True)
        fh = open(self.path, "a")
        try:
            fcntl.flock(fh, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            fh.close()
            return False
        self.fh = fh
        return True

    def release(self) -> None:
        if self.fh is not None:  # a run that opened the old file meanwhile re-checks the cache
            self.path.unlink(missing_ok=True)
            fcntl.flock(self.fh, fcntl.LOCK_UN)
            self.fh.close()
            self.fh = None


# ---- plan records: which trials make a figure --------------------------------------------------
def write_plan(cache_dir, figure: str, trials: list[dict], whole: bool, paper: dict) -> Path:
    """Record the trials of one simulate run. whole=True: they are the figure (an experiment);
    whole=False: each condition replaces that condition of earlier runs (a sweep's jobs)."""
    body = dict(figure=figure, whole=whole, paper=paper,
                trials=[{k: t[k] for k in ("key", "labels", "spec") if k in t}
                        | ({"variant": t["variant"]} if "variant" in t else {}) for t in trials])
    digest = hashlib.sha256(io.dump_json(body).encode()).hexdigest()[:16]
    path = Path(cache_dir) / figure / "plans" / f"{digest}.json"
    io.write_json(path, dict(body, created_ns=time.time_ns(), pid=os.getpid()))
    return path


def figure_trials(cache_dir, figure: str) -> tuple[list[dict], dict, list[str]]:
    """The trials of a figure from its plan records: the newest whole record, then newer partial
    ones replacing its conditions. Returns (trials, paper, problems with unreadable records)."""
    records, problems = [], []
    for p in sorted((Path(cache_dir) / figure / "plans").glob("*.json")):
        try:
            records.append(io.read_json(p))
        except ValueError as err:
            problems.append(f"plan record ignored: {err}")
    records.sort(key=lambda r: r.get("created_ns", 0))
    start = max((i for i, r in enumerate(records) if r.get("whole")), default=0)
    by_condition, paper = {}, {}
    for r in records[start:]:
        fresh = {}
        for t in r["trials"]:
            fresh.setdefault(t["labels"]["condition"], []).append(t)
        by_condition.update(fresh)
        if r.get("whole") or not paper:
            paper = r.get("paper", {})
    return [t for ts in by_condition.values() for t in ts], paper, problems


def figures(cache_dir) -> list[str]:
    return sorted(p.parent.name for p in Path(cache_dir).glob("*/plans"))
