"""The paper's claims (docs/scorecard.md): the register of criteria (register.yaml), checked
against its declared schema before any of it is used (`read_register`: each fault one ValueError
naming the file and the key), each claim's measure per trial before any criterion (`measures`;
a maximum over epochs of a mean curve has no fixed value to estimate) and the register's
readings applied to it (`judge`: the same Measure with the reading's bounds)."""
from __future__ import annotations

import datetime
import hashlib
import json
import math
import os
import stat
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
import pandas as pd
import yaml

from gbmodel.growth import factors

from .. import measures as curve_measures
from .figures import final_body

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


def read_register(path) -> dict:
    """The register file checked against its schema (a ValueError names the file and key)."""
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


SMOOTH = 5  # rebounds and blending: each trial's curve averaged over this many evaluation points
# where the absolute error is measured (a reading's params.points), every trial scoring all three
POINTS = {"grid": "abs_error", "path": "path_abs_error", "uniform": "uniform_abs_error"}
LAST_DECADE = "last decade"  # a final error's span: its mean over the last decade of epochs
DIVERGED = "diverged"  # a condition none of whose trials left a curve, and the cells it touches
FLAGS = ("primary", "diagnostic", "always_shown", "first")


@dataclass(frozen=True)
class Reading:
    id: str
    label: str
    criterion: str
    why: str
    params: dict
    fixed_at: str
    primary: bool = False
    diagnostic: bool = False  # shown and marked, never counted
    always_shown: bool = False  # shown beside the primary's verdict even where it agrees
    first: bool = False  # the claim's criterion as first fixed, before the first run's data


@dataclass(frozen=True)
class Claim:
    id: str
    words: str  # the claim in short, as the paper states it
    figures: str
    sentence: str
    measure: str  # what is measured on each trial, in words
    readings: tuple  # of Reading, the primary first
    diagnostic: bool = False  # added by us: shown and marked, never counted
    min_trials: int = 2  # fewer trials: inconclusive, whatever the interval
    changelog: tuple = ()
    our_reading: dict | None = None  # the project's reading in words: text, written_for

    @property
    def primary(self) -> Reading:
        return self.readings[0]

    @property
    def criterion(self) -> str:
        return self.primary.criterion


def load_register(path: Path = REGISTER) -> list[Claim]:
    """The claims of a register file (read_register's), each with exactly one primary."""
    out = []
    for e in read_register(path)["claims"]:
        rs = sorted((Reading(str(r["id"]), r.get("label", r["id"]), r["criterion"],
                             r.get("why", ""), dict(r.get("params") or {}),
                             str(r.get("fixed_at", "")), **{k: bool(r.get(k)) for k in FLAGS})
                     for r in e["readings"]), key=lambda r: not r.primary)
        if sum(r.primary for r in rs) != 1:
            raise ValueError(f"{path}: claim {e['id']!r} needs exactly one primary reading")
        out.append(Claim(e["id"], e["words"], e["figures"], e.get("sentence", ""), e["measure"],
                         tuple(rs), bool(e.get("diagnostic")), int(e.get("min_trials", 2)),
                         tuple(e.get("changelog", [])), e.get("our_reading")))
    return out


CLAIMS = load_register()
BY_ID = {c.id: c for c in CLAIMS}
RISE = BY_ID["rise"].primary.params["above"]  # a temporary rise: above this fraction


def diverged_conditions(summary: pd.DataFrame) -> list[str]:
    """The conditions none of whose trials left a curve (no per-trial value to judge)."""
    if "n_trials" not in summary:
        return []
    return [str(c) for c in summary.loc[summary["n_trials"] == 0, "condition"]]


@dataclass
class Measure:
    """One measure on one condition of a figure, a value per trial; judged (`judge`), its mean
    (with a control: minus the control's) must lie in [lo, hi]."""

    figure: str
    claim: str  # judged: the reading's claim; `measure` the claim whose measure it is
    where: str
    values: np.ndarray
    lo: float = -np.inf
    hi: float = np.inf
    unit: str = "%"  # how the value prints: "%" (a fraction), "x" (a ratio), "m", "rad", "rate"
    kind: str = ""
    size: float = 1.0  # the condition's final size over the figure's full size
    period: int = 0  # its T_G (0: no growth)
    control: np.ndarray | None = None  # the measure on the constant full-size reference's trials
    exact: bool = False  # a count (values: failed, total): judged exactly
    diverged: bool = False  # the condition (or a reference it needs) left no curve
    calibrated: tuple | None = None  # (t level or None, why) once known (measures.parquet)
    points: str = "grid"  # where the error is measured (POINTS)
    span: str = "end"  # the final error: at the last evaluation, or LAST_DECADE
    reading: str = ""  # judged: the register's reading ("": the primary)
    measure: str = ""
    diagnostic: bool = False
    min_trials: int = 2


Test = Measure  # a Measure judged under a reading (`judge`)


def per_trial(trials: pd.DataFrame, condition: str, column: str) -> tuple[np.ndarray, np.ndarray]:
    """(epochs, values[trial, epoch]) of one condition, as DataFrame.pivot and dropna give them."""
    c = trials.iloc[_rows_of(trials, condition)]
    ts, ti = np.unique(c["trial"].to_numpy(), return_inverse=True)
    es, ei = np.unique(c["epoch"].to_numpy(), return_inverse=True)
    if np.unique(ti * len(es) + ei).size < len(c):
        raise ValueError(f"{condition}: a trial has an epoch twice: no curve per trial")
    values = np.full((len(ts), len(es)), np.nan)
    values[ti, ei] = c[column].to_numpy(np.float64)
    keep = ~np.isnan(values).any(axis=0)
    return es[keep], values[:, keep]


_SPLIT: list = []  # [(the trials table, {condition: its row positions})], the last one split


def _rows_of(trials: pd.DataFrame, condition: str) -> np.ndarray:
    """The positions of `condition`'s rows, the table grouped once for all its conditions."""
    if not _SPLIT or _SPLIT[0][0] is not trials:
        _SPLIT[:] = [(trials, trials.groupby("condition", sort=False).indices)]
    return _SPLIT[0][1].get(condition, np.array([], dtype=np.intp))


def at(epochs: np.ndarray, ref: tuple) -> np.ndarray:
    """A reference's mean curve at `epochs`, every one of which it must have."""
    idx = np.searchsorted(ref[0], epochs)
    if np.any(idx >= len(ref[0])) or not np.array_equal(ref[0][np.minimum(idx, len(ref[0]) - 1)],
                                                          epochs):
        raise ValueError("a reference condition lacks some epochs of the growing one")
    return ref[1][:, idx].mean(axis=0)


def smooth(v: np.ndarray, k: int = SMOOTH) -> np.ndarray:
    """A moving average over k points (a curve of fewer than 2 k points as it is)."""
    if v.shape[-1] < 2 * k:
        return v
    c = np.cumsum(np.concatenate([np.zeros(v.shape[:-1] + (1,)), v], axis=-1), axis=-1)
    return (c[..., k:] - c[..., :-k]) / k


def rebound(v: np.ndarray) -> np.ndarray:
    """The largest rise above the running minimum, relative to it, along the last axis."""
    return (v / np.minimum.accumulate(v, axis=-1) - 1).max(axis=-1)


def rise(v: np.ndarray) -> np.ndarray:
    """pipeline.measures.rise per trial, relative to the lowest error before it."""
    i, up = curve_measures.rise(v)
    base = np.take_along_axis(v, i[..., None], -1)[..., 0] - up
    return np.where(base > 0, up / np.where(base > 0, base, 1), 0.0)


def excess(v: np.ndarray, ref: np.ndarray) -> np.ndarray:
    return (v / ref - 1).max(axis=-1)


def blend(v: np.ndarray, short: np.ndarray, long_: np.ndarray) -> np.ndarray:
    return np.maximum(excess(v, np.maximum(short, long_)), np.abs(v[..., -1] / long_[-1] - 1))


def _places(claim: str) -> list[tuple[str, str]]:
    """(points, span) of each measure of a claim."""
    spans = ("end", LAST_DECADE) if claim == "final" else ("end",)
    return [(p, s) for p in POINTS for s in spans] if claim in ("final", "rise") else \
        [("grid", "end")]


def _diverged_measures(figure: str, summary: pd.DataFrame, dead: list, n_refs: int,
                       has_paper: bool) -> list[Measure]:
    out = []
    for r in summary[summary["condition"].isin(dead)].itertuples():
        touched = (["final"] if has_paper else []) + (
            ["rise", "after", "during"] if r.growth != "none" else []) + (
            ["blend"] if n_refs == 2 else [])
        out += [Measure(figure, claim, r.condition, np.array([]), diverged=True,
                        period=int(r.growth_period) if r.growth != "none" else 0,
                        size=float(r.end_size) / float(summary["end_size"].max()),
                        points=p, span=s)
                for claim in touched for p, s in _places(claim)]
    return out


def measures(figure: str, trials: pd.DataFrame, summary: pd.DataFrame) -> list[Measure]:
    """Every claim's measure on one growth figure (Fig. 4, 5, 7), one per condition it covers."""
    every = summary
    paper = summary["paper_final_abs_error"].iloc[0] if len(summary) else np.nan
    dead = diverged_conditions(summary)
    n_refs = int((summary["growth"] == "none").sum())
    out = _diverged_measures(figure, summary, dead, n_refs, bool(np.isfinite(paper)))
    summary = summary[~summary["condition"].isin(dead)]
    refs = summary[summary["growth"] == "none"].sort_values("end_size")
    two_refs = len(refs) == n_refs == 2  # the comparisons with the references need both
    at_points = {p: {c: per_trial(trials, c, col) for c in summary["condition"]}
                 for p, col in POINTS.items() if col in trials}
    abs_ = at_points["grid"]
    rel = {c: per_trial(trials, c, "rel_error") for c in summary["condition"]}
    full = float(every["end_size"].max()) if len(every) else 1.0
    if np.isfinite(paper):
        for p, curves in at_points.items():
            for r in summary.itertuples():
                ep, v = curves[r.condition]
                for span, x in (("end", v[:, -1]), (LAST_DECADE, v[:, ep >= ep[-1] / 10].mean(1))):
                    out.append(Measure(figure, "final", r.condition, x / paper, unit="x",
                                       kind="final", size=float(r.end_size) / full, points=p,
                                       span=span))
    short, control = refs["condition"] if two_refs else (None, None)
    for r in summary[summary["growth"] != "none"].itertuples():
        c, period = r.condition, int(r.growth_period)
        (ep, g), gr = abs_[c], rel[c][1]
        during, after = ep <= period + 1, ep >= period + 1

        def ctrl(fn, curves):  # the same measure on the control's trials over the same epochs
            if control is None:
                return None
            cep, cv = curves[control]
            keep = np.isin(cep, ep)
            return fn(cv[:, keep]) if np.array_equal(cep[keep], ep) else None

        def add(claim, where, values, kind="rebound", **kw):
            out.append(Measure(figure, claim, where, values, kind=kind, period=period, **kw))
        for p, curves in at_points.items():  # the rise wherever the error is measured
            add("rise", c, rise(curves[c][1][:, during]), points=p,
                control=ctrl(lambda v: rise(v[:, during]), curves))
        if two_refs:
            s_, l_ = at(ep[during], abs_[short]), at(ep[during], abs_[control])
            add("above_start", c, excess(g[:, during], s_), "excess")
            add("above_refs", c, excess(g[:, during], np.maximum(s_, l_)), "excess")
            bands = (smooth(at(ep, rel[short])), smooth(at(ep, rel[control])))
            add("blend", c, blend(smooth(gr), *bands), "excess",
                control=ctrl(lambda v: blend(smooth(v), *bands), rel))
        if after.sum() >= 2:
            add("after", c + " rebound", rebound(smooth(gr[:, after])),
                control=ctrl(lambda v: rebound(smooth(v[:, after])), rel))
            add("after", c + " end / start", gr[:, after][:, -1] / gr[:, after][:, 0], "ratio",
                unit="x")
        add("during", c, rebound(smooth(gr[:, during])))
    lost = every.get("n_diverged", pd.Series(dtype=int)).sum() + every["n_run_failures"].sum()
    fails = int(every["n_bootstrap_failures"].sum() + lost)
    total = int(every["n_trials"].sum() + lost)
    out.append(Measure(figure, "bootstrap", f"{fails} of {total} trials failed",
                       np.array([fails, total]), unit="rate", exact=True))
    return out


def stage_measures(figure: str, spec: dict, trials: list[list]) -> list[Measure]:
    """Fig. 2's measures over trials (each trial's M per stage, the final M last)."""
    body, size, pattern, predict = final_body(spec)
    xs = body.target_set(size)
    spread, extreme = [], []
    for stages in trials:
        q = [predict(np.asarray(M), xs) for M in stages]
        spread.append([float(np.abs(x - body.home).max()) for x in q])
        err = np.linalg.norm(body.forward(q[-1], factors(body, size, pattern)) - xs, axis=-1)
        extreme.append(float(max(err[0], err[-1])))
    spread, extreme = np.array(spread), np.array(extreme)
    return [Measure(figure, "stages", "final error at the worse extreme", extreme, unit="m",
                    kind="final"),
            Measure(figure, "stages_home", "deviation from home after epoch 1", spread[:, 0],
                    unit="rad", kind="final"),
            Measure(figure, "stages_spread", "smallest growth of the spread",
                    np.diff(spread, axis=-1).min(axis=-1), unit="rad", kind="excess")]


def _bounds(claim: str, m: Measure, p: dict) -> tuple[float, float] | None:
    """[lo, hi] of a measure under a reading's params; None for a T_G outside its periods."""
    if ("from" in p or "up_to" in p) and not (
            m.period and p.get("from", 0) <= m.period <= p.get("up_to", np.inf)):
        return None
    if claim == "final":
        side = p["full"] if m.size >= 1 - 1e-9 else p["smaller"]
        return (1 / p["factor"] if side == "two-sided" else -np.inf), p["factor"]
    if "above" in p:
        return p["above"], np.inf
    if "below" in p:
        return -np.inf, p["below"] - (1e-12 if claim == "stages" else 0)
    if claim == "after":
        return -np.inf, p["rebound_below"] if m.kind == "rebound" else \
            p["end_over_start_below"] - 1e-12
    if "within_m" in p:
        return -np.inf, p["within_m"] - 1e-12
    if "within_rad" in p:
        return -np.inf, p["within_rad"]
    if "grows_by_rad" in p:
        return p["grows_by_rad"], np.inf
    return -np.inf, np.inf


SERVES = {"rise": ("rise", "rise_none")}  # a measure that serves more than its own claim


def judge(ms: list[Measure], claims: list[Claim] | None = None) -> list[Measure]:
    """Every measure under every reading of `claims` (default: this register's) that judges it."""
    by = {c.id: c for c in (CLAIMS if claims is None else claims)}
    out = []
    for m in ms:
        for c in (by[k] for k in SERVES.get(m.claim, (m.claim,)) if k in by):
            for r in c.readings:
                p = r.params
                if (m.points, m.span) != (p.get("points", "grid"), p.get("span", "end")):
                    continue  # measured elsewhere than where this reading measures
                b = _bounds(c.id, m, p) if not m.exact else (-np.inf, np.inf)
                if b is None or (p.get("control") and m.control is None and not m.diverged):
                    continue  # not judged: another T_G; no control (an end over its start)
                out.append(replace(
                    m, claim=c.id, lo=b[0], hi=b[1], reading="" if r.primary else r.id,
                    values=m.values / m.size if p.get("scale") == "size" else m.values,
                    measure=m.claim, min_trials=c.min_trials,
                    control=m.control if p.get("control") else None,
                    diagnostic=c.diagnostic or r.diagnostic))
    return out
