"""The paper's claims: one table (CLAIMS, one row per claim) and the measure of each.

A row holds the claim's words, the figures it applies to, its criterion and its measure in
words, and whether it is the paper's claim or a diagnostic we added (shown, marked, never counted
in the headline). `tests` turns a figure's trial curves into one Test per (claim, condition):
the measure's value on every trial, and the bounds it must lie within. The verdict on all trials
and every interval (pipeline/studies/scorecard.py) and every coverage draw
(pipeline/studies/coverage.py) use these same per-trial values: a claim is judged on the mean
over trials of its measure, computed on each trial's own curve.

Why per trial: a maximum over epochs of a mean curve (a rise, a rebound, an excess) grows as
the number of trials averaged falls, so it has no fixed value to estimate and no interval over
resampled trials covers it; the mean of a per-trial maximum has one, and a t interval covers it
(the coverage measured in docs/scorecard.md). A rebound and the blending are measured on each
trial's curve smoothed over SMOOTH evaluation points: unsmoothed, a single trial's jitter at a
constant rate reads as a rebound of ~30 % where the mean curve of 20 trials rebounds 3-6 %; a
rise during growth is not smoothed, as at T_G = 10 it lasts a few evaluation points. The references enter a growing body's measure as
their mean curves.

A study adds a claim by adding a row here and its measure in `tests`.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from gbmodel.growth import factors

from .. import measures
from .figures import final_body

FACTOR = 1.5  # "about" the paper's final error: within this factor of it
RISE = 0.10  # a temporary rise during growth: above this fraction of the error before it
EXCESS = 0.20  # blending and no degeneration: curves stay within this fraction
REACH = 0.05  # Fig. 2: the extremes count as reached within this distance [m]
MIN_TRIALS_STAGES = 3  # Fig. 2's extremes are judged on at least this many trials
ABOVE_REFS_FROM = 100  # "above both references" only for T_G >= this (see CLAIMS)
SMOOTH = 5  # rebounds and blending: each trial's curve averaged over this many evaluation points


@dataclass(frozen=True)
class Claim:
    id: str
    words: str  # the claim in short, as the paper states it
    figures: str  # the figures it applies to
    criterion: str  # what the measure must satisfy, in words
    measure: str  # what is measured on each trial, in words
    diagnostic: bool = False  # added by us: shown and marked, never counted
    min_trials: int = 2  # fewer trials: inconclusive, whatever the interval


CLAIMS = [
    Claim("final", "final error about the paper's value (2 cm arm, 6 mm iCub)",
          "Fig. 4, 5, 7",
          f"every condition within x{FACTOR:g} of the paper's value",
          "final absolute error per unit of the full body size (a half-size reference counts "
          "its error at full size), over the paper's value"),
    Claim("rise", "the error rises temporarily during growth", "Fig. 4, 5, 7",
          f"above +{RISE:.0%} for every T_G <= 1000",
          "the largest rise of the absolute error above its running minimum during epochs "
          "1 ... T_G + 1, relative to the lowest error before it"),
    Claim("blend", "the relative error blends between the references", "Fig. 4, 5, 7",
          f"below +{EXCESS:.0%} for every T_G",
          "the larger of: the most the relative error exceeds the upper of the two references' "
          "mean curves, and the final distance to the long reference (relative); curves "
          f"smoothed over {SMOOTH} evaluation points"),
    Claim("after", "no degeneration after growth", "Fig. 4, 5, 7",
          f"rebound below +{EXCESS:.0%} and end below start, for every T_G",
          "the largest rebound of the relative error above its running minimum after growth, "
          f"the curve smoothed over {SMOOTH} evaluation points (a trial's jitter at a constant "
          "rate is no rebound); its end over its value at the end of growth"),
    Claim("bootstrap", "bootstrapping succeeds in every trial", "Fig. 4, 5, 7",
          "no trial failed", "trials that failed to run, diverged, or ended above "
          "aggregate.fail_factor times their condition's median"),
    Claim("stages", "Fig. 2: the estimate expands until the extremes are reached", "Fig. 2",
          f"the extremes (heights -1 and +1 m) reached within {1000 * REACH:.0f} mm, on at least "
          f"{MIN_TRIALS_STAGES} trials",
          "the final error at the worse of the two extreme targets",
          min_trials=MIN_TRIALS_STAGES),
    Claim("above_start", "above the start body during growth", "Fig. 4, 5, 7",
          f"above +{RISE:.0%} for every T_G <= 1000",
          "the most the absolute error exceeds the constant short reference's mean curve during "
          "epochs 1 ... T_G + 1", diagnostic=True),
    Claim("above_refs", "above both references during growth", "Fig. 4, 5, 7",
          f"above +{RISE:.0%} for T_G in {{{ABOVE_REFS_FROM}, 1000}} (at T_G < "
          f"{ABOVE_REFS_FROM} the body is full-grown before either reference has learned, so "
          "it cannot pass)",
          "the most the absolute error exceeds the larger of the two references' mean curves "
          "during epochs 1 ... T_G + 1", diagnostic=True),
    Claim("during", "no degeneration during growth", "Fig. 4, 5, 7",
          f"rebound below +{EXCESS:.0%} for every T_G",
          "the largest rebound of the relative error above its running minimum during growth, "
          f"smoothed over {SMOOTH} evaluation points",
          diagnostic=True),
    Claim("stages_home", "Fig. 2: the estimate starts around home", "Fig. 2",
          "within 0.2 rad of home after epoch 1 (0.1 at initialisation plus one step)",
          "the largest joint deviation from home over the targets after epoch 1",
          diagnostic=True),
    Claim("stages_spread", "Fig. 2: the spread grows from stage to stage", "Fig. 2",
          "grows at every stage", "the smallest growth of the largest joint deviation from "
          "home between successive stages", diagnostic=True),
]
BY_ID = {c.id: c for c in CLAIMS}


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
class Test:
    """One measure of one claim on one condition: `values`, the measure on each trial, whose
    mean must lie in [lo, hi]. kind: the measure's type, for its measured coverage."""

    figure: str
    claim: str
    where: str  # which condition
    values: np.ndarray
    lo: float = -np.inf
    hi: float = np.inf
    unit: str = "%"  # how the value prints: "%" (a fraction), "x" (a ratio), "mm", "rad"
    kind: str = ""
    exact: bool = False  # a count over all trials (the bootstrap claim): judged exactly
    diverged: bool = False  # the condition (or a reference it needs) left no curve
    result: dict = field(default_factory=dict)


# --- the per-trial measures ------------------------------------------------------------------

def per_trial(trials: pd.DataFrame, condition: str, column: str) -> tuple[np.ndarray, np.ndarray]:
    """(epochs, values[trial, epoch]) of one condition's trial curves."""
    c = trials[trials["condition"] == condition]
    p = c.pivot(index="trial", columns="epoch", values=column).sort_index(axis=1).dropna(axis=1)
    return p.columns.to_numpy(), p.to_numpy()


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
    i, up = measures.rise(v)
    base = np.take_along_axis(v, i[..., None], -1)[..., 0] - up
    return np.where(base > 0, up / np.where(base > 0, base, 1), 0.0)


def excess(v: np.ndarray, ref: np.ndarray) -> np.ndarray:
    """The most `v` exceeds `ref` (relative to it) along the last axis."""
    return (v / ref - 1).max(axis=-1)


def blend(v: np.ndarray, short: np.ndarray, long_: np.ndarray) -> np.ndarray:
    up = np.maximum(short, long_)
    return np.maximum(excess(v, up), np.abs(v[..., -1] / long_[-1] - 1))


def tests(figure: str, trials: pd.DataFrame, summary: pd.DataFrame) -> list[Test]:
    """Every claim's test on one growth figure (Fig. 4, 5, 7): one per condition it covers."""
    out, every = [], summary
    paper = summary["paper_final_abs_error"].iloc[0] if len(summary) else np.nan
    dead = diverged_conditions(summary)
    n_refs = int((summary["growth"] == "none").sum())
    for r in summary[summary["condition"].isin(dead)].itertuples():
        touched = ["final"] if np.isfinite(paper) else []
        if r.growth != "none":
            touched += (["rise"] if r.growth_period <= 1000 else []) + ["after", "during"]
        touched += ["blend"] if n_refs == 2 else []  # a growing one's, or a reference's
        out += [Test(figure, claim, r.condition, np.array([]), diverged=True)
                for claim in touched]
    summary = summary[~summary["condition"].isin(dead)]
    growing = summary[summary["growth"] != "none"]
    refs = summary[summary["growth"] == "none"].sort_values("end_size")
    if len(refs) != n_refs:
        refs = refs.iloc[:0]  # the comparisons with the references need both of them
    abs_ = {c: per_trial(trials, c, "abs_error") for c in summary["condition"]}
    rel = {c: per_trial(trials, c, "rel_error") for c in summary["condition"]}
    if np.isfinite(paper):
        full = summary["end_size"].max()
        for r in summary.itertuples():
            out.append(Test(figure, "final", r.condition,
                            abs_[r.condition][1][:, -1] * full / r.end_size / paper,
                            1 / FACTOR, FACTOR, unit="x", kind="final"))
    two_refs = len(refs) == 2
    if two_refs:
        short, long_ = refs["condition"]
    for r in growing.itertuples():
        ep, g = abs_[r.condition]
        _, gr = rel[r.condition]
        during, after = ep <= r.growth_period + 1, ep >= r.growth_period + 1
        c = r.condition
        required = r.growth_period <= 1000
        if required:
            out.append(Test(figure, "rise", c, rise(g[:, during]), RISE, kind="rebound"))
        if two_refs and required:
            s_, l_ = at(ep[during], abs_[short]), at(ep[during], abs_[long_])
            out.append(Test(figure, "above_start", c, excess(g[:, during], s_), RISE,
                            kind="excess"))
            if r.growth_period >= ABOVE_REFS_FROM:
                out.append(Test(figure, "above_refs", c,
                                excess(g[:, during], np.maximum(s_, l_)), RISE, kind="excess"))
        if two_refs:
            out.append(Test(figure, "blend", c, blend(
                smooth(gr), smooth(at(ep, rel[short])), smooth(at(ep, rel[long_]))),
                hi=EXCESS, kind="excess"))
        if after.sum() >= 2:
            out.append(Test(figure, "after", c + " rebound", rebound(smooth(gr[:, after])),
                            hi=EXCESS, kind="rebound"))
            out.append(Test(figure, "after", c + " end / start",
                            gr[:, after][:, -1] / gr[:, after][:, 0], hi=1.0 - 1e-12, unit="x",
                            kind="ratio"))
        out.append(Test(figure, "during", c, rebound(smooth(gr[:, during])), hi=EXCESS,
                        kind="rebound"))
    fails = int(every["n_bootstrap_failures"].sum() + every["n_run_failures"].sum()
                + every.get("n_diverged", pd.Series(dtype=int)).sum())
    total = int(every["n_trials"].sum() + every["n_run_failures"].sum()
                + every.get("n_diverged", pd.Series(dtype=int)).sum())
    out.append(Test(figure, "bootstrap", f"{fails} of {total} trials failed",
                    np.array([fails, total]), unit="rate", exact=True))
    return out


def stage_tests(figure: str, spec: dict, trials: list[list]) -> list[Test]:
    """Fig. 2 over trials (`trials`: each trial's M per stage, the final M last): the error at
    the worse extreme (decisive, on at least MIN_TRIALS_STAGES trials), and as diagnostics the
    start's deviation from home and the smallest growth of the spread between stages."""
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
    return [Test(figure, "stages", "final error at the worse extreme", extreme,
                 hi=REACH - 1e-12, unit="m", kind="final"),
            Test(figure, "stages_home", "deviation from home after epoch 1", spread[:, 0],
                 hi=0.2, unit="rad", kind="final"),
            Test(figure, "stages_spread", "smallest growth of the spread",
                 np.diff(spread, axis=-1).min(axis=-1), lo=1e-12, unit="rad", kind="excess")]


def markdown() -> str:
    """The table of claims: words, figures, criterion, measure; diagnostics marked."""
    lines = ["| claim | figures | criterion (on the mean over trials) | measure, per trial |",
             "|---|---|---|---|"]
    lines += [f"| {title(c.id)} | {c.figures} | {c.criterion} | {c.measure} |" for c in CLAIMS]
    return "\n".join(lines) + "\n"


READINGS = Path(__file__).parent / "our_reading.csv"


def readings_table() -> pd.DataFrame:
    """Our reading of each claim (our_reading.csv, written by hand from findings.md): the text,
    and the verdicts per figure it was written for ("fig4=reproduced; fig5=...")."""
    t = pd.read_csv(READINGS, keep_default_na=False, dtype=str)
    unknown = sorted(set(t["claim"]) - set(BY_ID))
    if unknown:
        raise ValueError(f"{READINGS}: no claim {unknown[0]!r} in claims.CLAIMS")
    return t


def _written_for(text: str) -> dict:
    return dict(p.strip().split("=", 1) for p in text.split(";") if p.strip())


def our_reading(cards: pd.DataFrame, table: pd.DataFrame | None = None) -> dict:
    """claim -> our reading, shown where every verdict it was written for is this run's verdict
    (on the figures of both); else a note that it was written for other verdicts."""
    t = readings_table() if table is None else table
    now = {(r["claim"], r["figure"]): r["verdict"] for r in cards.to_dict("records")}
    out = {}
    for r in t.to_dict("records"):
        wanted = _written_for(r["written_for"])
        off = [f"{f}: {v}, now {now[(r['claim'], f)]}" for f, v in wanted.items()
               if (r["claim"], f) in now and now[(r["claim"], f)] != v]
        out[r["claim"]] = (r["text"] if not off else
                           "(our reading was written for other verdicts: " + "; ".join(off)
                           + "; see the discussion)")
    return out
