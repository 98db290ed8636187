"""Content keys: a condition and a trial are named by the hash of what they are (canonical JSON),
never by a label, so the same trial under two figures or two sweeps is computed once."""
from __future__ import annotations

import hashlib
import json


def canonical(obj) -> str:
    return json.dumps(obj, sort_keys=True, separators=(",", ":"))


def stable_hash32(obj) -> int:
    """A 32-bit integer from the canonical JSON of obj: the same on every machine and run."""
    return int.from_bytes(hashlib.sha256(canonical(obj).encode()).digest()[:4], "big")


def condition_id(spec: dict, root_seed: int) -> str:
    """A condition is its settings: the hash of its trial spec and root seed, never a label."""
    return hashlib.sha256(canonical(dict(spec=spec, root_seed=root_seed)).encode()).hexdigest()[:16]


def trial_key(spec: dict, seed: dict, code: str, start: dict | None = None) -> str:
    """A trial is its content: spec, seed, code fingerprint and, for a continuation, its start
    dict(epoch, key) of the base whose saved state it continues (pipeline.checkpoint)."""
    content = dict(spec=spec, seed=seed, code=code)
    if start is not None:
        content["start"] = start
    return hashlib.sha256(canonical(content).encode()).hexdigest()[:20]
