"""Content keys: a condition and a trial are named by the hash of what they are (canonical JSON),
never by a label, so the same trial under two figures or two sweeps is computed once; and seals,
the hash of a whole record kept in it.
"""
from __future__ import annotations

import hashlib
import json

from .errors import DamagedFile


def canonical(obj) -> str:
    return json.dumps(obj, sort_keys=True, separators=(",", ":"))


def stable_hash32(obj) -> int:
    """A 32-bit integer from the canonical JSON of obj: the same on every machine and run."""
    return int.from_bytes(hashlib.sha256(canonical(obj).encode()).digest()[:4], "big")


def condition_id(spec: dict, root_seed: int) -> str:
    """A condition is its settings: the hash of its trial spec (body, growth, learner,
    evaluation, epochs, snapshots) and the root seed, never a label."""
    return hashlib.sha256(canonical(dict(spec=spec, root_seed=root_seed)).encode()).hexdigest()[:16]


def trial_key(spec: dict, seed: dict, code: str, start: dict | None = None) -> str:
    """A trial is its content: spec, seed and code fingerprint. The figure, the condition's
    label or the variant that asked for it are not part of it, so the same trial under two
    figures or two sweeps is computed once. start: a continuation's base, dict(epoch, key) (the
    trial whose saved state it continues: pipeline.checkpoint)."""
    content = dict(spec=spec, seed=seed, code=code)
    if start is not None:
        content["start"] = start
    return hashlib.sha256(canonical(content).encode()).hexdigest()[:20]


# ---- a checksum over a whole record --------------------------------------------------------------
SEAL = "seal"


def _encoded(record: dict) -> dict[str, str]:
    """Each member of `record` but the seal as canonical JSON text, `"key":value` (sorted keys
    within, no spaces): joined in key order between braces, json.dumps's text of the record."""
    enc = _COMPACT.encode
    return {k: f"{enc(k)}:{enc(v)}" for k, v in record.items() if k != SEAL}


def _joined(items: dict[str, str]) -> str:
    return "{" + ",".join(items[k] for k in sorted(items)) + "}"


def _sha_of(items: dict[str, str]) -> str:
    """The seal of a record's _encoded items: the SHA-256 of its canonical JSON without it."""
    return hashlib.sha256(_joined(items).encode()).hexdigest()


def sealed_json(record: dict) -> bytes:
    """The file write_json(path, seal(record), compact=True) writes, with each value of
    `record` encoded once (seal and write_json encode the whole record each)."""
    items = _encoded(record)
    items[SEAL] = f"{_COMPACT.encode(SEAL)}:{_COMPACT.encode(_sha_of(items))}"
    return (_joined(items) + "\n").encode()


_COMPACT = json.JSONEncoder(sort_keys=True, separators=(",", ":"), allow_nan=True)


def seal(record: dict) -> dict:
    """`record` with `seal`: the SHA-256 of everything else in it (canonical JSON), so that an
    edit of any field (a sidecar's model M, snapshots, status, error) is caught by check_seal."""
    return {**record, SEAL: _sha_of(_encoded(record))}


def check_seal(record: dict, path=None) -> dict:
    """`record` if its seal matches its content, else DamagedFile naming `path`."""
    where = f"{path}: " if path is not None else ""
    if SEAL not in record:
        raise DamagedFile(f"{where}damaged or of an older version: no seal")
    if record[SEAL] != _sha_of(_encoded(record)):
        raise DamagedFile(f"{where}damaged: its content does not match its seal")
    return record
