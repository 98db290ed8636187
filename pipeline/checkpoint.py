"""A base trial's final state, from which its continuations start (gbmodel.Checkpoint; planned
by conditions.continues): the learner's and the generator's state, and the base's cached curve
and snapshots; the result is an uninterrupted run's, to the bit. Only a trial planned as a base
keeps it (`keep_state`), in trials/<kk>/<key>.state.json beside its sidecar, sealed, as plain
data (arrays as base64, gbmodel's dataclasses by name, looked up, never imported) that crosses to
a worker like any trial.
A base in the cache without it is run again, before its continuations."""
from __future__ import annotations

import base64
import dataclasses
from pathlib import Path

import numpy as np

SUFFIX = ".state.json"
# the curve columns a continuation takes from its base trial (gbmodel.TrialResult's curves)
CURVE = ("epoch", "size", "abs_error", "rel_error", "heldout_abs_error", "uniform_abs_error",
         "path_abs_error")


def encode(x):
    """A learner's state as plain JSON data (decode inverts it to the bit)."""
    if isinstance(x, np.ndarray):
        return {"array": x.dtype.str, "shape": list(x.shape),
                "data": base64.b64encode(np.ascontiguousarray(x).tobytes()).decode()}
    if isinstance(x, np.generic):
        return {"scalar": encode(np.asarray(x))}
    if dataclasses.is_dataclass(x) and not isinstance(x, type):
        kind = type(x)
        return {"dataclass": f"{kind.__module__}:{kind.__qualname__}",
                "fields": {f.name: encode(getattr(x, f.name)) for f in dataclasses.fields(x)}}
    if isinstance(x, (tuple, list)):
        return {type(x).__name__: [encode(v) for v in x]}
    if isinstance(x, dict):
        return {"dict": [[encode(k), encode(v)] for k, v in x.items()]}
    if isinstance(x, float):
        return {"float": x.hex()}
    if x is None or isinstance(x, (bool, int, str)):
        return x
    raise TypeError(f"a learner's state holds a {type(x).__name__}, which a checkpoint cannot "
                    "keep (arrays, numbers, strings, tuples, lists, dicts and dataclasses)")


def decode(d, kinds: dict):
    """encode's inverse; a dataclass is looked up by name in `kinds` (state_kinds), never
    imported: the file names no code to run."""
    if not isinstance(d, dict):
        return d
    if "array" in d:
        a = np.frombuffer(base64.b64decode(d["data"]), dtype=np.dtype(d["array"]))
        return a.reshape(d["shape"]).copy()
    if "scalar" in d:
        return decode(d["scalar"], kinds)[()]
    if "dataclass" in d:
        if d["dataclass"] not in kinds:
            raise ValueError(f"a checkpoint names {d['dataclass']!r}, not a dataclass of gbmodel")
        return kinds[d["dataclass"]](**{k: decode(v, kinds) for k, v in d["fields"].items()})
    if "tuple" in d:
        return tuple(decode(v, kinds) for v in d["tuple"])
    if "list" in d:
        return [decode(v, kinds) for v in d["list"]]
    if "dict" in d:
        return {decode(k, kinds): decode(v, kinds) for k, v in d["dict"]}
    if "float" in d:
        return float.fromhex(d["float"])
    raise ValueError(f"not a checkpoint's data: keys {sorted(d)}")


def final_state(res) -> dict:
    """What a finished trial keeps for its continuations (a worker's result, plain data): its
    last epoch, the generator's state and the learner's state."""
    return dict(epoch=int(res.epoch[-1]), rng=encode(res.rng), state=encode(res.state))


def path(cache_dir, trial: dict) -> Path:
    from . import cache  # here, not above: a worker only encodes and decodes

    return cache.trial_paths(cache_dir, trial)[1].with_suffix(SUFFIX)


def write(cache_dir, trial: dict, final: dict) -> None:
    """Keep a trial's final state (before its sidecar: a finished trial has it)."""
    from . import io

    io.write_json(path(cache_dir, trial), io.seal(dict(key=trial["key"], **final)), compact=True)


def has(cache_dir, trial: dict) -> bool:
    return path(cache_dir, trial).is_file()


def load(cache_dir, base: dict) -> tuple[dict | None, str | None]:
    """(a finished base's checkpoint as plain data for a worker, None), or (None, why)."""
    from . import cache, io

    side, table, why = cache.read_trial(cache_dir, base)
    if side is None:
        return None, why or f"its base trial {base['key']} is not in the cache"
    if side["status"] != "ok":
        return None, f"its base trial {base['key']} {side['status']}: {side.get('error')}"
    where = path(cache_dir, base)
    try:
        saved = io.check_seal(io.parse_json(where.read_bytes(), where), where)
        if saved.get("key") != base["key"]:
            return None, f"{where.name} belongs to another trial"
    except FileNotFoundError:
        return None, f"its base trial {base['key']} kept no state"
    except (OSError, ValueError) as err:
        return None, str(err)
    curve = {c: table.column(c).to_pylist() for c in CURVE}
    return dict(epoch=saved["epoch"], rng=saved["rng"], state=saved["state"], curve=curve,
                snapshots=side["snapshots"]), None


def state_kinds(learner: str) -> dict:
    """The dataclasses of gbmodel's modules once learner `learner` is imported (its state's
    kinds among them), by encode's name for them: a checkpoint picks a class of these only."""
    import sys

    import gbmodel

    gbmodel.learners.get(learner)
    mods = [m for n, m in list(sys.modules.items()) if n.split(".")[0] == "gbmodel"]
    return {f"{k.__module__}:{k.__qualname__}": k for m in mods for k in vars(m).values()
            if isinstance(k, type) and dataclasses.is_dataclass(k) and k.__module__ == m.__name__}


def checkpoint(data: dict, learner: str):
    """The gbmodel.Checkpoint of load()'s plain data (in the worker), for a trial of `learner`."""
    import gbmodel

    kinds = state_kinds(learner)
    c = data["curve"]
    result = gbmodel.TrialResult(
        **{k: np.asarray(c[k], np.int64 if k == "epoch" else np.float64) for k in CURVE}, M=None,
        snapshots={int(e): np.asarray(m) for e, m in data["snapshots"].items()})
    return gbmodel.Checkpoint(data["epoch"], decode(data["state"], kinds), decode(data["rng"], kinds),
                              result)
