"""Every file the pipeline writes goes through here: atomic, deterministic writes, and the schema
of the learning-curve table.

A file under its final name is always complete: it is written to a temporary name beside it and
renamed. Parquet is written with fixed settings and no timestamps, JSON with sorted keys, so the
same content gives the same bytes.
"""
from __future__ import annotations

import hashlib
import json
import os
from contextlib import contextmanager
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

# The learning curve of one trial (and, concatenated, of a figure). External scripts read these.
LABELS = pa.schema([("figure", pa.string()), ("body", pa.string()), ("learner", pa.string()),
                    ("growth", pa.string()), ("growth_period", pa.int64()),
                    ("condition", pa.string()), ("trial", pa.int64())])
CURVE = pa.schema(list(LABELS) + [("epoch", pa.int64()), ("samples", pa.int64()),
                                  ("size", pa.float64()), ("abs_error", pa.float64()),
                                  ("rel_error", pa.float64())])
LABEL_COLUMNS = LABELS.names
CURVE_COLUMNS = CURVE.names
# One trial's curve as the cache keeps it: its content only (a cached trial may serve several
# figures and conditions; aggregate adds the labels of the figure that uses it).
TRIAL_CURVE = pa.schema([f for f in CURVE if f.name not in LABELS.names])


def _tmp_name(path: Path) -> Path:
    return path.with_name(f".{path.name}.{os.getpid()}.tmp")


@contextmanager
def atomic_path(path):
    """Yield a temporary path beside `path`; rename it onto `path` if the block succeeds."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = _tmp_name(path)
    try:
        yield tmp
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)


@contextmanager
def new_dir(final):
    """Yield an empty folder beside `final`; if the block succeeds, it replaces `final` as one
    set (two renames: the old set aside, the new one in, then the old one removed). A reader, or a
    process killed at any moment, sees the old set, the new set or none, never a mix; a leftover
    folder of a killed run is removed by the next."""
    import shutil

    final = Path(final)
    final.parent.mkdir(parents=True, exist_ok=True)
    for stale in final.parent.glob(f".{final.name}.*.dir"):
        pid = stale.name.rsplit(".", 2)[-2].rsplit("-", 1)[-1]
        if not (pid.isdigit() and _alive(int(pid))):
            shutil.rmtree(stale, ignore_errors=True)
    tmp = final.with_name(f".{final.name}.new-{os.getpid()}.dir")
    old = final.with_name(f".{final.name}.old-{os.getpid()}.dir")
    shutil.rmtree(tmp, ignore_errors=True)
    tmp.mkdir()
    try:
        yield tmp
        if final.exists():
            os.rename(final, old)
        os.rename(tmp, final)
        shutil.rmtree(old, ignore_errors=True)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


def write_text(path, text: str) -> None:
    with atomic_path(path) as tmp:
        tmp.write_text(text)


def dump_json(obj) -> str:
    return json.dumps(obj, sort_keys=True, indent=1) + "\n"


def write_json(path, obj) -> None:
    write_text(path, dump_json(obj))


def read_json(path) -> dict:
    """The JSON object in `path`; ValueError naming the file if it is not one."""
    try:
        obj = json.loads(Path(path).read_text())
    except (json.JSONDecodeError, UnicodeDecodeError) as err:
        raise ValueError(f"{path}: not valid JSON ({err})") from None
    if not isinstance(obj, dict):
        raise ValueError(f"{path}: not a JSON object")
    return obj


def write_table(path, table: pa.Table) -> None:
    """Parquet with fixed settings and no timestamps: the same table gives the same bytes."""
    with atomic_path(path) as tmp:
        pq.write_table(table, tmp, compression="zstd", compression_level=3)


def frame_to_table(df) -> pa.Table:
    return pa.Table.from_pandas(df, preserve_index=False)


def trial_curve_table(result: dict) -> pa.Table:
    """One trial's learning curve in the TRIAL_CURVE schema (a worker's result)."""
    return pa.Table.from_arrays(
        [pa.array(np.asarray(result[f.name]), type=f.type) for f in TRIAL_CURVE],
        schema=TRIAL_CURVE)


def is_plain_name(name) -> bool:
    """A name that can become one path component: no separator, not hidden, not empty."""
    return (isinstance(name, str) and bool(name) and "/" not in name and "\\" not in name
            and not name.startswith(".") and "\0" not in name)


def sha256_file(path) -> str:
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def remove_stale_tmp(folder) -> None:
    """Delete temporary files left by a killed process (their pid no longer runs)."""
    for tmp in Path(folder).glob(".*.tmp"):
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
