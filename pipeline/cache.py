"""The trial cache: one Parquet learning curve and one JSON sidecar per trial, plus a manifest.

Layout under paths.cache:
    <figure>/<key>.parquet   the learning curve (columns CURVE_COLUMNS)
    <figure>/<key>.json      the trial's config slice, seed, code fingerprint, final M, snapshots
    <figure>/manifest.json   per condition, the trials of the latest simulate run that included it

The key hashes the trial's config slice and gbmodel's code fingerprint (pipeline.plan), so a
trial is computed once and recomputed only when something it depends on changes. Files are
written to a temporary name and renamed, so a file under its final name is always complete; the
Parquet file is renamed last and marks the trial as done.
"""
from __future__ import annotations

import fcntl
import json
import os
from contextlib import contextmanager
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

LABEL_COLUMNS = ["figure", "body", "growth", "growth_period", "condition", "trial"]
CURVE_COLUMNS = LABEL_COLUMNS + ["epoch", "size", "abs_error", "rel_error"]
_INT_COLUMNS = {"growth_period", "trial", "epoch"}
_STR_COLUMNS = {"figure", "body", "growth", "condition"}


# ---- atomic, deterministic writes ------------------------------------------------------------
def _tmp_name(path: Path) -> Path:
    return path.with_name(f".{path.name}.{os.getpid()}.tmp")


@contextmanager
def atomic_path(path: Path):
    """Yield a temporary path beside `path`; rename it onto `path` if the block succeeds."""
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = _tmp_name(path)
    try:
        yield tmp
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)


def write_text(path: Path, text: str) -> None:
    with atomic_path(path) as tmp:
        tmp.write_text(text)


def dump_json(obj) -> str:
    return json.dumps(obj, sort_keys=True, indent=1) + "\n"


def write_table(path: Path, table: pa.Table) -> None:
    """Parquet with fixed settings and no timestamps: the same table gives the same bytes."""
    with atomic_path(path) as tmp:
        pq.write_table(table, tmp, compression="zstd", compression_level=3)


def frame_to_table(df) -> pa.Table:
    return pa.Table.from_pandas(df, preserve_index=False)


def remove_stale_tmp(folder: Path) -> None:
    """Delete temporary files left by a killed process (their pid no longer runs)."""
    for tmp in folder.glob(".*.tmp"):
        pid = tmp.name.rsplit(".", 2)[-2]
        if pid.isdigit() and not _alive(int(pid)):
            tmp.unlink(missing_ok=True)


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


# ---- trials ----------------------------------------------------------------------------------
def trial_paths(cache_dir, trial: dict) -> tuple[Path, Path]:
    folder = Path(cache_dir) / trial["labels"]["figure"]
    return folder / f"{trial['key']}.parquet", folder / f"{trial['key']}.json"


def is_done(cache_dir, trial: dict) -> bool:
    curve, sidecar = trial_paths(cache_dir, trial)
    return curve.exists() and sidecar.exists()


def curve_table(labels: dict, epoch, size, abs_error, rel_error) -> pa.Table:
    n = len(epoch)
    cols = {}
    for name in LABEL_COLUMNS:
        typ = pa.int64() if name in _INT_COLUMNS else pa.string()
        cols[name] = pa.array([labels[name]] * n, type=typ)
    cols["epoch"] = pa.array(np.asarray(epoch, dtype=np.int64))
    for name, values in (("size", size), ("abs_error", abs_error), ("rel_error", rel_error)):
        cols[name] = pa.array(np.asarray(values, dtype=np.float64))
    return pa.table(cols)


def write_trial(cache_dir, trial: dict, result: dict) -> None:
    """Store a finished trial: the sidecar first, then the curve (the done marker)."""
    curve, sidecar = trial_paths(cache_dir, trial)
    side = dict(trial)
    side["M"] = np.asarray(result["M"]).tolist()
    side["snapshots"] = {str(e): np.asarray(M).tolist() for e, M in sorted(result["snapshots"].items())}
    write_text(sidecar, dump_json(side))
    write_table(curve, curve_table(trial["labels"], result["epoch"], result["size"],
                                   result["abs_error"], result["rel_error"]))


def read_sidecar(path) -> dict:
    return json.loads(Path(path).read_text())


# ---- manifest --------------------------------------------------------------------------------
@contextmanager
def _locked(folder: Path):
    """An exclusive lock on the figure's folder (parallel Hydra jobs share the manifest)."""
    folder.mkdir(parents=True, exist_ok=True)
    with open(folder / ".lock", "w") as fh:
        fcntl.flock(fh, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(fh, fcntl.LOCK_UN)


def manifest_path(cache_dir, figure: str) -> Path:
    return Path(cache_dir) / figure / "manifest.json"


def update_manifest(cache_dir, figure: str, paper: dict, trials: list[dict],
                    failed: dict[str, str], replace: bool) -> None:
    """Record the conditions of this run. replace=True: they become the figure's conditions (a
    whole experiment). replace=False: each replaces that condition's previous entry and the
    others stay, so a multirun over growth periods builds one figure from many jobs."""
    path = manifest_path(cache_dir, figure)
    with _locked(path.parent):
        man = {"figure": figure, "conditions": {}}
        if path.exists() and not replace:
            man = json.loads(path.read_text())
        if replace or "paper" not in man:  # a single-condition run keeps the figure's paper info
            man["paper"] = paper
        fresh = {}
        for t in trials:
            c = fresh.setdefault(t["labels"]["condition"], {
                "labels": {k: t["labels"][k] for k in LABEL_COLUMNS if k != "trial"},
                "spec": t["spec"], "trials": {}})
            entry = {"key": t["key"], "status": "failed" if t["key"] in failed else "ok"}
            if t["key"] in failed:
                entry["error"] = failed[t["key"]]
            c["trials"][str(t["labels"]["trial"])] = entry
        man["conditions"].update(fresh)
        write_text(path, dump_json(man))


def read_manifests(cache_dir) -> list[dict]:
    """Every figure's manifest under the cache, sorted by figure name."""
    return [json.loads(p.read_text()) for p in sorted(Path(cache_dir).glob("*/manifest.json"))]
