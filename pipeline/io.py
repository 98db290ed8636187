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
                                  ("rel_error", pa.float64()),
                                  ("heldout_abs_error", pa.float64())])  # on the held-out set
LABEL_COLUMNS = LABELS.names
CURVE_COLUMNS = CURVE.names


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


def curve_table(labels: dict, epoch, samples, size, abs_error, rel_error,
                heldout_abs_error) -> pa.Table:
    """One trial's learning curve in the CURVE schema."""
    n = len(epoch)
    cols = [pa.array([labels[f.name]] * n, type=f.type) for f in LABELS]
    cols += [pa.array(np.asarray(v, dtype=np.int64)) for v in (epoch, samples)]
    cols += [pa.array(np.asarray(v, dtype=np.float64))
             for v in (size, abs_error, rel_error, heldout_abs_error)]
    return pa.Table.from_arrays(cols, schema=CURVE)


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
