"""Calibration from a replicate set (docs/scorecard.md): does the prediction interval of each
counted measure (the scorecard's interval widened for the replicate's noise) cover the mean of
an independent run from another root seed? The shares are pooled per claim against the exact
95 % range; calibration.csv has one row per (figure, claim, where).
"""
from __future__ import annotations

import math

import numpy as np
import pandas as pd
from scipy import stats

from . import claims, coverage, scorecard
from .choices import escape
from .sections import Context, prose, reads, register

STUDY = "replicate"
SHARE = {"final": "calibration.final.share", "rise": "calibration.rise.share",  # quoted names
         "rise_none": "calibration.rise_none.share", "blend": "calibration.blend.share",
         "after": "calibration.after.share"}
RANGE = 0.95  # the two-sided probability of the expected range of a pooled share
COLUMNS = ["figure", "claim", "where", "deciding", "n1", "n2", "level", "mean", "low", "high",
           "replicate_mean", "covered"]


def prediction(values, n2: int, level: float) -> tuple[float, float, float]:
    """(mean, low, high): the prediction interval of the mean of n2 new trials."""
    v = np.asarray(values, float)
    mean = float(v.mean()) if len(v) else np.nan
    if len(v) < 2 or n2 < 1:
        return mean, np.nan, np.nan
    half = float(stats.t.ppf(0.5 + level / 2, len(v) - 1) * v.std(ddof=1)
                 * math.sqrt(1 / len(v) + 1 / n2))
    return mean, mean - half, mean + half


def rows(figure: str, first: list, second: list, scale: str = "",
         table: pd.DataFrame | None = None) -> list[dict]:
    """calibration.csv's rows of one figure: its measures and the replicate's (`second`), paired
    by (claim, where, points, span), the first judged as the scorecard judges it at `scale`."""
    table = coverage.current() if table is None else table
    res = scorecard.no_verdicts(scorecard.judged(first, table), scale)  # calibrates `first`
    cards = scorecard.cells(res) if res else pd.DataFrame(columns=["claim", "where"])
    deciding = set(zip(cards["claim"], cards["where"]))
    key = lambda m: (m.claim, m.where, m.points, m.span)  # noqa: E731
    other = {key(m): m for m in second if not (m.exact or m.diverged)}
    out = []
    for m1 in first:
        m2 = other.get(key(m1))
        if m2 is None or m1.exact or m1.diverged:
            continue
        for t1, t2 in zip(claims.judge([m1]), claims.judge([m2])):
            r = scorecard.run_test(t1, table)
            if not r["primary"] or r["diagnostic"] or t1.control is not None:
                continue
            mean, low, high = prediction(t1.values, len(t2.values), r["level"])
            if not np.isfinite(low):  # one trial (or none in the replicate): no interval
                continue
            rep = float(np.mean(t2.values))
            out.append(dict(figure=figure, claim=t1.claim, where=t1.where,
                            deciding=(t1.claim, t1.where) in deciding, n1=len(t1.values),
                            n2=len(t2.values), level=r["level"], mean=mean, low=low, high=high,
                            replicate_mean=rep, covered=bool(low <= rep <= high)))
    return out


def expected_range(levels) -> tuple[int, int]:
    """(lo, hi): the two-sided RANGE of the number covering if each covers with its level."""
    pmf = np.ones(1)
    for p in levels:
        pmf = np.convolve(pmf, [1 - p, p])
    cdf = np.cumsum(pmf)
    tail = (1 - RANGE) / 2
    return (int(np.searchsorted(cdf, tail - 1e-12)),
            int(np.searchsorted(cdf, 1 - tail - 1e-12)))


def summary(table: pd.DataFrame) -> pd.DataFrame:
    """Per claim, pooled over the figures: the share covering, its expected range, `fails`."""
    out = []
    for claim, g in table.groupby("claim", sort=False):
        n, k = len(g), int(g["covered"].sum())
        lo, hi = expected_range(g["level"].to_numpy(float))
        out.append(dict(claim=claim, figures=", ".join(dict.fromkeys(g["figure"])),
                        intervals=n, covered=k, share=k / n, expected_low=lo / n,
                        expected_high=hi / n, fails=k < lo))
    return pd.DataFrame(out, columns=["claim", "figures", "intervals", "covered", "share",
                                      "expected_low", "expected_high", "fails"])


def failing(table: pd.DataFrame, scale: str = "") -> set[tuple[str, str]]:
    """The (figure, claim) cells whose claim's pooled share lies below its range or whose own
    deciding condition is not covered (none at a reduced scale)."""
    if scale or not len(table):
        return set()
    bad = set(summary(table).query("fails")["claim"])
    hit = table[table["claim"].isin(bad) | (table["deciding"].astype(bool)
                                            & ~table["covered"].astype(bool))]
    return set(zip(hit["figure"], hit["claim"]))


def _pairs(ctx: Context) -> dict:
    """(replicate, figure) -> (the figure's measures, the replicate's), made once."""
    def make():
        figs, reps, out = ctx.of("figures"), ctx.of(STUDY), {}
        for r, f in reads(STUDY).items():
            if r in reps and f in figs and "trials" in reps[r] and "trials" in figs[f]:
                out[(r, f)] = tuple(claims.measures(f, a["trials"], a["summary"])
                                    for a in (figs[f], reps[r]))
        return out
    return ctx.once("replicate measures", make)


def calibrate(ctx: Context) -> pd.DataFrame:
    """calibration.csv of the report `ctx`, made once."""
    scale = ctx.cfg.report.scale or ""
    return ctx.once("replicate calibration", lambda: pd.DataFrame(
        [x for (_, f), (a, b) in _pairs(ctx).items() for x in rows(f, a, b, scale)],
        columns=COLUMNS))


def frames(ctx: Context) -> list[pd.DataFrame]:
    """measures.parquet's rows of the replicate sets."""
    from . import measures_table

    return [measures_table.frame(b, STUDY) for (_, f), (_, b) in _pairs(ctx).items()]


def markdown(s: pd.DataFrame) -> str:
    lines = ["| claim | figures | intervals | covering the replicate | share | expected "
             f"({100 * RANGE:g} % range) |", "|---|---|--:|--:|--:|---|"]
    lines += [f"| {escape(scorecard.TITLES[r.claim])} | {r.figures} | {r.intervals} | {r.covered} "
              f"| {100 * r.share:.0f} % | {100 * r.expected_low:.0f}-{100 * r.expected_high:.0f} %"
              + (" **below**" if r.fails else "") + " |" for r in s.itertuples()]
    return "\n".join(lines) + "\n"


@register(STUDY, 15)
def section(ctx: Context) -> list[str]:
    table = calibrate(ctx)
    if not len(table):
        alone = [f"{r} (of {f})" for r, f in reads(STUDY).items() if r in ctx.of(STUDY)]
        return ["## Calibration: no replicate set with its figure", "",
                prose("replicate.alone", alone=", ".join(alone)), ""] if alone else []
    ctx.text("calibration.csv", table.to_csv(index=False, float_format="%.6g"))
    s, scale = summary(table), ctx.cfg.report.scale
    for r in s.itertuples():
        if r.claim in SHARE:
            ctx.value(SHARE[r.claim], r.share)
    bad = sorted(failing(table))
    verdict = (f"A {scale} run ({int(table['n1'].max())} trials): measured, not a verdict at "
               "that scale." if scale else
               prose("replicate.fails", cells=", ".join(f"{c} on {f}" for f, c in bad) or "none"))
    pairs = ", ".join(f"{r} (of {f})" for r, f in _pairs(ctx))
    return ["## Calibration: the scorecard's intervals against a replicate set", "",
            prose("replicate.section", pairs=pairs), "", markdown(s), verdict, ""]
