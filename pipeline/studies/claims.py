"""The paper's claims, checked against the aggregated results with numbers.

Each check returns rows (figure, claim, measured, verdict) for report.md and claims.csv. The
criteria (CRITERIA, with the thresholds below) were fixed before the full-scale results existed.
"""
from __future__ import annotations

import numpy as np
import pandas as pd

import gbmodel

from .figures import final_body

FACTOR = 1.5  # "about" the paper's final error: within this factor of it
RISE = 0.10  # a temporary rise during growth: above this fraction of the error before it
EXCESS = 0.20  # blending and no degeneration: curves stay within this fraction

CRITERIA = f"""Verdicts, with criteria fixed before the full-scale run:
- *final error about the paper's value*: the mean final absolute error of every condition lies
  within a factor {FACTOR:g} of it;
- *temporary rise during growth*: the mean absolute error rises during epochs 1 ... T_G + 1 by
  more than {RISE:.0%} of the lowest error reached before the rise (required for T_G <= 1000);
- *above the references during growth* (added after the full run, when a review showed that the
  pre-set measure above misses a rise slower than the learner's own progress): the mean absolute
  error of a growing body exceeds the larger of the two constant-size references at the same
  epoch, during epochs 1 ... T_G + 1, by more than {RISE:.0%} (required for T_G <= 1000);
- *blending*: the mean relative error of a growing body never exceeds the larger of the two
  references by more than {EXCESS:.0%}, and ends within {EXCESS:.0%} of the long reference;
- *no degeneration*: after growth the mean relative error never rebounds more than {EXCESS:.0%}
  above its running minimum, and ends below its value at the end of growth;
- *bootstrapping succeeds in every trial*: no trial failed to run or to bootstrap (final
  relative error above `aggregate.fail_factor` times its condition's median);
- *above the start body during growth* (added after the full run, marked "added": the paper's
  "more distant targets" compare the growing body with the body it starts from): the mean
  absolute error of a growing body exceeds the constant short reference at the same epoch,
  during epochs 1 ... T_G + 1, by more than {RISE:.0%} (required for T_G <= 1000);
- *no degeneration during growth* (added): during growth the mean relative error never rebounds
  more than {EXCESS:.0%} above its running minimum;
- *Fig. 2 stages*: after epoch 1 the estimate is within 0.2 rad of home (0.1 at initialisation
  plus one step), its spread over the targets grows
  from stage to stage, and at the end both extreme heights are reached within 5 cm."""


DIVERGED = "diverged"  # what a condition all of whose trials diverged is marked with
# the claims that compare growing bodies with the two constant-size references
REFERENCE_CLAIMS = (
    "the absolute error rises above both constant-size references during growth, T_G in "
    "{10, 100, 1000} (measure added after the full run)",
    "the absolute error rises above the body growth starts from during growth, T_G in "
    "{10, 100, 1000} (added)",
    "the relative error blends between the short and the long reference")


def diverged_conditions(summary: pd.DataFrame) -> list[str]:
    """The conditions none of whose trials left a curve (every one diverged or failed): no mean
    curve to check a claim on."""
    if "n_trials" not in summary:
        return []
    return [str(c) for c in summary.loc[summary["n_trials"] == 0, "condition"]]


def _mm(v: float) -> str:
    return f"{1000 * v:.1f} mm"


def _verdict(failing: list[str]) -> str:
    """'reproduced', or 'not reproduced' and where the criterion fails."""
    return "reproduced" if not failing else "not reproduced: " + ", ".join(failing)


def _curve(curves: pd.DataFrame, condition: str, column: str) -> pd.Series:
    c = curves[curves["condition"] == condition].sort_values("epoch")
    return pd.Series(c[f"{column}_mean"].to_numpy(), index=c["epoch"].to_numpy())


def _above(figure, curves, growing, reference: pd.Series, claim: str) -> dict:
    """How far each growing body's mean absolute error exceeds `reference` at the same epoch
    during epochs 1 ... T_G + 1; required above RISE for T_G <= 1000."""
    parts, failing = [], []
    for r in growing.itertuples():
        g = _curve(curves, r.condition, "abs_error")
        during = g[g.index <= r.growth_period + 1]
        excess = during / reference[during.index] - 1
        parts.append(f"T_G={r.growth_period}: +{100 * max(excess.max(), 0):.0f} % at epoch "
                     f"{excess.idxmax()}")
        if r.growth_period <= 1000 and excess.max() <= RISE:
            failing.append(f"T_G={r.growth_period}")
    return dict(figure=figure, claim=claim, measured="; ".join(parts), verdict=_verdict(failing))


def growth_claims(figure: str, curves: pd.DataFrame, summary: pd.DataFrame) -> list[dict]:
    """Claims of Fig. 4, 5 and 7 (sec. 3.1-3.3) for one figure's conditions."""
    rows = []
    dead = diverged_conditions(summary)
    alive = summary[~summary["condition"].isin(dead)]
    # named in the verdict of every claim on growing bodies
    lost = [f"{c} {DIVERGED}" for c in summary.loc[(summary["growth"] != "none")
                                                   & summary["condition"].isin(dead), "condition"]]
    growing = alive[alive["growth"] != "none"]
    refs = summary[summary["growth"] == "none"].sort_values("end_size")
    dead_refs = [c for c in refs["condition"] if c in dead]
    paper = summary["paper_final_abs_error"].iloc[0] if len(summary) else np.nan
    if np.isfinite(paper) and len(alive):
        finals = alive.set_index("condition")["final_abs_error_mean"]
        ratio = finals / paper
        rows.append(dict(
            figure=figure, claim=f"final error about {_mm(paper)}, with and without growth",
            measured="; ".join(f"{c} {_mm(v)}" for c, v in finals.items())
            + "".join(f"; {c} {DIVERGED}" for c in dead)
            + f" (ratio to the paper {ratio.min():.2f} ... {ratio.max():.2f})",
            verdict=_verdict([f"{c} ({v:.2f})" for c, v in ratio.items()
                              if not 1 / FACTOR <= v <= FACTOR] + [f"{c} {DIVERGED}"
                                                                   for c in dead])))
    if dead_refs and len(refs) == 2:
        for claim in REFERENCE_CLAIMS:
            rows.append(dict(figure=figure, claim=claim,
                             measured=f"not measured: {', '.join(dead_refs)} {DIVERGED}",
                             verdict=f"{DIVERGED}: {', '.join(dead_refs)}"))
    refs = refs[~refs["condition"].isin(dead)]
    if len(growing):
        parts, failing = [], []
        for r in growing.itertuples():
            before = r.peak_abs_error_growth - r.rise_abs_error_growth
            rel = r.rise_abs_error_growth / before if before > 0 else 0.0
            parts.append(f"T_G={r.growth_period}: +{_mm(r.rise_abs_error_growth)} "
                         f"(+{100 * rel:.0f} %) at epoch {r.peak_epoch_growth}")
            if r.growth_period <= 1000 and rel <= RISE:
                failing.append(f"T_G={r.growth_period}")
        rows.append(dict(figure=figure,
                         claim="the absolute error rises temporarily during growth for "
                               "T_G in {10, 100, 1000}",
                         measured="; ".join(parts), verdict=_verdict(failing + lost)))
    if len(growing) and len(refs) == 2:
        upper = np.maximum(*(_curve(curves, c, "abs_error") for c in refs["condition"]))
        rows.append(_above(figure, curves, growing, upper, REFERENCE_CLAIMS[0]))
        rows.append(_above(figure, curves, growing,
                           _curve(curves, refs["condition"].iloc[0], "abs_error"),
                           REFERENCE_CLAIMS[1]))
        short, long_ = (_curve(curves, c, "rel_error") for c in refs["condition"])
        upper = np.maximum(short, long_)
        parts, failing = [], []
        for r in growing.itertuples():
            g = _curve(curves, r.condition, "rel_error")
            excess = float(((g - upper) / upper).max())
            end = float(g.iloc[-1] / long_.iloc[-1] - 1)
            parts.append(f"T_G={r.growth_period}: at most {100 * max(excess, 0):.0f} % above "
                         f"the upper reference, final {100 * end:+.0f} % vs the long one")
            if excess > EXCESS or abs(end) > EXCESS:
                failing.append(f"T_G={r.growth_period}")
        rows.append(dict(figure=figure, claim=REFERENCE_CLAIMS[2], measured="; ".join(parts),
                         verdict=_verdict(failing + lost)))
    if len(growing):
        parts, failing = [], []
        for r in growing.itertuples():
            g = _curve(curves, r.condition, "rel_error")
            after = g[g.index >= r.growth_period + 1]
            if len(after) < 2:
                continue
            bounce = float((after / np.minimum.accumulate(after.to_numpy()) - 1).max())
            parts.append(f"T_G={r.growth_period}: {after.iloc[0] * 1000:.1f} -> "
                         f"{after.iloc[-1] * 1000:.1f} mm/size after growth, largest "
                         f"rebound {100 * bounce:.0f} %")
            if not (after.iloc[-1] < after.iloc[0] and bounce <= EXCESS):
                failing.append(f"T_G={r.growth_period}")
        rows.append(dict(figure=figure, claim="no degeneration: the error keeps decreasing "
                         "after growth", measured="; ".join(parts),
                         verdict=_verdict(failing + lost)))
        parts, failing = [], []
        for r in growing.itertuples():
            g = _curve(curves, r.condition, "rel_error")
            during = g[g.index <= r.growth_period + 1].to_numpy()
            bounce = float((during / np.minimum.accumulate(during) - 1).max())
            parts.append(f"T_G={r.growth_period}: largest rebound {100 * bounce:.0f} %")
            if bounce > EXCESS:
                failing.append(f"T_G={r.growth_period}")
        rows.append(dict(figure=figure, claim="no degeneration during growth: the relative error "
                         "does not rebound while the body grows (added)",
                         measured="; ".join(parts), verdict=_verdict(failing + lost)))
    fails = int(summary["n_bootstrap_failures"].sum() + summary["n_run_failures"].sum()
                + summary.get("n_diverged", pd.Series(dtype=int)).sum())
    rows.append(dict(figure=figure, claim="bootstrapping succeeds in every trial",
                     measured=f"{fails} of {int(summary['n_trials'].sum())} trials failed "
                              f"(per condition: "
                              + ", ".join(f"{r.condition} "
                                          f"{r.n_bootstrap_failures + r.n_run_failures + getattr(r, 'n_diverged', 0)}"
                                          for r in summary.itertuples()) + ")",
                     verdict=_verdict([] if fails == 0 else [f"{fails} trials"])))
    return rows


def stage_claims(figure: str, spec: dict, stages: list) -> list[dict]:
    """Fig. 2: the inverse estimate starts around home, aligns, expands, reaches the extremes.

    For each stage: the largest joint deviation from home over the target set, the mean error,
    and the error at the two extreme targets (heights -1 and +1 m).
    """
    body, size, pattern, exps = final_body(spec)
    xs = body.target_set(size)
    parts, spreads, extremes = [], [], []
    for label, M in stages:
        q = gbmodel.predict(np.asarray(M), xs, exps)
        err = np.linalg.norm(body.forward(q, size, pattern) - xs, axis=-1)
        spreads.append(float(np.abs(q - body.home).max()))
        extremes.append(float(max(err[0], err[-1])))
        parts.append(f"{label}: largest joint deviation from home {spreads[-1]:.2f} rad, mean error "
                     f"{_mm(err.mean())}, at the extremes {_mm(extremes[-1])}")
    failing = ([f"starts {spreads[0]:.2f} rad from home"] if spreads[0] > 0.2 else []) \
        + (["the spread does not grow at every stage"] if any(np.diff(spreads) <= 0) else []) \
        + ([f"extremes missed by {_mm(extremes[-1])}"] if extremes[-1] >= 0.05 else [])
    return [dict(figure=figure, claim="stages: around home, aligned and expanding, reaching "
                 "the extremes", measured="; ".join(parts), verdict=_verdict(failing))]


def markdown(rows: list[dict]) -> str:
    lines = ["| figure | claim of the paper | measured | verdict |", "|---|---|---|---|"]
    lines += [f"| {r['figure']} | {r['claim']} | {r['measured']} | {r['verdict']} |" for r in rows]
    return "\n".join(lines) + "\n"
