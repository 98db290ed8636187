"""The schema of a register of criteria (register.yaml, or an edited copy for rescore), checked
before any of it is used: a regular file of at most MAX_BYTES of plain YAML, {claims: [CLAIM],
recommended: [RECOMMENDED]}, each mapping of its schema's keys (NEEDED ones required), params
of PARAMS, numbers finite and in range; each fault one ValueError naming the file and the key.
"""
from __future__ import annotations

import datetime
import hashlib
import json
import math
import os
import stat
from pathlib import Path

import yaml

REGISTER = Path(__file__).parent / "register.yaml"
MAX_BYTES = 2**20  # the committed register is 19 kB
TEXT, FLAG, CHILDREN = "text", "true or false", "a list of mappings"
TEXTS, MAPPING = "a list of texts", "a mapping"
CLAIM = dict(id=TEXT, words=TEXT, figures=TEXT, sentence=TEXT, measure=TEXT, diagnostic=FLAG,
             min_trials=(1, 1000), readings=CHILDREN, changelog=CHILDREN, our_reading=MAPPING)
OUR_READING = dict(text=TEXT, written_for=MAPPING)
RECOMMENDED = dict(figure=TEXT, reading=TEXT, reproduces=TEXTS, why=TEXT)
READING = dict(id=TEXT, label=TEXT, criterion=TEXT, why=TEXT, fixed_at=TEXT, primary=FLAG,
               diagnostic=FLAG, always_shown=FLAG, first=FLAG, params=MAPPING)
CHANGELOG = dict(date=TEXT, commit=TEXT, reason=TEXT, before=TEXT, after=TEXT, hash=TEXT)
NEEDED = dict(claim=("id", "words", "figures", "measure", "readings"),
              reading=("id", "criterion"), changelog=(), our_reading=("text", "written_for"),
              recommendation=("figure", "reading", "reproduces", "why"))
# a reading's params (claims._bounds and claims.judge read exactly these): a choice, or a
# number's closed range [lo, hi]
SIDES = ("two-sided", "at-most")
PARAMS = dict(scale=("metres", "size"), full=SIDES, smaller=SIDES, control=FLAG,
              factor=(1.0, 1e3), above=(0.0, 1e6), below=(0.0, 1e6), rebound_below=(0.0, 1e6),
              end_over_start_below=(0.0, 1e6), within_m=(0.0, 1e3), within_rad=(0.0, 1e3),
              grows_by_rad=(0.0, 1e3), points=("grid", "path", "uniform"),
              span=("end", "last decade"),
              **{"from": (0, 2**63 - 1), "up_to": (0, 2**63 - 1)})
NEEDED_PARAMS = dict(final=("factor", "full", "smaller"),
                     after=("rebound_below", "end_over_start_below"))


def _fail(path, where, value, why) -> ValueError:
    text = repr(value)
    return ValueError(f"{path}: {where}={text[:60] + '...' if len(text) > 60 else text}: {why}")


def read_text(path) -> str:
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK)  # a FIFO: opened, never waited on
    except OSError as err:
        raise ValueError(f"{path}: cannot read the register: {err.strerror}") from None
    with os.fdopen(fd, "rb") as fh:
        info = os.fstat(fh.fileno())
        ok = stat.S_ISREG(info.st_mode) and info.st_size <= MAX_BYTES
        raw = fh.read(MAX_BYTES + 1) if ok else b""
    if not ok or len(raw) > MAX_BYTES:
        raise ValueError(f"{path}: not a regular file of at most {MAX_BYTES:,} bytes "
                         f"({info.st_size:,} bytes)")
    try:
        return raw.decode("utf-8")
    except UnicodeDecodeError as err:
        raise ValueError(f"{path}: not UTF-8 (byte {err.start})") from None


def load(path) -> dict:
    try:
        data = yaml.safe_load(read_text(path))
    except (yaml.YAMLError, RecursionError) as err:  # RecursionError: nested too deeply
        why = " ".join(str(err).split()) or "nested too deeply"
        raise ValueError(f"{path}: not a register ({type(err).__name__}: {why[:200]})") from None
    if not isinstance(data, dict) or not {"claims"} <= set(data) <= {"claims", "recommended"}:
        raise _fail(path, "top level", sorted(data) if isinstance(data, dict) else
                    type(data).__name__, "a register is a mapping {claims: [...]}")
    if not isinstance(data["claims"], list) or not data["claims"]:
        raise _fail(path, "claims", data["claims"], "a list of at least one claim")
    for i, claim in enumerate(data["claims"]):
        _entry(path, f"claims[{i}]", claim, CLAIM, "claim")
        for j, r in enumerate(claim["readings"]):
            _entry(path, f"claims[{i}].readings[{j}]", r, READING, "reading")
            _entry(path, f"claims[{i}].readings[{j}].params", r.get("params") or {}, PARAMS,
                   "param", NEEDED_PARAMS.get(claim["id"], ()), f"a reading of {claim['id']}")
        for j, c in enumerate(claim.get("changelog") or ()):
            _entry(path, f"claims[{i}].changelog[{j}]", c, CHANGELOG, "changelog")
        if "our_reading" in claim:
            _entry(path, f"claims[{i}].our_reading", claim["our_reading"], OUR_READING,
                   "our_reading")
            for f, v in claim["our_reading"]["written_for"].items():
                _value(path, f"claims[{i}].our_reading.written_for.{f}", v, TEXT)
    _value(path, "recommended", data.get("recommended", []), CHILDREN)
    for i, r in enumerate(data.get("recommended", [])):
        _entry(path, f"recommended[{i}]", r, RECOMMENDED, "recommendation")
    return data


def _entry(path, where, entry, schema: dict, kind: str, needed=None, who=None) -> None:
    if not isinstance(entry, dict):
        raise _fail(path, where, entry, f"a {kind} is a mapping")
    for key in NEEDED[kind] if needed is None else needed:
        if key not in entry:
            raise _fail(path, f"{where}.{key}", None, f"{who or 'a ' + kind} needs {key}")
    for key, value in entry.items():
        if key not in schema:
            raise _fail(path, f"{where}.{key}", value, f"not a {kind}; they are {sorted(schema)}"
                        if kind == "param" else f"not a key of a {kind}; it has {sorted(schema)}")
        _value(path, f"{where}.{key}", value, schema[key])


def _value(path, where, value, want) -> None:
    """`value` of the kind `want`: TEXT (a changelog's commit or date may read as a number or a
    date), FLAG, CHILDREN, TEXTS, MAPPING, a tuple of choices or a range (lo, hi)."""
    if want == TEXT:
        ok = isinstance(value, str) or (where.endswith((".commit", ".date"))
                                        and isinstance(value, (int, datetime.date)))
    elif want == FLAG:
        ok = isinstance(value, bool)
    elif want in (CHILDREN, TEXTS):
        ok = isinstance(value, list) and all(isinstance(v, dict if want == CHILDREN else str)
                                             for v in value)
    elif isinstance(want, str):
        ok = isinstance(value, dict)
    elif isinstance(want[0], str):
        ok = value in want
        want = f"one of {list(want)}"
    else:
        ok = _within(value, *want)
        want = (f"an integer in [{want[0]:,}, {want[1]:,}]" if isinstance(want[0], int)
                else f"a finite number in [{want[0]:g}, {want[1]:g}]")
    if not ok:
        raise _fail(path, where, value, f"must be {want}")


def _within(value, lo, hi) -> bool:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or (
            isinstance(lo, int) and not isinstance(value, int)):
        return False
    try:
        return math.isfinite(float(value)) and lo <= value <= hi
    except OverflowError:  # an integer of hundreds of digits
        return False


HASHED = ("id", "diagnostic", "min_trials", "readings")  # what a changelog entry must cover
HASHED_READING = ("id", "primary", "diagnostic", "params")


def criterion_hash(entry: dict) -> str:
    """The hash of a claim's criterion (HASHED, each reading's HASHED_READING): what its latest
    changelog entry must record."""
    keep = {k: entry.get(k) for k in HASHED}
    keep["readings"] = [{k: r.get(k) for k in HASHED_READING} for r in entry.get("readings", [])]
    return hashlib.sha256(json.dumps(keep, sort_keys=True).encode()).hexdigest()[:12]


def unlogged(path=REGISTER) -> list[str]:
    """What the register's test reports: the claims whose criterion changed without a changelog
    entry (the latest entry's hash is not the criterion's), entries that lack a field."""
    data = yaml.safe_load(Path(path).read_text())
    out = []
    for e in data["claims"]:
        log = e.get("changelog") or []
        if not log or log[-1].get("hash") != criterion_hash(e):
            out.append(f"{e['id']}: criterion {criterion_hash(e)} has no changelog entry "
                       "(add one: date, commit, reason, before, after, hash)")
        out += [f"{e['id']}: changelog entry {i} lacks {k!r}" for i, x in enumerate(log)
                for k in ("date", "commit", "reason", "before", "after") if not x.get(k)]
        out += [f"{e['id']}: reading {r.get('id')!r} lacks {k!r}" for r in e.get("readings", [])
                for k in ("criterion", "why", "fixed_at") if not r.get(k)]
    return out
