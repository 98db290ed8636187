"""The scorecard: every claim of the paper on every figure, with a 95 % interval over trials.

claims.py checks each claim on the mean curves, against criteria fixed before the full-scale run.
The mean over 5 or 20 trials is itself uncertain, so here each claim's measure is recomputed on
bootstrap resamples of the trials (each condition resampled on its own: the conditions' trials
are independent runs) and the verdict follows from where its 95 % interval lies:

    reproduced      the interval lies within the criterion
    not reproduced  the interval lies outside it
    inconclusive    the interval straddles a bound of the criterion (or there is one trial only)

For an inconclusive measure, `trials_to_decide` is the trial count per condition at which an
interval of the observed spread (its half-width shrinking as 1 / sqrt(n)) would no longer reach
the bound.

Interval: scipy.stats.bootstrap, percentile method, 2000 resamples, a fixed seed (SEED) so that
the report is byte-stable. Why percentile, not BCa: BCa's acceleration comes from the jackknife,
n leave-one-out values, and with the 2-5 trials of Fig. 7 and the readings study it is
ill-determined (scipy warns of a degenerate distribution, and returns NaN when the trials agree);
the percentile interval is defined for every n >= 2. With so few trials any bootstrap interval
is too narrow rather than too wide (it cannot see spread the trials did not show), so an
"inconclusive" is a firm statement and a "reproduced" on 2-5 trials a weaker one.

The trials of a condition are resampled as whole curves, so a measure over epochs (a rise, a
rebound) is recomputed on the resample's mean curve, exactly as claims.py computes it on the mean.
"""
from __future__ import annotations

import math
import textwrap
from dataclasses import dataclass, field

import numpy as np
import pandas as pd
from scipy import stats

import gbmodel

from .claims import EXCESS, FACTOR, RISE, diverged_conditions
from .figures import final_body

SEED = 2010  # the bootstrap's random draws: fixed, so the same trials give the same bytes
RESAMPLES = 2000  # the 2.5 % and 97.5 % points move by < 1 % of the interval's width beyond this
LEVEL = 0.95

# (id, the claim in short, added after the full run?) in the scorecard's row order
CLAIMS = [
    ("final", "final error about the paper's value (within x1.5)", False),
    ("rise", "the error rises temporarily during growth", False),
    ("above_refs", "above both references during growth", True),
    ("above_start", "above the start body during growth", True),
    ("blend", "the relative error blends between the references", False),
    ("after", "no degeneration after growth", False),
    ("during", "no degeneration during growth", True),
    ("bootstrap", "bootstrapping succeeds in every trial", False),
    ("stages", "Fig. 2 stages: home, expanding, extremes reached", False),
]
TITLES = {c: t + (" (added)" if added else "") for c, t, added in CLAIMS}
REPRODUCED, NOT, INCONCLUSIVE = "reproduced", "not reproduced", "inconclusive"


@dataclass
class Test:
    """One measure of one claim: `stat` of the trial means of `samples` (arrays with trials on
    axis 0), required to lie in [lo, hi]."""

    figure: str
    claim: str
    where: str  # which condition(s)
    samples: list
    stat: object  # callable(*means) -> value; vectorised over leading axes
    lo: float = -np.inf
    hi: float = np.inf
    unit: str = "%"  # how the value prints: "%" (a fraction), "x" (a ratio), "mm", "rad"
    exact: bool = False  # a count over all trials: no resampling (bootstrap claim)
    result: dict = field(default_factory=dict)


def interval(samples: list, stat) -> tuple[float, float, float]:
    """(point, low, high): `stat` of the trial means and its 95 % percentile bootstrap interval
    over trials, each sample resampled on its own; (point, nan, nan) with fewer than 2 trials."""
    samples = [np.asarray(s, float) for s in samples]
    point = float(stat(*[s.mean(axis=0) for s in samples]))
    if min(len(s) for s in samples) < 2:
        return point, np.nan, np.nan

    def of_indices(*idx, axis=-1):
        return stat(*[s[i].mean(axis=i.ndim - 1) for s, i in zip(samples, idx)])

    res = stats.bootstrap([np.arange(len(s)) for s in samples], of_indices, vectorized=True,
                          paired=False, n_resamples=RESAMPLES, batch=200, method="percentile",
                          confidence_level=LEVEL, rng=np.random.default_rng(SEED))
    return point, float(res.confidence_interval.low), float(res.confidence_interval.high)


def verdict(low: float, high: float, lo: float, hi: float) -> str:
    """reproduced if [low, high] lies within [lo, hi], not reproduced if outside, else (or with
    no interval) inconclusive."""
    if not (np.isfinite(low) and np.isfinite(high)):
        return INCONCLUSIVE
    if lo <= low and high <= hi:
        return REPRODUCED
    if high < lo or low > hi:
        return NOT
    return INCONCLUSIVE


def trials_to_decide(point: float, low: float, high: float, lo: float, hi: float,
                     n: int) -> int | None:
    """Trials per condition at which an interval of the observed spread would clear the bound it
    straddles: the half-width on that side times sqrt(n / n') below the distance from the point
    to the bound. None when undefined (no interval, or the point on the bound)."""
    if not (np.isfinite(low) and np.isfinite(high)):
        return None
    bounds = [b for b in (lo, hi) if np.isfinite(b) and low <= b <= high]
    if not bounds:
        return None
    b = min(bounds, key=lambda b: abs(point - b))
    gap = abs(point - b)
    half = (point - low) if b <= point else (high - point)
    if gap == 0 or half <= 0:
        return None
    return max(n + 1, math.ceil(n * (half / gap) ** 2))


def run_test(t: Test) -> dict:
    """Measure a test and judge it; stores and returns its result."""
    n = min(len(s) for s in t.samples)
    if t.exact:  # a count: the verdict is exact, the interval is the failure rate's
        k, n_all = (int(v) for v in t.samples[0])
        ci = stats.binomtest(k, n_all).proportion_ci(LEVEL) if n_all else None
        point, low, high = (k / n_all if n_all else np.nan,
                            ci.low if ci else np.nan, ci.high if ci else np.nan)
        v, need = (REPRODUCED if k == 0 else NOT), None
        n = n_all
    else:
        point, low, high = interval(t.samples, t.stat)
        v = verdict(low, high, t.lo, t.hi)
        need = trials_to_decide(point, low, high, t.lo, t.hi, n) if v == INCONCLUSIVE else None
    t.result = dict(figure=t.figure, claim=t.claim, where=t.where, value=point, low=low,
                    high=high, lo=t.lo, hi=t.hi, unit=t.unit, trials=n, verdict=v,
                    trials_to_decide=need)
    return t.result


# --- the measures, on trial curves ---------------------------------------------------------------

def _per_trial(trials: pd.DataFrame, condition: str, column: str) -> tuple[np.ndarray, np.ndarray]:
    """(epochs, values[trial, epoch]) of one condition's trial curves."""
    c = trials[trials["condition"] == condition]
    p = c.pivot(index="trial", columns="epoch", values=column).sort_index(axis=1).dropna(axis=1)
    return p.columns.to_numpy(), p.to_numpy()


def _at(epochs: np.ndarray, ref: tuple) -> np.ndarray:
    """A reference's values (trial, epoch) at `epochs`; every epoch must be among its own (the
    conditions of a figure are evaluated at the same epochs)."""
    idx = np.searchsorted(ref[0], epochs)
    if np.any(idx >= len(ref[0])) or not np.array_equal(ref[0][np.minimum(idx, len(ref[0]) - 1)],
                                                          epochs):
        raise ValueError("a reference condition lacks some epochs of the growing one")
    return ref[1][:, idx]


def _rebound(v):
    """The largest rise above the running minimum, relative to it, along the last axis."""
    return (v / np.minimum.accumulate(v, axis=-1) - 1).max(axis=-1)


def _rise(v):
    """The pre-set temporary rise (aggregate.rise) relative to the lowest error before it."""
    r = v - np.minimum.accumulate(v, axis=-1)
    i = np.argmax(r, axis=-1)[..., None]
    top, up = np.take_along_axis(v, i, -1)[..., 0], np.take_along_axis(r, i, -1)[..., 0]
    base = top - up
    return np.where(base > 0, up / np.where(base > 0, base, 1), 0.0)


def growth_tests(figure: str, trials: pd.DataFrame, summary: pd.DataFrame) -> list[Test]:
    """The tests of every growth claim (Fig. 4, 5, 7) on one figure's trial curves, the same
    measures and criteria as claims.growth_claims, per condition."""
    tests = []
    dead = diverged_conditions(summary)  # no trial curve to resample: claims.py marks them
    refs = summary[summary["growth"] == "none"].sort_values("end_size")
    if any(c in dead for c in refs["condition"]):
        refs = refs.iloc[:0]  # the reference tests need both references
    summary = summary[~summary["condition"].isin(dead)]
    refs = refs[refs["condition"].isin(summary["condition"])]
    growing = summary[summary["growth"] != "none"]
    paper = summary["paper_final_abs_error"].iloc[0] if len(summary) else np.nan
    abs_, rel = {}, {}
    for c in summary["condition"]:
        abs_[c], rel[c] = _per_trial(trials, c, "abs_error"), _per_trial(trials, c, "rel_error")
    if np.isfinite(paper):
        for c in summary["condition"]:
            tests.append(Test(figure, "final", c, [abs_[c][1][:, -1]], lambda m: m / paper,
                              1 / FACTOR, FACTOR, unit="x"))
    two_refs = len(refs) == 2
    if two_refs:
        short, long_ = refs["condition"]
    for r in growing.itertuples():
        ep, g = abs_[r.condition]
        _, gr = rel[r.condition]
        during = ep <= r.growth_period + 1
        after = ep >= r.growth_period + 1
        where = r.condition
        required = r.growth_period <= 1000
        if required:
            tests.append(Test(figure, "rise", where, [g[:, during]], _rise, RISE, np.inf))
        if two_refs and required:
            s_, l_ = _at(ep[during], abs_[short]), _at(ep[during], abs_[long_])
            tests.append(Test(figure, "above_refs", where, [g[:, during], s_, l_],
                              lambda m, s, l: (m / np.maximum(s, l) - 1).max(axis=-1),
                              RISE, np.inf))
            tests.append(Test(figure, "above_start", where, [g[:, during], s_],
                              lambda m, s: (m / s - 1).max(axis=-1), RISE, np.inf))
        if two_refs:
            s_, l_ = _at(ep, rel[short]), _at(ep, rel[long_])

            def blend(m, s, l):
                up = np.maximum(s, l)
                return np.maximum(((m - up) / up).max(axis=-1), np.abs(m[..., -1] / l[..., -1] - 1))
            tests.append(Test(figure, "blend", where, [gr, s_, l_], blend, -np.inf, EXCESS))
        if after.sum() >= 2:
            tests.append(Test(figure, "after", where + " rebound", [gr[:, after]], _rebound,
                              -np.inf, EXCESS))
            tests.append(Test(figure, "after", where + " end / start", [gr[:, after]],
                              lambda m: m[..., -1] / m[..., 0], -np.inf, 1.0 - 1e-12, unit="x"))
        tests.append(Test(figure, "during", where, [gr[:, during]], _rebound, -np.inf, EXCESS))
    fails = int(summary["n_bootstrap_failures"].sum() + summary["n_run_failures"].sum()
                + summary.get("n_diverged", pd.Series(dtype=int)).sum())
    total = int(summary["n_trials"].sum() + summary["n_run_failures"].sum()
                + summary.get("n_diverged", pd.Series(dtype=int)).sum())
    tests.append(Test(figure, "bootstrap", f"{fails} of {total} trials failed",
                      [np.array([fails, total])], None, unit="rate", exact=True))
    return tests


def stage_tests(figure: str, spec: dict, trials: list[list]) -> list[Test]:
    """Fig. 2 (claims.stage_claims) over trials: `trials` holds each trial's M per stage. The
    mean over trials of the start's deviation from home <= 0.2 rad, of the growth of the spread
    from stage to stage > 0, and of the error at the worst extreme < 5 cm."""
    body, size, pattern, exps = final_body(spec)
    xs = body.target_set(size)
    spread, extreme = [], []
    for stages in trials:
        s = []
        for M in stages:
            q = gbmodel.predict(np.asarray(M), xs, exps)
            s.append(float(np.abs(q - body.home).max()))
        err = np.linalg.norm(body.forward(q, size, pattern) - xs, axis=-1)
        spread.append(s)
        extreme.append(float(max(err[0], err[-1])))
    spread, extreme = np.array(spread), np.array(extreme)
    return [Test(figure, "stages", "start: deviation from home", [spread[:, 0]], lambda m: m,
                 -np.inf, 0.2, unit="rad"),
            Test(figure, "stages", "smallest growth of the spread", [spread],
                 lambda m: np.diff(m, axis=-1).min(axis=-1), 1e-12, np.inf, unit="rad"),
            Test(figure, "stages", "final error at the extremes", [extreme], lambda m: m,
                 -np.inf, 0.05 - 1e-12, unit="mm")]


# --- cells, tables, figure -------------------------------------------------------------------------

def fmt(value: float, unit: str) -> str:
    if not np.isfinite(value):
        return "n/a"
    if unit == "%":
        return f"{100 * value:+.0f} %"
    if unit == "rate":
        return f"{100 * value:.0f} %"
    if unit == "mm":
        return f"{1000 * value:.1f} mm"
    if unit == "rad":
        return f"{value:.2f} rad"
    return f"{value:.2f}x"


def fmt_interval(r: dict) -> str:
    if not (np.isfinite(r["low"]) and np.isfinite(r["high"])):
        return "no interval (1 trial)" if r["trials"] < 2 else "n/a"
    if r["unit"] == "rate":
        return f"(failure rate 95 % interval {fmt(r['low'], 'rate')} ... {fmt(r['high'], 'rate')})"
    return f"[{fmt(r['low'], r['unit'])}, {fmt(r['high'], r['unit'])}]"


def criterion(r: dict) -> str:
    if r["claim"] == "bootstrap":
        return "no failed trial"
    lo, hi = r["lo"], r["hi"]
    if np.isfinite(lo) and np.isfinite(hi):
        return f"{fmt(lo, r['unit'])} ... {fmt(hi, r['unit'])}"
    return (f"> {fmt(lo, r['unit'])}" if np.isfinite(lo) else f"< {fmt(hi, r['unit'])}")


def cells(results: list[dict]) -> pd.DataFrame:
    """One cell per (claim, figure): the verdict of all its measures (not reproduced if any is,
    else inconclusive if any is, else reproduced) and the measure that decides it."""
    df = pd.DataFrame(results)
    rows = []
    for (claim, figure), g in df.groupby(["claim", "figure"], sort=False):
        vs = g["verdict"].tolist()
        if NOT in vs:
            v, pick = NOT, g[g["verdict"] == NOT].iloc[0]
        elif INCONCLUSIVE in vs:
            inc = g[g["verdict"] == INCONCLUSIVE]
            need = inc["trials_to_decide"].map(lambda x: np.inf if x is None or pd.isna(x) else x)
            v, pick = INCONCLUSIVE, inc.loc[need.idxmax()]
        else:
            span = (g["high"] - g["low"]).abs().replace(0, 1e-300)
            margin = np.minimum((g["low"] - g["lo"]) / span, (g["hi"] - g["high"]) / span)
            v, pick = REPRODUCED, g.loc[margin.fillna(np.inf).idxmin()]
        need = pick["trials_to_decide"]
        rows.append(dict(claim=claim, figure=figure, verdict=v, where=pick["where"],
                         value=pick["value"], low=pick["low"], high=pick["high"],
                         unit=pick["unit"], trials=int(pick["trials"]),
                         trials_to_decide=None if need is None or pd.isna(need) else int(need),
                         measures=len(g), counts=f"{vs.count(REPRODUCED)}/{vs.count(NOT)}/"
                                                 f"{vs.count(INCONCLUSIVE)}"))
    return pd.DataFrame(rows)


def _need(r: dict) -> int | None:
    """The trials to decide, as an int (pandas turns a column with gaps into floats)."""
    n = r.get("trials_to_decide")
    return None if n is None or pd.isna(n) else int(n)


def cell_text(c, newline: str = " ") -> str:
    """'not reproduced' + the deciding measure, its value and interval (+ trials to decide)."""
    r = dict(c)
    text = f"**{r['verdict']}**{newline}{r['where']}: {fmt(r['value'], r['unit'])} {fmt_interval(r)}"
    if r["verdict"] == INCONCLUSIVE and _need(r):
        text += f"{newline}~{_need(r)} trials would decide"
    return text


def _order(cards: pd.DataFrame) -> tuple[list, list]:
    claims = [c for c, _, _ in CLAIMS if c in set(cards["claim"])]
    figs = sorted(set(cards["figure"]))
    return claims, figs


def reading(claim: str, row: pd.DataFrame) -> str:
    """'our reading' of a claim over the figures, in one line, from its verdicts alone."""
    vs = set(row["verdict"])
    if vs == {REPRODUCED}:
        return "reproduced on every figure"
    if vs == {NOT}:
        return "not reproduced on any figure, beyond the trials' spread"
    parts = [f"{v} on {', '.join(row[row['verdict'] == v]['figure'])}"
             for v in (REPRODUCED, NOT, INCONCLUSIVE) if v in vs]
    return "; ".join(parts)


def markdown(cards: pd.DataFrame, results: list[dict]) -> str:
    """The scorecard (claims x figures) and, below it, every measure with its interval."""
    claims, figs = _order(cards)
    n = {v: int((cards["verdict"] == v).sum()) for v in (REPRODUCED, NOT, INCONCLUSIVE)}
    lines = [f"{len(cards)} claim cells: **{n[REPRODUCED]} reproduced, {n[NOT]} not reproduced, "
             f"{n[INCONCLUSIVE]} inconclusive** (95 % percentile bootstrap intervals over "
             f"trials; \"(added)\": a measure added after the full run, beside the pre-set ones).",
             "", "| claim of the paper | " + " | ".join(figs) + " | our reading |",
             "|---|" + "---|" * (len(figs) + 1)]
    for claim in claims:
        row = cards[cards["claim"] == claim]
        by = {r.figure: cell_text(r._asdict(), "<br>") for r in row.itertuples()}
        lines.append(f"| {TITLES[claim]} | " + " | ".join(by.get(f, "—") for f in figs)
                     + f" | {reading(claim, row)} |")
    lines += ["", "<details><summary>every measure, its 95 % interval and criterion</summary>", "",
              "| figure | claim | measure | value | 95 % interval | criterion | trials | verdict "
              "| trials to decide |", "|---|---|---|---|---|---|---|---|---|"]
    for r in results:
        lines.append(f"| {r['figure']} | {TITLES[r['claim']]} | {r['where']} "
                     f"| {fmt(r['value'], r['unit'])} | {fmt_interval(r)} | {criterion(r)} "
                     f"| {r['trials']} | {r['verdict']} | {_need(r) or ''} |")
    lines += ["", "</details>", ""]
    return "\n".join(lines)


COLOURS = {REPRODUCED: "#b7e1b0", NOT: "#f4b6b0", INCONCLUSIVE: "#fbe3a0"}


def figure(cards: pd.DataFrame, title: str):
    """scorecard.png: claims (rows) x figures (columns), cells coloured by verdict."""
    from .figures import plt

    claims, figs = _order(cards)
    fig, ax = plt.subplots(figsize=(2.9 * len(figs) + 2.6, 0.7 * len(claims) + 1.2))
    ax.set(xlim=(0, len(figs)), ylim=(len(claims), 0))
    ax.set_xticks(np.arange(len(figs)) + 0.5, figs)
    ax.set_yticks(np.arange(len(claims)) + 0.5, [textwrap.fill(TITLES[c], 34) for c in claims])
    ax.xaxis.tick_top()
    ax.tick_params(length=0)
    ax.grid(False)
    for i, claim in enumerate(claims):
        for j, f in enumerate(figs):
            hit = cards[(cards["claim"] == claim) & (cards["figure"] == f)]
            if not len(hit):
                ax.add_patch(plt.Rectangle((j, i), 1, 1, fc="#eeeeee", ec="white", lw=2))
                continue
            c = hit.iloc[0].to_dict()
            ax.add_patch(plt.Rectangle((j, i), 1, 1, fc=COLOURS[c["verdict"]], ec="white", lw=2))
            text = f"{c['where']}: {fmt(c['value'], c['unit'])} {fmt_interval(c)}"
            if c["verdict"] == INCONCLUSIVE and _need(c):
                text += f"; ~{_need(c)} trials would decide"
            ax.text(j + 0.5, i + 0.3, c["verdict"], ha="center", va="center", fontsize=8,
                    fontweight="bold")
            ax.text(j + 0.5, i + 0.65, textwrap.fill(text, 46), ha="center", va="center",
                    fontsize=6.5, linespacing=1.1)
    for s in ax.spines.values():
        s.set_visible(False)
    handles = [plt.Rectangle((0, 0), 1, 1, fc=col) for col in COLOURS.values()]
    ax.legend(handles, list(COLOURS), loc="upper center", bbox_to_anchor=(0.5, -0.02), ncol=3,
              frameon=False, fontsize=8)
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    return fig


def results(aggs: dict, stages: dict | None = None) -> list[dict]:
    """Every test of every figure that declares the paper's claims (aggs: figure -> aggregate with
    its trials), and of Fig. 2's stages (`stages`: figure, spec, per-trial Ms), measured."""
    tests = []
    for name, agg in aggs.items():
        if (agg["summary"]["growth"] != "none").any():
            tests += growth_tests(name, agg["trials"], agg["summary"])
    if stages:
        tests += stage_tests(stages["figure"], stages["spec"], stages["trials"])
    return [run_test(t) for t in tests]
