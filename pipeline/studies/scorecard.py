"""The scorecard: every claim of the paper on every figure, with a 95 % interval over trials.

Each claim's measure (pipeline/studies/claims.py) is a value per trial; a cell's value is its
mean over the trials, and the interval is Student's t interval of that mean:

    mean +- t(0.975, n - 1) * s / sqrt(n)

Why t, on per-trial values: the mean of independent trials is what the t interval is for, its
point always lies inside it, and its coverage measured by drawing 3, 5 and 10 of 20 trials
(pipeline/studies/coverage.py, docs/scorecard.md) is near 95 % for every measure type; the
percentile bootstrap of a maximum of the mean curve was biased (it covered the 20-trial value in
far fewer than 95 % of draws) and had its point outside its own interval.

    reproduced      the interval lies within the criterion
    not reproduced  the interval lies outside it, and the measure's coverage at this trial
                    count is established (COVERAGE, >= MIN_COVERAGE); else inconclusive
    inconclusive    the interval straddles a bound of the criterion (or there is one trial only)

A cell (claim x figure) holds one measure per condition: it is not reproduced if any is, else
inconclusive if any is, else reproduced; it shows its worst condition and how many of its
measures are reproduced. For an inconclusive measure, `trials_to_decide` is the trial count per
condition at which an interval of the observed spread (its half-width shrinking as 1 / sqrt(n))
would no longer reach the bound.
"""
from __future__ import annotations

import math
import textwrap
from pathlib import Path

import numpy as np
import pandas as pd
from scipy import stats

from .claims import BY_ID, CLAIMS, DIVERGED, Test, stage_tests, tests as growth_tests, title

LEVEL = 0.95
MIN_COVERAGE = 0.90  # a measure type's interval is trusted to say "not reproduced" from here
COVERAGE = Path(__file__).parent / "coverage.csv"  # written by pipeline.studies.coverage
TITLES = {c.id: title(c.id) for c in CLAIMS}
REPRODUCED, NOT, INCONCLUSIVE = "reproduced", "not reproduced", "inconclusive"


def interval(values: np.ndarray) -> tuple[float, float, float]:
    """(mean, low, high): the mean of the per-trial values and its 95 % t interval (no interval
    for one trial)."""
    v = np.asarray(values, float)
    point = float(v.mean()) if len(v) else np.nan
    if len(v) < 2:
        return point, np.nan, np.nan
    half = float(stats.t.ppf(0.5 + LEVEL / 2, len(v) - 1) * v.std(ddof=1) / math.sqrt(len(v)))
    return point, point - half, point + half


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


def coverage_table() -> pd.DataFrame:
    """The measured coverage per measure type and trial count (empty when never measured)."""
    if not COVERAGE.exists():
        return pd.DataFrame(columns=["kind", "trials", "draws", "coverage"])
    return pd.read_csv(COVERAGE)


def established(kind: str, n: int, table: pd.DataFrame | None = None) -> bool:
    """Whether the interval of measure type `kind` on n trials is trusted to say "not
    reproduced": the coverage measured at the largest trial count <= n is >= MIN_COVERAGE."""
    t = coverage_table() if table is None else table
    t = t[(t["kind"] == kind) & (t["trials"] <= n)]
    return bool(len(t)) and float(t.sort_values("trials")["coverage"].iloc[-1]) >= MIN_COVERAGE


def run_test(t: Test, table: pd.DataFrame | None = None) -> dict:
    """Measure a test and judge it; stores and returns its result."""
    if t.diverged:  # nothing to measure: the cell says so
        t.result = dict(figure=t.figure, claim=t.claim, diagnostic=BY_ID[t.claim].diagnostic,
                        where=t.where, value=np.nan, low=np.nan, high=np.nan, lo=t.lo, hi=t.hi,
                        unit=t.unit, kind=t.kind, trials=0, verdict=DIVERGED,
                        trials_to_decide=None, per_trial="")
        return t.result
    if t.exact:  # a count: the verdict is exact, the interval is the failure rate's
        k, n = (int(v) for v in t.values)
        ci = stats.binomtest(k, n).proportion_ci(LEVEL) if n else None
        point, low, high = (k / n if n else np.nan, ci.low if ci else np.nan,
                            ci.high if ci else np.nan)
        v, need, per_trial = (REPRODUCED if k == 0 else NOT), None, ""
    else:
        n = len(t.values)
        point, low, high = interval(t.values)
        v = verdict(low, high, t.lo, t.hi)
        if (v == NOT and not established(t.kind, n, table)) or n < BY_ID[t.claim].min_trials:
            v = INCONCLUSIVE
        need = trials_to_decide(point, low, high, t.lo, t.hi, n) if v == INCONCLUSIVE else None
        per_trial = " ".join(f"{x:.6g}" for x in t.values)
    t.result = dict(figure=t.figure, claim=t.claim, diagnostic=BY_ID[t.claim].diagnostic,
                    where=t.where, value=point, low=low, high=high, lo=t.lo, hi=t.hi,
                    unit=t.unit, kind=t.kind, trials=n, verdict=v, trials_to_decide=need,
                    per_trial=per_trial)
    return t.result


# --- cells, tables, figure -------------------------------------------------------------------------

def fmt(value: float, unit: str) -> str:
    if not np.isfinite(value):
        return "n/a"
    if unit == "%":
        return f"{100 * value:+.0f} %"
    if unit == "rate":
        return f"{100 * value:.0f} %"
    if unit == "m":  # a length, stored in metres, printed in mm
        return f"{1000 * value:.1f} mm"
    if unit == "rad":
        return f"{value:.2f} rad"
    return f"{value:.2f}x"


def fmt_interval(r: dict) -> str:
    if r.get("verdict") == DIVERGED:
        return "(every trial diverged)"
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


def _margin(g: pd.DataFrame) -> pd.Series:
    """How far each measure's point lies inside its criterion, relative to the bound's size
    (negative: outside); the worst condition of a cell has the smallest."""
    def rel(d, b):
        return d / np.maximum(np.abs(b.where(np.isfinite(b), 1.0)), 1e-2)
    return np.minimum(rel(g["value"] - g["lo"], g["lo"]), rel(g["hi"] - g["value"], g["hi"]))


def cells(results: list[dict]) -> pd.DataFrame:
    """One cell per (claim, figure): the verdict of all its measures (not reproduced if any is,
    else inconclusive if any is, else reproduced), how many are reproduced (k of n), and the
    worst measure (the smallest margin to the criterion), which the cell shows."""
    df = pd.DataFrame(results)
    rows = []
    for (claim, figure), g in df.groupby(["claim", "figure"], sort=False):
        vs = g["verdict"].tolist()
        v = (DIVERGED if DIVERGED in vs else NOT if NOT in vs else INCONCLUSIVE
             if INCONCLUSIVE in vs else REPRODUCED)
        pick = g.loc[_margin(g).fillna(-np.inf).idxmin()]
        need = pick["trials_to_decide"]
        rows.append(dict(claim=claim, figure=figure, diagnostic=bool(BY_ID[claim].diagnostic),
                         verdict=v, where=pick["where"], value=pick["value"], low=pick["low"],
                         high=pick["high"], unit=pick["unit"], trials=int(pick["trials"]),
                         trials_to_decide=None if need is None or pd.isna(need) else int(need),
                         reproduced=vs.count(REPRODUCED), measures=len(g),
                         per_trial=pick.get("per_trial", ""), lo=pick["lo"], hi=pick["hi"]))
    return pd.DataFrame(rows)


def _need(r: dict) -> int | None:
    """The trials to decide, as an int (pandas turns a column with gaps into floats)."""
    n = r.get("trials_to_decide")
    return None if n is None or pd.isna(n) else int(n)


def cell_text(c, newline: str = " ") -> str:
    """'not reproduced', k of n, the worst measure: its value and interval (+ trials to
    decide)."""
    r = dict(c)
    text = f"**{r['verdict']}**"
    if r.get("measures", 1) > 1:
        text += f" ({r['reproduced']} of {r['measures']} reproduced)"
    text += f"{newline}worst: {r['where']}: {fmt(r['value'], r['unit'])} {fmt_interval(r)}"
    if r["verdict"] == INCONCLUSIVE and _need(r):
        text += f"{newline}~{_need(r)} trials would decide"
    return text


def _order(cards: pd.DataFrame) -> tuple[list, list]:
    claims = [c.id for c in CLAIMS if c.id in set(cards["claim"])]
    figs = sorted(set(cards["figure"]))
    return claims, figs


def headline(cards: pd.DataFrame, counted=None) -> dict:
    """Cells per verdict over the paper's claims (no diagnostics) on the counted figures (None:
    every figure): each claim of the paper once per figure it is judged on."""
    c = cards[~cards["diagnostic"].astype(bool)]
    if counted is not None:
        c = c[c["figure"].isin(counted)]
    return {v: int((c["verdict"] == v).sum()) for v in (REPRODUCED, NOT, INCONCLUSIVE, DIVERGED)}


def claims_table(cards: pd.DataFrame) -> pd.DataFrame:
    """claims.csv: one row per cell, the claim's words, criterion and measure from the table of
    claims, and the cell's verdict, worst condition and k of n, from the same results as
    scorecard.csv."""
    rows = []
    for r in cards.to_dict("records"):
        c = BY_ID[r["claim"]]
        rows.append(dict(figure=r["figure"], claim=r["claim"], words=c.words,
                         diagnostic=c.diagnostic, criterion=c.criterion, measure=c.measure,
                         verdict=r["verdict"], reproduced=r["reproduced"],
                         measures=r["measures"], worst=r["where"],
                         measured=f"{fmt(r['value'], r['unit'])} {fmt_interval(r)}",
                         trials=r["trials"]))
    return pd.DataFrame(rows)


def markdown(cards: pd.DataFrame, results: list[dict], counted=None, readings=None) -> str:
    """The scorecard (claims x figures) and, below it, every measure with its interval.
    counted: the figures the headline counts; readings: claim -> our reading (written text)."""
    claims, figs = _order(cards)
    n = headline(cards, counted)
    where = "" if counted is None else f" on {', '.join(sorted(counted))}"
    lines = [f"The paper's claims{where}: **{n[REPRODUCED]} reproduced, {n[NOT]} not reproduced, "
             f"{n[INCONCLUSIVE]} inconclusive" + (f", {n[DIVERGED]} diverged" if n[DIVERGED]
                                                   else "") + "** (95 % t intervals of the mean over trials of a "
             "per-trial measure; diagnostics, marked, are shown and not counted).",
             "", "| claim of the paper | " + " | ".join(figs) + " | our reading |",
             "|---|" + "---|" * (len(figs) + 1)]
    for claim in claims:
        row = cards[cards["claim"] == claim]
        by = {r.figure: cell_text(r._asdict(), "<br>") for r in row.itertuples()}
        lines.append(f"| {TITLES[claim]} | " + " | ".join(by.get(f, "—") for f in figs)
                     + f" | {(readings or {}).get(claim, '')} |")
    lines += ["", "<details><summary>every measure, its 95 % interval and criterion</summary>", "",
              "| figure | claim | measure | value | 95 % interval | criterion | trials | verdict "
              "| trials to decide |", "|---|---|---|---|---|---|---|---|---|"]
    for r in results:
        lines.append(f"| {r['figure']} | {TITLES[r['claim']]} | {r['where']} "
                     f"| {fmt(r['value'], r['unit'])} | {fmt_interval(r)} | {criterion(r)} "
                     f"| {r['trials']} | {r['verdict']} | {_need(r) or ''} |")
    lines += ["", "</details>", ""]
    return "\n".join(lines)


COLOURS = {REPRODUCED: "#b7e1b0", NOT: "#f4b6b0", INCONCLUSIVE: "#fbe3a0", DIVERGED: "#c9c3e6"}


def _trials_strip(ax, x0: float, y: float, c: dict) -> None:
    """Each trial's value of the cell's worst measure as a dot on a strip across the cell, the
    criterion's bounds as ticks and the 95 % interval as a bar: the spread the verdict judges."""
    values = np.array([float(v) for v in str(c.get("per_trial") or "").split()])
    if len(values) < 2 or c["unit"] == "rate":
        return
    bounds = [b for b in (c.get("lo"), c.get("hi")) if b is not None and np.isfinite(b)]
    span = np.concatenate([values, bounds, [c["low"], c["high"]]])
    span = span[np.isfinite(span)]
    lo, hi = float(span.min()), float(span.max())
    pad = 0.05 * (hi - lo or 1.0)
    lo, hi = lo - pad, hi + pad
    def at(v):
        return x0 + 0.08 + 0.84 * (np.asarray(v, float) - lo) / (hi - lo)
    ax.plot([x0 + 0.08, x0 + 0.92], [y, y], color="0.55", lw=0.5)
    for b in bounds:
        ax.plot([at(b)] * 2, [y - 0.06, y + 0.06], color="black", lw=0.8)
    if np.isfinite(c["low"]) and np.isfinite(c["high"]):
        ax.plot([at(c["low"]), at(c["high"])], [y, y], color="black", lw=2.2, alpha=0.35,
                solid_capstyle="butt")
    ax.scatter(at(values), np.full(len(values), y), s=5, color="black", zorder=3, lw=0)


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
            text = (f"{c['reproduced']} of {c['measures']} reproduced; " if c["measures"] > 1
                    else "") + f"worst: {c['where']}: {fmt(c['value'], c['unit'])} {fmt_interval(c)}"
            if c["verdict"] == INCONCLUSIVE and _need(c):
                text += f"; ~{_need(c)} trials would decide"
            ax.text(j + 0.5, i + 0.2, c["verdict"], ha="center", va="center", fontsize=8,
                    fontweight="bold")
            ax.text(j + 0.5, i + 0.5, textwrap.fill(text, 46), ha="center", va="center",
                    fontsize=6.5, linespacing=1.1)
            _trials_strip(ax, j, i + 0.84, c)
    for s in ax.spines.values():
        s.set_visible(False)
    handles = [plt.Rectangle((0, 0), 1, 1, fc=col) for col in COLOURS.values()]
    ax.legend(handles, list(COLOURS), loc="upper center", bbox_to_anchor=(0.5, -0.02), ncol=len(COLOURS),
              frameon=False, fontsize=8)
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    return fig


def results(aggs: dict, stages: dict | None = None, table: pd.DataFrame | None = None) -> list[dict]:
    """Every test of every figure that declares the paper's claims (aggs: figure -> aggregate with
    its trials), and of Fig. 2's stages (`stages`: figure, spec, per-trial Ms), measured."""
    tests = []
    for name, agg in aggs.items():
        if (agg["summary"]["growth"] != "none").any():
            tests += growth_tests(name, agg["trials"], agg["summary"])
    if stages:
        tests += stage_tests(stages["figure"], stages["spec"], stages["trials"])
    table = coverage_table() if table is None else table
    return [run_test(t, table) for t in tests]
