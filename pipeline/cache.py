"""The trial cache: per trial (keyed by its content, pipeline.keys.trial_key) one Parquet curve,
written first, and one sealed JSON sidecar with the curve's checksum, written last: a finished
trial (layout: docs/running.md, "Where outputs land"). A diverged trial is a result (no curve);
a failed one runs again. Per figure, plan records say which trials make it: a *group* of them
(one simulate run, or every job of a multirun) is the figure's current one. Measured CPU times
are kept apart (paths.out/logs/times/): the cache's bytes do not vary with the machine."""
from __future__ import annotations

import errno
import fcntl
import hashlib
import json
import os
import re
import time
from contextlib import suppress
from functools import lru_cache
from pathlib import Path

import numpy as np

from . import io
from .keys import trial_key

TRIALS, PLANS, FAILED = "trials", "plans", "failed"
KEY = re.compile(r"[0-9a-f]{20}")  # pipeline.keys.trial_key


def trial_paths(cache_dir, trial: dict) -> tuple[Path, Path]:
    """(curve, sidecar) of a trial; its key (read from a file, too) must be a key."""
    stem = _stem(cache_dir, trial)
    return Path(f"{stem}.parquet"), Path(f"{stem}.json")


def _stem(cache_dir, trial: dict) -> str:
    """A trial's path without suffix, a string (pathlib's joins cost more than a stat)."""
    key = trial["key"]
    if not isinstance(key, str) or not KEY.fullmatch(key):
        raise io.DamagedFile(f"trial key {key!r}: not a trial key (20 hexadecimal digits)")
    return os.path.join(_inside(os.path.join(cache_dir, TRIALS, key[:2]), io.confined_root()), key)


@lru_cache(maxsize=1024)
def _inside(folder: str, root) -> str:
    """io.check_inside(folder), once per process and confinement instead of once per trial."""
    io.check_inside(folder)
    return folder


def failure_path(cache_dir, trial: dict) -> Path:
    trial_paths(cache_dir, trial)  # the key checked
    return io.check_inside(Path(cache_dir) / FAILED / f"{trial['key']}.json")


def check(cache_dir, trial: dict) -> tuple[dict | None, str | None]:
    """(sidecar, None) for an intact finished trial, (None, None) for one not run, (None, why)."""
    side, _, why = read_trial(cache_dir, trial, curve=False)
    return side, why


def read_trial(cache_dir, trial: dict, curve: bool = True):
    """(sidecar, curve table or None, None) for an intact finished trial, each file read once
    (curve=False: checked, not parsed); (None, None, None) for one not run yet; (None, None,
    why) for a damaged one (recomputed)."""
    stem = _stem(cache_dir, trial)
    try:  # a trial not run yet is the common answer: no path objects for it
        with open(f"{stem}.json", "rb") as fh:
            raw = fh.read()
    except FileNotFoundError:
        return None, None, None
    except IsADirectoryError:
        return None, None, f"{stem}.json: a folder, not a JSON file"
    except OSError as err:
        return None, None, str(err)
    curve_path, side = Path(f"{stem}.parquet"), Path(f"{stem}.json")
    try:
        s = io.check_seal(io.parse_json(raw, side), side.name)  # model, snapshots, status too
        if s.get("key") != trial["key"]:
            return None, None, f"{side.name} belongs to another trial"
        if not _keyed(s):
            return None, None, f"{side.name}: its spec, seed and code do not hash to its key"
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
    """Size, inode, modification and change times of a trial's files: unchanged, a reader may
    reuse what it checked before. None: no sidecar."""
    parts, stem = [], _stem(cache_dir, trial)
    for path in (f"{stem}.json", f"{stem}.parquet"):
        try:
            st = os.stat(path)
            parts.append(f"{st.st_size}:{st.st_ino}:{st.st_mtime_ns}:{st.st_ctime_ns}")
        except FileNotFoundError:
            parts.append("-")
    return None if parts[0] == "-" else "/".join(parts)


def _keyed(s: dict) -> bool:
    """Whether a sidecar's own spec, seed and code hash to its key (not one copied or edited)."""
    try:
        return trial_key(s["spec"], s["seed"], s["code"], s.get("start")) == s["key"]
    except (KeyError, TypeError, ValueError):
        return False


CONTENT = ("key", "spec", "seed", "code", "labels")  # what a sidecar keeps of the planned trial


def write_trial(cache_dir, trial: dict, result: dict) -> None:
    """Store a finished trial: the curve, then the sealed sidecar (io.sealed_json: compact, no
    timing, so its bytes do not vary), both in the folder _stem checked."""
    stem = _stem(cache_dir, trial)
    curve, side = f"{stem}.parquet", f"{stem}.json"
    record = {k: trial[k] for k in CONTENT} | dict(status=result["status"])
    if trial.get("start") is not None:  # a continuation: its base is part of its key
        record["start"] = trial["start"]
    if result["status"] == "diverged":
        record.update(error=result["error"], epoch=result["epoch"])
        Path(curve).unlink(missing_ok=True)
    else:
        data = io.table_bytes(io.trial_curve_table(result), compress=False)  # (a few kB)
        io.write_in_checked(curve, data)
        record["curve_sha256"] = hashlib.sha256(data).hexdigest()
        record["largest_jump"] = float(result["largest_jump"])
        M = result["M"]
        record["M"] = None if M is None else np.asarray(M).tolist()
        record["snapshots"] = {str(e): np.asarray(m).tolist()
                               for e, m in sorted(result["snapshots"].items())}
    io.write_in_checked(side, io.sealed_json(record))


def forget_failure(cache_dir, trial: dict) -> None:
    """Remove the failure record of a trial (failure_path), if there is one."""
    _stem(cache_dir, trial)  # the key checked
    folder = _inside(os.path.join(cache_dir, FAILED), io.confined_root())
    with suppress(FileNotFoundError):  # (an unlink never follows a link)
        os.unlink(os.path.join(folder, f"{trial['key']}.json"))


def read_curve(cache_dir, trial: dict):
    return io.read_table(trial_paths(cache_dir, trial)[0], schema=io.TRIAL_CURVE).to_pandas()


CLAIMS = "claims"  # the one lock file of a cache: a byte-range lock per trial being computed
_claims: dict[tuple[int, Path], tuple[int, set]] = {}  # (pid, file) -> (descriptor, offsets held)


def _claims_fd(cache_dir) -> tuple[int, set]:
    """This process's descriptor of the lock file, kept open (closing one drops every lock),
    and the offsets it holds."""
    path = Path(cache_dir).absolute() / CLAIMS
    key = (os.getpid(), path)  # a forked child holds none of its parent's locks
    if key not in _claims:
        io.check_inside(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        flags = os.O_RDWR | os.O_CREAT | os.O_NOFOLLOW | os.O_CLOEXEC
        try:
            fd = os.open(path, flags, 0o644)
        except OSError as err:
            if err.errno == errno.ELOOP:
                raise io.UnsafeName(f"{path}: a link; remove it (the claims file is never "
                                    "followed)") from None
            raise
        _claims[key] = fd, set()
    return _claims[key]


class Claim:
    """An exclusive, non-blocking claim on a trial, so two runs on one cache do not compute it
    both: a one-byte fcntl lock at the trial's offset in cache/claims, one descriptor per
    process. The system drops the locks of a process that dies; NFS with lockd shares them."""

    def __init__(self, cache_dir, trial: dict):
        _stem(cache_dir, trial)  # the key checked
        self.cache_dir = cache_dir
        self.offset = int(trial["key"][:15], 16)  # 60 bits: distinct for distinct keys
        self.fh = None  # (descriptor, offsets held) while held

    def acquire(self) -> bool:
        fd, held = _claims_fd(self.cache_dir)
        if self.offset in held:  # another claim of this process holds it
            return False
        try:
            fcntl.lockf(fd, fcntl.LOCK_EX | fcntl.LOCK_NB, 1, self.offset)
        except (BlockingIOError, PermissionError):  # held by another process
            return False
        held.add(self.offset)
        self.fh = fd, held
        return True

    def release(self) -> None:
        if self.fh is not None:
            fcntl.lockf(self.fh[0], fcntl.LOCK_UN, 1, self.offset)
            self.fh[1].discard(self.offset)
            self.fh = None


# ---- plan records: which conditions make a figure ----------------------------------------------
def plan_record(figure: str, conditions: list[dict], paper: dict, experiment: str | None) -> dict:
    return dict(figure=figure, experiment=experiment, paper=paper, conditions=conditions)


def record_digest(record: dict) -> str:
    return hashlib.sha256(io.dump_json(record).encode()).hexdigest()[:16]


def write_plan(cache_dir, record: dict, group: str | None = None) -> tuple[str, dict | None]:
    """Record one simulate run's conditions in `group` (a multirun's, whose jobs make one figure;
    None: this run's own) and make it the figure's current one; returns (group, the summary of
    the current group it replaced, or None)."""
    folder = io.check_inside(Path(cache_dir) / PLANS / io.safe_name("figure", record["figure"]))
    digest = record_digest(record)
    group = group or f"run-{digest}"
    path = folder / group / f"{digest}.json"
    if not path.exists():
        io.write_json(path, record)
    current = folder / "current.json"
    try:
        before = read_current(folder)
    except io.DamagedFile:  # a damaged pointer: this run's group replaces it
        before = None
    if before == group:
        return group, None
    replaced = None
    if before is not None:
        replaced = dict(group=before, conditions=len(group_conditions(folder, before)[0]),
                        experiment=_group_experiment(folder, before))
    io.write_json(current, dict(group=group))
    return group, replaced


def read_current(folder: Path) -> str | None:
    path = Path(folder) / "current.json"
    if not path.exists():
        return None
    group = io.safe_name(f"{path}: group", io.read_json(path).get("group"))
    if not (Path(folder) / group).is_dir():
        raise io.DamagedFile(f"{path}: names the group {group!r}, which is not there; run "
                             "pipeline.simulate for this figure again")
    return group


def _group_experiment(folder: Path, group: str) -> str | None:
    for p in sorted((folder / group).glob("*.json")):
        try:
            return io.read_json(p).get("experiment")
        except ValueError:
            continue
    return None


SPEC_KEYS = {"body", "growth", "learner", "evaluation", "epochs"}  # of gbmodel.TrialSpec.to_dict


def _condition_ok(c) -> bool:
    """Whether a plan record's condition has an id, a spec, a growth label and trials with a
    trial key and an index."""
    return (isinstance(c, dict) and {"id", "spec", "trials", "growth_label"} <= set(c)
            and isinstance(c["spec"], dict) and SPEC_KEYS <= set(c["spec"])
            and isinstance(c["trials"], list)
            and all(isinstance(t, dict) and isinstance(t.get("key"), str)
                    and KEY.fullmatch(t["key"]) and isinstance(t.get("trial"), int)
                    for t in c["trials"]))


def group_conditions(folder: Path, group: str) -> tuple[list[dict], dict, list[str]]:
    """(conditions, paper, problems) of one group: its records' conditions, one per (variant,
    settings), in the run order the records store (their names are content hashes)."""
    records = []
    for p in sorted((Path(folder) / group).glob("*.json")):  # DamagedFile names a bad one
        r = io.read_json(p, need=("figure", "conditions"))
        if not isinstance(r["conditions"], list) or not all(map(_condition_ok, r["conditions"])):
            raise io.DamagedFile(f"{p}: not a plan record (its conditions are malformed)")
        records.append(r)
    if len(records) > 1:  # a record's digest costs a dump of all its trials
        records.sort(key=lambda r: (r.get("job", 0), record_digest(r)))
    conds, paper = {}, {}
    for r in records:
        for c in r["conditions"]:
            v = c.get("variant")
            conds.setdefault((v["label"] if v else None, c["id"]), c)
        paper = paper or r.get("paper") or {}
    return list(conds.values()), paper, []


def figure_conditions(cache_dir, figure: str) -> tuple[list[dict], dict, list[str]]:
    """group_conditions of a figure's current group; a damaged plan record is a DamagedFile (a
    good aggregate is never replaced by a partial one)."""
    folder = Path(cache_dir) / PLANS / figure
    group = read_current(folder)
    if group is None:
        raise FileNotFoundError(f"figure={figure}: not simulated (no plan under {folder})")
    conds, paper, problems = group_conditions(folder, group)
    if not conds:
        raise io.DamagedFile(f"figure={figure}: no plan record under {folder / group}; run "
                             "pipeline.simulate for this figure again")
    return conds, paper, problems


def figures(cache_dir) -> list[str]:
    return sorted(p.parent.name for p in (Path(cache_dir) / PLANS).glob("*/current.json"))


TIMES = ("logs", "times")  # under paths.out: the measured CPU seconds of each run's trials


def write_times(out_dir, cpu: dict[str, float]) -> Path | None:
    """One run's CPU seconds per trial key in a file of its own, named by the nanoseconds since
    1970 (they sort as the runs ended); None when the run computed nothing."""
    if not cpu:
        return None
    path = Path(out_dir).joinpath(*TIMES) / f"{time.time_ns()}-{os.getpid()}.json"
    io.write_json(path, {k: round(v, 3) for k, v in cpu.items()}, compact=True)
    return path


def read_times(out_dir) -> dict[str, float]:
    """Trial key -> CPU seconds, a later run's winning; a damaged file is skipped (provenance)."""
    out = {}
    for p in sorted(Path(out_dir).joinpath(*TIMES).glob("*.json")):
        try:
            data = json.loads(p.read_bytes())
        except (OSError, ValueError):
            continue
        if isinstance(data, dict):
            out.update({k: float(v) for k, v in data.items() if isinstance(v, (int, float))})
    return out
