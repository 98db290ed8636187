"""The declared schema of a register of criteria (register.yaml), checked before any of it is
used: a register is data, and an edited copy is what `python -m pipeline.tools.rescore
--register FILE` reads.

A register is a regular file of at most MAX_BYTES (checked before it is parsed), YAML of plain
data (`yaml.safe_load`: no tag builds an object; nesting too deep for the parser is one line):
a mapping {claims: [claim, ...], recommended: [...]}; each claim a mapping of CLAIM's keys, its
readings mappings of READING's keys, its changelog mappings of CHANGELOG's, its our_reading of
OUR_READING's (written_for: figure -> verdict); each recommendation a mapping of RECOMMENDED's
keys (reproduces: a list of claims); each reading's params only PARAMS'
keys (and the ones NEEDED_PARAMS says its claim reads), each value of its kind and range:
numbers finite and within their bounds (a factor of 0, -1.5, .nan or .inf is refused, so it
never becomes a verdict). Every fault is one ValueError naming the file and the key.
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

MAX_BYTES = 2**20  # the committed register is 19 kB
TEXT, FLAG, CHILDREN = "text", "true or false", "a list of mappings"
TEXTS, MAPPING = "a list of texts", "a mapping"
CLAIM = dict(id=TEXT, words=TEXT, figures=TEXT, sentence=TEXT, measure=TEXT, diagnostic=FLAG,
             min_trials=(1, 1000), readings=CHILDREN, changelog=CHILDREN, our_reading=MAPPING)
OUR_READING = dict(text=TEXT, written_for=MAPPING)
RECOMMENDED = dict(figure=TEXT, reading=TEXT, reproduces=TEXTS, why=TEXT)
READING = dict(id=TEXT, label=TEXT, criterion=TEXT, why=TEXT, fixed_at=TEXT, primary=FLAG,
               diagnostic=FLAG, always_shown=FLAG, first=FLAG, params="a mapping")
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
    """The register's text: a regular file of at most MAX_BYTES, UTF-8 (ValueError, one line)."""
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
    """The register in `path`, checked against the schema (module docstring)."""
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
            _params(path, f"claims[{i}].readings[{j}].params", r.get("params") or {},
                    claim["id"])
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


def _entry(path, where, entry, schema: dict, kind: str) -> None:
    if not isinstance(entry, dict):
        raise _fail(path, where, entry, f"a {kind} is a mapping")
    for key in NEEDED[kind]:
        if key not in entry:
            raise _fail(path, f"{where}.{key}", None, f"a {kind} needs {key}")
    for key, value in entry.items():
        want = schema.get(key)
        if want is None:
            raise _fail(path, f"{where}.{key}", value, f"not a key of a {kind}; it has "
                        f"{sorted(schema)}")
        _value(path, f"{where}.{key}", value, want)


def _params(path, where, params, claim) -> None:
    if not isinstance(params, dict):
        raise _fail(path, where, params, "a mapping of params")
    for key in NEEDED_PARAMS.get(claim, ()):
        if key not in params:
            raise _fail(path, f"{where}.{key}", None, f"a reading of {claim} needs {key}")
    for key, value in params.items():
        if key not in PARAMS:
            raise _fail(path, f"{where}.{key}", value, f"not a param; they are {sorted(PARAMS)}")
        _value(path, f"{where}.{key}", value, PARAMS[key])


def _value(path, where, value, want) -> None:
    """`value` of the kind `want`: TEXT (a string; a changelog's commit or date may read as a number or a date),
    FLAG, CHILDREN (a list of mappings), 'a mapping', a tuple of choices or a range (lo, hi)."""
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
    """The hash of a claim's criterion as the register holds it (its id, diagnostic flag,
    min_trials and every reading's id, primary and diagnostic flags and params): what its latest
    changelog entry must record."""
    keep = {k: entry.get(k) for k in HASHED}
    keep["readings"] = [{k: r.get(k) for k in HASHED_READING} for r in entry.get("readings", [])]
    return hashlib.sha256(json.dumps(keep, sort_keys=True).encode()).hexdigest()[:12]


def unlogged(path) -> list[str]:
    """The claims of a register whose criterion changed without a changelog entry (the latest
    entry's hash is not the criterion's), and entries that lack a field: what the register's
    test reports."""
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
