"""The paper's claims: the register of criteria (register.yaml) and the measure of each claim.

The register (pipeline/studies/register.yaml) holds, per claim, the paper's sentence, its
measure, its criterion, every reasonable reading of an ambiguous sentence (each with its params,
which one is primary and why, and the commit at which it was fixed) and a changelog. Judging is
two steps: `measures` turns a figure's trial curves into per-trial values (one Measure per
measure and condition, with the per-trial values of the constant full-size reference over the
same epochs as its control), and `judge` applies the register's readings to them (one Test per
claim, reading and condition: values and the bounds their mean must lie within). The report
writes every Measure to measures.parquet, so `python -m pipeline.tools.rescore` can judge a
report again under an edited register without running a trial.

Why per trial: a maximum over epochs of a mean curve (a rise, a rebound, an excess) grows as
the number of trials averaged falls, so it has no fixed value to estimate and no interval over
resampled trials covers it; the mean of a per-trial maximum has one, and a t interval covers it
(the skew diagnostic and the replicate calibration in docs/scorecard.md). A rebound and the
blending are measured on each trial's curve smoothed over SMOOTH evaluation points:
unsmoothed, a single trial's jitter at a
constant rate reads as a rebound of ~30 % where the mean curve of 20 trials rebounds 3-6 %; a
rise during growth is not smoothed, as at T_G = 10 it lasts a few evaluation points. The
references enter a growing body's measure as their mean curves.

A study adds a claim by adding it to the register and its measure in `measures` and `judge`.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from gbmodel.growth import factors

from .. import measures as curve_measures
from . import register_schema
from .register_schema import criterion_hash
from .figures import final_body

SMOOTH = 5  # rebounds and blending: each trial's curve averaged over this many evaluation points
# Where the absolute error is measured (a reading's params.points; every trial scores all three at
# every evaluation, gbmodel.evaluation): the target grid, the path targets eq. 10 sums over, the
# uniform points of the held-out set. The final error and the rise are measured on each.
POINTS = {"grid": "abs_error", "path": "path_abs_error", "uniform": "uniform_abs_error"}
LAST_DECADE = "last decade"  # a final error's span: the mean over the evaluations of the last
# decade of epochs (epoch >= the last / 10: 20 of them), not where the last epoch falls
REGISTER = Path(__file__).parent / "register.yaml"


@dataclass(frozen=True)
class Reading:
    id: str
    label: str
    criterion: str
    why: str
    params: dict
    fixed_at: str
    primary: bool = False
    diagnostic: bool = False  # a reading shown and marked, never counted
    always_shown: bool = False  # shown beside the primary's verdict even where it agrees
    first: bool = False  # the claim's criterion as first fixed, before the first run's data


@dataclass(frozen=True)
class Claim:
    id: str
    words: str  # the claim in short, as the paper states it
    figures: str  # the figures it applies to
    sentence: str  # the paper's sentence
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
    """The claims of a register file, each reading's primary first; a ValueError names what is
    wrong (its schema, register_schema; not exactly one primary)."""
    data = register_schema.load(path)
    out = []
    for e in data["claims"]:
        rs = [Reading(id=str(r["id"]), label=r.get("label", r["id"]), criterion=r["criterion"],
                      why=r.get("why", ""), params=dict(r.get("params") or {}),
                      fixed_at=str(r.get("fixed_at", "")), primary=bool(r.get("primary")),
                      diagnostic=bool(r.get("diagnostic")),
                      always_shown=bool(r.get("always_shown")), first=bool(r.get("first")))
              for r in e.get("readings", [])]
        if sum(r.primary for r in rs) != 1:
            raise ValueError(f"{path}: claim {e['id']!r} needs exactly one primary reading")
        rs.sort(key=lambda r: not r.primary)
        out.append(Claim(id=e["id"], words=e["words"], figures=e["figures"],
                         sentence=e.get("sentence", ""), measure=e["measure"], readings=tuple(rs),
                         diagnostic=bool(e.get("diagnostic")),
                         min_trials=int(e.get("min_trials", 2)),
                         changelog=tuple(e.get("changelog", [])),
                         our_reading=e.get("our_reading")))
    return out


CLAIMS = load_register()
BY_ID = {c.id: c for c in CLAIMS}
RISE = BY_ID["rise"].primary.params["above"]  # a temporary rise: above this fraction


def title(claim: str) -> str:
    c = BY_ID[claim]
    return c.words + (" (diagnostic)" if c.diagnostic else "")


DIVERGED = "diverged"  # a condition none of whose trials left a curve, and the cells it touches


def diverged_conditions(summary: pd.DataFrame) -> list[str]:
    """The conditions none of whose trials left a curve (every one diverged or failed): no
    per-trial value to judge a claim on."""
    if "n_trials" not in summary:
        return []
    return [str(c) for c in summary.loc[summary["n_trials"] == 0, "condition"]]


@dataclass
class Measure:
    """One measure on one condition of a figure: `values`, its value on each trial, before any
    criterion. claim: the claim whose measure it is ("rise" also serves "rise_none"); size: the
    condition's final size over the figure's full size; period: its T_G (0: no growth);
    control: the same measure on the constant full-size reference's trials over the same epochs
    (None where there is no control); exact: a count (values: failed, total)."""

    figure: str
    claim: str
    where: str
    values: np.ndarray
    unit: str = "%"
    kind: str = ""
    size: float = 1.0
    period: int = 0
    control: np.ndarray | None = None
    exact: bool = False
    diverged: bool = False
    calibrated: tuple | None = None  # (t level or None, why) once known (measures.parquet)
    points: str = "grid"  # where the error is measured (POINTS): a reading's params.points
    span: str = "end"  # the final error: at the last evaluation, or its mean over the last decade


@dataclass
class Test:
    """One measure of one claim on one condition under one reading of its criterion: `values`,
    the measure on each trial, whose mean must lie in [lo, hi] (with a control: the difference
    of the means of `values` and `control`). kind: the measure's type."""

    figure: str
    claim: str
    where: str
    values: np.ndarray
    lo: float = -np.inf
    hi: float = np.inf
    unit: str = "%"  # how the value prints: "%" (a fraction), "x" (a ratio), "mm", "rad"
    kind: str = ""
    exact: bool = False  # a count over all trials (the bootstrap claim): judged exactly
    diverged: bool = False  # the condition (or a reference it needs) left no curve
    reading: str = ""  # the register's reading ("": the primary)
    primary: bool = True
    measure: str = ""  # the claim whose measure it is (coverage is looked up by it)
    control: np.ndarray | None = None
    diagnostic: bool | None = None  # None: the claim's in this register (BY_ID)
    min_trials: int | None = None
    calibrated: tuple | None = None  # the measure's (t level or None, why), where known
    result: dict = field(default_factory=dict)


# --- the per-trial measures ------------------------------------------------------------------

def per_trial(trials: pd.DataFrame, condition: str, column: str) -> tuple[np.ndarray, np.ndarray]:
    """(epochs, values[trial, epoch]) of one condition's trial curves: trials in ascending
    order, the epochs every trial has (ascending), as DataFrame.pivot and dropna give them."""
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
    """The positions of `condition`'s rows in `trials`, in order: the table is grouped once
    (kept with it, so its id is its own) for all its conditions, instead of masking every row
    per condition and curve (a report asks for each figure's conditions dozens of times)."""
    if not _SPLIT or _SPLIT[0][0] is not trials:
        _SPLIT[:] = [(trials, trials.groupby("condition", sort=False).indices)]
    return _SPLIT[0][1].get(condition, np.array([], dtype=np.intp))


def at(epochs: np.ndarray, ref: tuple) -> np.ndarray:
    """A reference's mean curve at `epochs`; every epoch must be among its own (the conditions
    of a figure are evaluated at the same epochs)."""
    idx = np.searchsorted(ref[0], epochs)
    if np.any(idx >= len(ref[0])) or not np.array_equal(ref[0][np.minimum(idx, len(ref[0]) - 1)],
                                                          epochs):
        raise ValueError("a reference condition lacks some epochs of the growing one")
    return ref[1][:, idx].mean(axis=0)


def smooth(v: np.ndarray, k: int = SMOOTH) -> np.ndarray:
    """A moving average over k successive evaluation points along the last axis (a quarter
    decade of epochs at 20 points per decade), only the points with k neighbours kept; a curve
    of fewer than 2 k points as it is (too short to smooth and still see a rebound)."""
    if v.shape[-1] < 2 * k:
        return v
    c = np.cumsum(np.concatenate([np.zeros(v.shape[:-1] + (1,)), v], axis=-1), axis=-1)
    return (c[..., k:] - c[..., :-k]) / k


def rebound(v: np.ndarray) -> np.ndarray:
    """The largest rise above the running minimum, relative to it, along the last axis."""
    return (v / np.minimum.accumulate(v, axis=-1) - 1).max(axis=-1)


def rise(v: np.ndarray) -> np.ndarray:
    """The pre-set temporary rise (pipeline.measures.rise, as aggregate measures it) per trial,
    relative to the lowest error before it."""
    i, up = curve_measures.rise(v)
    base = np.take_along_axis(v, i[..., None], -1)[..., 0] - up
    return np.where(base > 0, up / np.where(base > 0, base, 1), 0.0)


def excess(v: np.ndarray, ref: np.ndarray) -> np.ndarray:
    """The most `v` exceeds `ref` (relative to it) along the last axis."""
    return (v / ref - 1).max(axis=-1)


def blend(v: np.ndarray, short: np.ndarray, long_: np.ndarray) -> np.ndarray:
    up = np.maximum(short, long_)
    return np.maximum(excess(v, up), np.abs(v[..., -1] / long_[-1] - 1))


def _diverged_measures(figure: str, summary: pd.DataFrame, dead: list, n_refs: int,
                       has_paper: bool) -> list[Measure]:
    """The measures a condition with no curve would have had: each a Measure marked diverged,
    so the cells it touches say so."""
    out = []
    for r in summary[summary["condition"].isin(dead)].itertuples():
        touched = ["final"] if has_paper else []
        if r.growth != "none":
            touched += ["rise", "after", "during"]
        touched += ["blend"] if n_refs == 2 else []  # a growing one's, or a reference's
        out += [Measure(figure, claim, r.condition, np.array([]), diverged=True,
                        period=int(r.growth_period) if r.growth != "none" else 0,
                        size=float(r.end_size) / float(summary["end_size"].max()),
                        points=p, span=s)
                for claim in touched for p, s in _places(claim)]
    return out


def _places(claim: str) -> list[tuple[str, str]]:
    """(points, span) of every measure `measures` makes of a claim (the final error and the
    rise wherever the error is measured, the rest on the grid)."""
    spans = ("end", LAST_DECADE) if claim == "final" else ("end",)
    return [(p, s) for p in POINTS for s in spans] if claim in ("final", "rise") else \
        [("grid", "end")]


def measures(figure: str, trials: pd.DataFrame, summary: pd.DataFrame) -> list[Measure]:
    """Every claim's measure on one growth figure (Fig. 4, 5, 7), per trial, one Measure per
    condition it covers, before any criterion: `judge` applies the register's readings."""
    out, every = [], summary
    paper = summary["paper_final_abs_error"].iloc[0] if len(summary) else np.nan
    dead = diverged_conditions(summary)
    n_refs = int((summary["growth"] == "none").sum())
    out += _diverged_measures(figure, summary, dead, n_refs, bool(np.isfinite(paper)))
    summary = summary[~summary["condition"].isin(dead)]
    growing = summary[summary["growth"] != "none"]
    refs = summary[summary["growth"] == "none"].sort_values("end_size")
    if len(refs) != n_refs:
        refs = refs.iloc[:0]  # the comparisons with the references need both of them
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
    two_refs = len(refs) == 2
    if two_refs:
        short, long_ = refs["condition"]
    control = long_ if two_refs else None
    for r in growing.itertuples():
        ep, g = abs_[r.condition]
        _, gr = rel[r.condition]
        during, after = ep <= r.growth_period + 1, ep >= r.growth_period + 1
        c, period = r.condition, int(r.growth_period)

        def ctrl(fn, curves):  # the same measure on the control's trials over the same epochs
            if control is None:
                return None
            cep, cv = curves[control]
            keep = np.isin(cep, ep)
            if not np.array_equal(cep[keep], ep):
                return None
            return fn(cv[:, keep])
        for p, curves in at_points.items():  # the rise wherever the error is measured
            out.append(Measure(figure, "rise", c, rise(curves[c][1][:, during]), kind="rebound",
                               period=period, points=p,
                               control=ctrl(lambda v: rise(v[:, during]), curves)))
        if two_refs:
            s_, l_ = at(ep[during], abs_[short]), at(ep[during], abs_[long_])
            out.append(Measure(figure, "above_start", c, excess(g[:, during], s_),
                               kind="excess", period=period))
            out.append(Measure(figure, "above_refs", c, excess(g[:, during], np.maximum(s_, l_)),
                               kind="excess", period=period))
            bands = (smooth(at(ep, rel[short])), smooth(at(ep, rel[long_])))
            out.append(Measure(figure, "blend", c, blend(smooth(gr), *bands), kind="excess",
                               period=period,
                               control=ctrl(lambda v: blend(smooth(v), *bands), rel)))
        if after.sum() >= 2:
            out.append(Measure(figure, "after", c + " rebound", rebound(smooth(gr[:, after])),
                               kind="rebound", period=period,
                               control=ctrl(lambda v: rebound(smooth(v[:, after])), rel)))
            out.append(Measure(figure, "after", c + " end / start",
                               gr[:, after][:, -1] / gr[:, after][:, 0], unit="x", kind="ratio",
                               period=period))
        out.append(Measure(figure, "during", c, rebound(smooth(gr[:, during])), kind="rebound",
                           period=period))
    fails = int(every["n_bootstrap_failures"].sum() + every["n_run_failures"].sum()
                + every.get("n_diverged", pd.Series(dtype=int)).sum())
    total = int(every["n_trials"].sum() + every["n_run_failures"].sum()
                + every.get("n_diverged", pd.Series(dtype=int)).sum())
    out.append(Measure(figure, "bootstrap", f"{fails} of {total} trials failed",
                       np.array([fails, total]), unit="rate", exact=True))
    return out


def _bounds(claim: str, m: Measure, p: dict) -> tuple[float, float] | None:
    """[lo, hi] of a measure under a reading's params, or None where the reading does not judge
    it (a T_G outside its periods)."""
    if ("from" in p or "up_to" in p) and not (
            m.period and p.get("from", 0) <= m.period <= p.get("up_to", np.inf)):
        return None
    if claim == "final":
        side = p["full"] if m.size >= 1 - 1e-9 else p["smaller"]
        return (1 / p["factor"] if side == "two-sided" else -np.inf), p["factor"]
    if "above" in p:
        return p["above"], np.inf
    if "below" in p:
        return -np.inf, p["below"] - (1e-12 if claim in ("stages",) else 0)
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


def judge(ms: list[Measure], claims: list[Claim] | None = None) -> list[Test]:
    """Every claim's Tests under every registered reading (claims: a register's; default this
    one's): one per (claim, reading, condition) the reading judges, its values scaled as the
    reading says, with its bounds; a controlled reading's Test carries the control's values."""
    by = {c.id: c for c in (CLAIMS if claims is None else claims)}
    out = []
    for m in ms:
        for claim in SERVES.get(m.claim, (m.claim,)):
            c = by.get(claim)
            if c is None:
                continue
            for r in c.readings:
                p = r.params
                if (m.points, m.span) != (p.get("points", "grid"), p.get("span", "end")):
                    continue  # measured elsewhere than where this reading measures
                b = _bounds(claim, m, p) if not m.exact else (-np.inf, np.inf)
                if b is None:
                    continue
                if p.get("control") and m.control is None and not m.diverged:
                    continue  # no control for this measure (an end over its start)
                values = m.values / m.size if p.get("scale") == "size" else m.values
                out.append(Test(m.figure, claim, m.where, values, b[0], b[1], unit=m.unit,
                                kind=m.kind, exact=m.exact, diverged=m.diverged,
                                reading="" if r.primary else r.id, primary=r.primary,
                                measure=m.claim,
                                control=m.control if p.get("control") else None,
                                diagnostic=c.diagnostic or r.diagnostic,
                                min_trials=c.min_trials, calibrated=m.calibrated))
    return out


def tests(figure: str, trials: pd.DataFrame, summary: pd.DataFrame,
          claims: list[Claim] | None = None) -> list[Test]:
    """Every claim's test on one growth figure (Fig. 4, 5, 7) under every registered reading."""
    return judge(measures(figure, trials, summary), claims)


def stage_measures(figure: str, spec: dict, trials: list[list]) -> list[Measure]:
    """Fig. 2 over trials (`trials`: each trial's M per stage, the final M last): the error at
    the worse extreme (decisive, on at least its min_trials), and as diagnostics the start's
    deviation from home and the smallest growth of the spread between stages."""
    body, size, pattern, predict = final_body(spec)
    xs = body.target_set(size)
    spread, extreme = [], []
    for stages in trials:
        s = []
        for M in stages:
            q = predict(np.asarray(M), xs)
            s.append(float(np.abs(q - body.home).max()))
        err = np.linalg.norm(body.forward(q, factors(body, size, pattern)) - xs, axis=-1)
        spread.append(s)
        extreme.append(float(max(err[0], err[-1])))
    spread, extreme = np.array(spread), np.array(extreme)
    return [Measure(figure, "stages", "final error at the worse extreme", extreme, unit="m",
                    kind="final"),
            Measure(figure, "stages_home", "deviation from home after epoch 1", spread[:, 0],
                    unit="rad", kind="final"),
            Measure(figure, "stages_spread", "smallest growth of the spread",
                    np.diff(spread, axis=-1).min(axis=-1), unit="rad", kind="excess")]


def stage_tests(figure: str, spec: dict, trials: list[list]) -> list[Test]:
    return judge(stage_measures(figure, spec, trials))

def markdown() -> str:
    """The table of claims: words, figures, criterion, measure; diagnostics marked."""
    lines = ["| claim | figures | criterion (on the mean over trials) | measure, per trial |",
             "|---|---|---|---|"]
    lines += [f"| {title(c.id)} | {c.figures} | {c.criterion} | {c.measure} |" for c in CLAIMS]
    return "\n".join(lines) + "\n"


def readings_markdown() -> str:
    """Every registered reading of every claim: its criterion, whether it is primary (counted)
    and why, and the commit at which it was fixed (register.yaml)."""
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
    """claim -> our reading (the register's our_reading, written by hand from findings.md),
    shown where every verdict it was written for is this run's verdict (on the figures of both);
    else a note that it was written for other verdicts."""
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


def unlogged(path: Path = REGISTER) -> list[str]:
    """register_schema.unlogged of a register file (this one's by default)."""
    return register_schema.unlogged(path)
