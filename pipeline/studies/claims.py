"""The paper's claims (docs/scorecard.md): the register of criteria (register.yaml), each
claim's measure per trial before any criterion (`measures`: a Measure per measure and condition;
a maximum over epochs of a mean curve has no fixed value to estimate) and the register's
readings applied to it (`judge`: the same Measure with the reading's bounds)."""
from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
import pandas as pd

from gbmodel.growth import factors

from .. import measures as curve_measures
from . import register_schema
from .register_schema import REGISTER, criterion_hash, unlogged  # noqa: F401 (the register's)
from .figures import final_body

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
    """The claims of a register file (register_schema's), each with exactly one primary."""
    out = []
    for e in register_schema.load(path)["claims"]:
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


def title(claim: str) -> str:
    c = BY_ID[claim]
    return c.words + (" (diagnostic)" if c.diagnostic else "")


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
    t, e, v = c["trial"].to_numpy(), c["epoch"].to_numpy(), c[column].to_numpy()
    if not len(c) or v.dtype != np.float64 or t.dtype.kind not in "iu" or e.dtype.kind not in "iu":
        p = c.pivot(index="trial", columns="epoch", values=column).sort_index(axis=1).dropna(axis=1)
        return p.columns.to_numpy(), p.to_numpy()
    ts, ti = np.unique(t, return_inverse=True)
    es, ei = np.unique(e, return_inverse=True)
    if np.unique(ti * len(es) + ei).size < len(c):
        raise ValueError(f"{condition}: a trial has an epoch twice: no curve per trial")
    values = np.full((len(ts), len(es)), np.nan)
    values[ti, ei] = v
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


def markdown() -> str:
    lines = ["| claim | figures | criterion (on the mean over trials) | measure, per trial |",
             "|---|---|---|---|"]
    lines += [f"| {title(c.id)} | {c.figures} | {c.criterion} | {c.measure} |" for c in CLAIMS]
    return "\n".join(lines) + "\n"


def readings_markdown() -> str:
    lines = ["| claim | reading | criterion | counted | why (the paper's words) | fixed at |",
             "|---|---|---|---|---|---|"]
    for c in CLAIMS:
        for r in c.readings:
            counted = ("primary" if r.primary and not c.diagnostic else
                       "diagnostic" if r.diagnostic or c.diagnostic else "shown where it differs")
            lines.append(f"| {title(c.id)} | {r.label} | {r.criterion} | {counted} "
                         f"| {' '.join(r.why.split())} | {r.fixed_at} |")
    return "\n".join(lines) + "\n"


def our_reading(cards: pd.DataFrame, register: list[Claim] | None = None) -> dict:
    """claim -> our reading where every verdict it was written for is this run's, else a note."""
    now = {(r["claim"], r["figure"]): r["verdict"] for r in cards.to_dict("records")}
    out = {}
    for c in CLAIMS if register is None else register:
        if not c.our_reading:
            continue
        off = [f"{f}: {v}, now {now[(c.id, f)]}" for f, v in c.our_reading["written_for"].items()
               if (c.id, f) in now and now[(c.id, f)] != v]
        out[c.id] = (c.our_reading["text"] if not off else
                     "(our reading was written for other verdicts: " + "; ".join(off)
                     + "; see the discussion)")
    return out
