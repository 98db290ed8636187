"""The trial cache: per trial one Parquet learning curve and one JSON sidecar, checked on read;
per figure the plan records that say which trials make it.

Layout under paths.cache:
    trials/<kk>/<key>.parquet     the learning curve (pipeline.io.TRIAL_CURVE); kk = key[:2]
    trials/<kk>/<key>.json        the trial's spec, seed, code fingerprint, status, final model,
                                  snapshots, the SHA-256 of the Parquet file, and a seal (the
                                  SHA-256 of everything else in the sidecar)
    trials/<kk>/<key>.lock        held (flock) by the process computing the trial
    failed/<key>.json             the error of a trial that failed (not cached: it runs again)
    plans/<figure>/<group>/<hash>.json   the conditions one simulate run planned for a figure
    plans/<figure>/current.json   the group that makes the figure now

A trial's key hashes its content only (spec, seed, code fingerprint: pipeline.plan.trial_key),
never the figure or the label that asked for it: the same trial under two figures or two sweeps
is computed once. The curve is written first and the sidecar last: the sidecar marks a finished
trial, its curve checksum proves the curve complete and its seal (pipeline.io.seal) proves the sidecar unchanged (the
model, the snapshots, the status). A trial that diverged is a result too (status `diverged`, no
curve); a trial that failed with an error is not cached and runs again next time.

A figure is a *group* of plan records: one simulate run, or every job of one Hydra multirun (they
share the sweep's folder). The group a run writes becomes the figure's current group; its
conditions are the union of its records' (one per distinct setting).
"""
from __future__ import annotations

import fcntl
import hashlib
import os
from pathlib import Path

import numpy as np

from . import io

TRIALS, PLANS, FAILED = "trials", "plans", "failed"


def trial_paths(cache_dir, trial: dict) -> tuple[Path, Path]:
    key = trial["key"]
    stem = os.path.join(cache_dir, TRIALS, key[:2], key)  # strings first: pathlib's joins cost
    return Path(f"{stem}.parquet"), Path(f"{stem}.json")


def failure_path(cache_dir, trial: dict) -> Path:
    return Path(cache_dir) / FAILED / f"{trial['key']}.json"


def check(cache_dir, trial: dict) -> tuple[dict | None, str | None]:
    """(sidecar, None) for a finished trial whose files are intact; (None, None) for one not
    run yet; (None, why) for one whose files are damaged (they are then recomputed)."""
    side, _, why = read_trial(cache_dir, trial, curve=False)
    return side, why


def read_trial(cache_dir, trial: dict, curve: bool = True):
    """(sidecar, curve table or None, None) for a finished trial whose files are intact, each
    file read once: its checksum and its table come from the same bytes (curve=False: checked,
    not parsed); (None, None, None) for one not run yet; (None, None, why) for a damaged one."""
    curve_path, side = trial_paths(cache_dir, trial)
    try:
        raw = side.read_bytes()
    except FileNotFoundError:
        return None, None, None
    except IsADirectoryError:
        return None, None, f"{side}: a folder, not a JSON file"
    except OSError as err:
        return None, None, str(err)
    try:
        s = io.check_seal(io.parse_json(raw, side), side.name)  # model, snapshots, status too
        if s.get("key") != trial["key"]:
            return None, None, f"{side.name} belongs to another trial"
        if s.get("status") == "diverged":
            return s, None, None
        try:
            data = curve_path.read_bytes()
        except FileNotFoundError:
            return None, None, f"{curve_path.name} is missing"
        if hashlib.sha256(data).hexdigest() != s.get("curve_sha256"):
            return None, None, (f"{curve_path.name} does not match its checksum (truncated or "
                                "changed)")
        table = io.parse_table(data, curve_path, schema=io.TRIAL_CURVE) if curve else None
    except (OSError, ValueError) as err:
        return None, None, str(err)
    return s, table, None


def signature(cache_dir, trial: dict) -> str | None:
    """What the file system says about a trial's files (size, inode, modification and change
    times of the sidecar and the curve): any write or replacement changes it, so an unchanged
    signature lets a reader reuse what it checked before. None: no sidecar."""
    parts = []
    for path in trial_paths(cache_dir, trial)[::-1]:
        try:
            st = os.stat(path)
        except FileNotFoundError:
            if not parts:
                return None
            parts.append("-")
            continue
        parts.append(f"{st.st_size}:{st.st_ino}:{st.st_mtime_ns}:{st.st_ctime_ns}")
    return "/".join(parts)


CONTENT = ("key", "spec", "seed", "code", "labels")  # what a sidecar keeps of the planned trial


def write_trial(cache_dir, trial: dict, result: dict) -> None:
    """Store a finished trial: the curve first, then the sealed sidecar with its checksum."""
    curve, side = trial_paths(cache_dir, trial)
    record = {k: trial[k] for k in CONTENT} | dict(status=result["status"])
    if result["status"] == "diverged":
        record.update(error=result["error"], epoch=result["epoch"])
        curve.unlink(missing_ok=True)
    else:
        record["curve_sha256"] = io.write_table(curve, io.trial_curve_table(result))
        record["largest_jump"] = float(result["largest_jump"])
        M = result["M"]
        record["M"] = None if M is None else np.asarray(M).tolist()
        record["snapshots"] = {str(e): np.asarray(m).tolist()
                               for e, m in sorted(result["snapshots"].items())}
    # compact: the sidecar is read by programs; timing is left out: its bytes must not vary
    io.write_json(side, io.seal(record), compact=True)


def read_curve(cache_dir, trial: dict):
    return io.read_table(trial_paths(cache_dir, trial)[0], schema=io.TRIAL_CURVE).to_pandas()


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


# ---- plan records: which conditions make a figure ----------------------------------------------
def plan_record(figure: str, conditions: list[dict], paper: dict, experiment: str | None) -> dict:
    return dict(figure=figure, experiment=experiment, paper=paper, conditions=conditions)


def record_digest(record: dict) -> str:
    return hashlib.sha256(io.dump_json(record).encode()).hexdigest()[:16]


def write_plan(cache_dir, record: dict, group: str | None = None) -> tuple[str, dict | None]:
    """Record the conditions of one simulate run and make its group the figure's current one.

    group: the multirun this run is a job of (its jobs' records form one figure); None: this run
    alone. Nothing is rewritten when the same record is there already. Returns (group, the
    previous current group's summary when this run replaced another group, else None)."""
    folder = Path(cache_dir) / PLANS / record["figure"]
    digest = record_digest(record)
    group = group or f"run-{digest}"
    path = folder / group / f"{digest}.json"
    if not path.exists():
        io.write_json(path, record)
    current = folder / "current.json"
    before = read_current(folder)
    if before != group:
        replaced = None
        if before is not None:
            old, _, _ = group_conditions(folder, before)
            replaced = dict(group=before, conditions=len(old),
                            experiment=_group_experiment(folder, before))
        io.write_json(current, dict(group=group))
        return group, replaced
    return group, None


def read_current(folder: Path) -> str | None:
    path = Path(folder) / "current.json"
    if not path.exists():
        return None
    return io.safe_name(f"{path}: group", io.read_json(path).get("group"))


def _group_experiment(folder: Path, group: str) -> str | None:
    for p in sorted((folder / group).glob("*.json")):
        try:
            return io.read_json(p).get("experiment")
        except ValueError:
            continue
    return None


def group_conditions(folder: Path, group: str) -> tuple[list[dict], dict, list[str]]:
    """(conditions, paper, problems) of one group: the union of its records' conditions, one per
    (variant, settings), in the order of the records' writing (file names are content hashes, so
    they are sorted by the run order each record stores)."""
    records, problems = [], []
    for p in sorted((Path(folder) / group).glob("*.json")):  # DamagedFile names a bad one
        r = io.read_json(p, need=("figure", "conditions"))
        if not isinstance(r["conditions"], list) or not all(
                isinstance(c, dict) and {"id", "spec", "trials", "growth_label"} <= set(c)
                for c in r["conditions"]):
            raise io.DamagedFile(f"{p}: not a plan record (its conditions are malformed)")
        records.append(r)
    records.sort(key=lambda r: (r.get("job", 0), record_digest(r)))
    conds, paper = {}, {}
    for r in records:
        for c in r["conditions"]:
            v = c.get("variant")
            conds.setdefault((v["label"] if v else None, c["id"]), c)
        paper = paper or r.get("paper") or {}
    return list(conds.values()), paper, problems


def figure_conditions(cache_dir, figure: str) -> tuple[list[dict], dict, list[str]]:
    """The conditions of a figure (its current group), its paper section and any problems; a
    damaged plan record is an io.DamagedFile naming it (the figure is then not aggregated, so a
    good aggregate is never replaced by a partial one)."""
    folder = Path(cache_dir) / PLANS / figure
    group = read_current(folder)
    if group is None:
        raise FileNotFoundError(f"figure={figure}: not simulated (no plan under {folder})")
    conds, paper, problems = group_conditions(folder, group)
    if not conds:
        raise ValueError(f"figure={figure}: its plan records under {folder / group} are unreadable")
    return conds, paper, problems


def figures(cache_dir) -> list[str]:
    return sorted(p.parent.name for p in (Path(cache_dir) / PLANS).glob("*/current.json"))
