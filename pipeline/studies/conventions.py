"""Reporting conventions (conventions.csv): the measured effect of each alternative on the
paper's figures (those declaring `conventions: true`), from their aggregates alone: the spread's
ddof, the failed-to-bootstrap factor, trial 0's rank in the postures, the curves' sampling, the
relative error's normalisation. A row whose data is absent is left out."""
from __future__ import annotations

import numpy as np
import pandas as pd

import gbmodel
from gbmodel import evaluation

from ..measures import finals as trial_finals, growth_peak
from .choices import escape
from .sections import declared


def figures_declared() -> tuple[str, ...]:
    """The experiments whose file declares `conventions: true`, in declared order."""
    return tuple(n for n, e in declared().items() if e.declares.conventions)


FACTORS = (1.5, 2.0, 5.0)  # alternatives to aggregate.fail_factor
STRIDES = (2, 4)  # every 2nd, every 4th evaluation point
COLUMNS = ["convention", "ours", "alternative", "measured_effect"]


def finals(trials: dict) -> pd.DataFrame:
    """Each trial's final row (measures.finals), of every figure."""
    frames = [trial_finals(t) for t in trials.values()]
    return pd.concat(frames, ignore_index=True) if frames else pd.DataFrame()


def _where(figure, condition) -> str:
    return f"{figure} {condition}"


def spread(fin: pd.DataFrame) -> dict | None:
    """ddof 0 / ddof 1 of the final errors per trial count n, and the largest deviation from
    sqrt((n - 1) / n) (None without 2 trials anywhere)."""
    per_n, count, dev = {}, {}, 0.0
    for _, g in fin.groupby(["figure", "condition"], sort=False):
        n = len(g)
        cols = [c for c in ("abs_error", "rel_error") if n > 1 and g[c].std(ddof=1) > 0]
        count[n] = count.get(n, 0) + bool(cols)
        for col in cols:
            ratio = g[col].std(ddof=0) / g[col].std(ddof=1)
            per_n.setdefault(n, []).append(ratio)
            dev = max(dev, abs(ratio - np.sqrt((n - 1) / n)))
    if not per_n:
        return None
    return dict(ratio={n: float(np.mean(r)) for n, r in sorted(per_n.items(), reverse=True)},
                conditions=count, deviation=dev)


def flagged(fin: pd.DataFrame, factors) -> dict:
    """Per factor the trials whose final relative error exceeds factor x their condition's
    median; the trial count and the largest final / median ratio and where."""
    median = fin.groupby(["figure", "condition"], sort=False)["rel_error"].transform("median")
    ratio = fin["rel_error"] / median
    i = int(np.argmax(ratio.to_numpy()))
    r = fin.iloc[i]
    return dict(counts={f: int((fin["rel_error"] > f * median).sum()) for f in factors},
                trials=len(fin), largest=float(ratio.iloc[i]),
                where=f"{_where(r['figure'], r['condition'])}, trial {r['trial']}")


def trial0_rank(fin: pd.DataFrame, wanted) -> list[dict]:
    """Per (panel, figure, condition): trial 0's final error, rank (1 = smallest), percentile
    (0 best) and the condition's median."""
    out = []
    for panel, figure, condition in wanted:
        g = fin[(fin["figure"] == figure) & (fin["condition"] == condition)]
        if not (g["trial"] == 0).any():
            continue
        e = g["abs_error"].to_numpy()
        e0 = float(g.loc[g["trial"] == 0, "abs_error"].iloc[0])
        rank = int((e < e0).sum()) + 1
        out.append(dict(panel=panel, where=_where(figure, condition), error=e0, rank=rank, n=len(e),
                        percentile=100 * (rank - 1) / (len(e) - 1) if len(e) > 1 else np.nan,
                        median=float(np.median(e))))
    return out


def rise_pct(curve: pd.DataFrame) -> float:
    """The rise during growth (measures.growth_peak) in % of the lowest error before it."""
    _, peak, rise = growth_peak(curve)
    before = peak - rise
    return 100 * rise / before if before > 0 else np.nan


def subsampled_rise(curves: pd.DataFrame, summary: pd.DataFrame, strides) -> list[dict]:
    """Per growing condition: rise_pct of the mean curve, and of every k-th point of it."""
    out = []
    for r in summary.itertuples():
        if r.growth == "none":
            continue
        c = curves[curves["condition"] == r.condition].sort_values("epoch")
        if len(c):  # k = 1: the stored curve
            rise = {k: rise_pct(c.iloc[::k][c.iloc[::k]["epoch"] <= r.growth_period + 1])
                    for k in (1, *strides)}
            out.append({"where": _where(r.figure, r.condition), "full": rise.pop(1), **rise})
    return out


def length_ratio(body, scales) -> np.ndarray:
    """The chain's total segment length at per-joint length factors `scales` over the full one."""
    def total(k):
        ch = body.chain(k)
        return np.hypot(ch["a"], ch["d"]).sum(axis=-1)

    return total(np.asarray(scales, np.float64)) / total(np.ones(body.m))


def normalisations(spec: dict) -> dict:
    """eq. 11's S against L / L_full over the spec's evaluation epochs: the largest
    |S / (L / L_full) - 1|, and the range of the per-joint length factors over S."""
    s = gbmodel.TrialSpec.from_dict(spec)
    body, growth = s.make_body(), s.make_growth()
    sizes = growth.sizes(evaluation.eval_epochs(s.epochs, s.evals_per_decade))
    scales = growth.scales(body, sizes)
    per_joint = scales / sizes[:, None]
    return dict(difference=float(np.max(np.abs(sizes / length_ratio(body, scales) - 1))),
                spread=(float(per_joint.min()), float(per_joint.max())))


def _g(v) -> str:
    return f"{v:.3g}"


def _postures_row(ranks: list[dict], named: dict) -> tuple:
    """The row of trial0_rank's ranks; `named` gets the numbers the pages quote."""
    cells = []
    for r in ranks:
        pct = f"{100 * (r['error'] / r['median'] - 1):+.3g}"
        if (r["where"], r["panel"]) in QUOTED_RANKS:
            name, sign = QUOTED_RANKS[r["where"], r["panel"]]
            named[name] = sign * float(pct)
        at = "" if np.isnan(r["percentile"]) else f", percentile {r['percentile']:.0f}"
        cells.append(f"{r['where']} ({r['panel']}): rank {r['rank']} of {r['n']}{at}, "
                     f"{_g(1e3 * r['error'])} mm against the median {_g(1e3 * r['median'])} "
                     f"mm ({pct} %)")
    return ("Fig. 3 / 6 postures", "trial 0's final model", "another trial (e.g. the median one)",
            "trial 0's final abs. error (rank 1 = smallest): " + "; ".join(cells))


def _sampling_row(aggs: dict) -> tuple | None:
    sub = [r for a in aggs.values() for r in subsampled_rise(a["curves"], a["summary"], STRIDES)]
    cells = []
    for k in STRIDES:
        d = [(r[k] - r["full"], r) for r in sub if np.isfinite(r[k]) and np.isfinite(r["full"])]
        if not d:
            continue
        pp, r = max(d, key=lambda x: abs(x[0]))
        cell = (f"every {k}{'nd' if k == 2 else 'th'}: largest change {pp:+.3g} percentage "
                f"points ({r['where']}: +{_g(r['full'])} % -> +{_g(r[k])} %)")
        rel = [(r[k] / r["full"], r) for _, r in d if r["full"] > 0]
        if rel:
            _, q = min(rel, key=lambda x: x[0])
            cell += f", relatively most {q['where']} (+{_g(q['full'])} % -> +{_g(q[k])} %)"
        cells.append(cell)
    return ("learning-curve sampling",
            "about 20 log-spaced evaluations per decade; the growth peak read from them",
            "every 2nd / every 4th evaluation point", "rise of the mean abs. error during growth "
            f"(% of the lowest error before it), over {len(sub)} growing conditions: "
            + "; ".join(cells)) if cells else None


def _normalisation_row(aggs: dict) -> tuple | None:
    norms = [(name, cond, normalisations(c["spec"])) for name, a in aggs.items()
             for cond, c in a["models"]["conditions"].items()]
    if not norms:
        return None
    diff, name, cond = max((x[2]["difference"], x[0], x[1]) for x in norms)
    uneven = [x[2]["spread"] for x in norms if not np.allclose(x[2]["spread"], 1.0)]
    effect = (f"0 within rounding ({diff:.1g})" if diff < 1e-12 else
              f"up to {_g(100 * diff)} % ({_where(name, cond)})")
    effect += f", largest over {len(norms)} conditions and their evaluation epochs"
    if uneven:
        effect += (f"; in the {len(uneven)} with unequal segments (per-joint length factors "
                   f"{_g(min(u[0] for u in uneven))}-{_g(max(u[1] for u in uneven))} x S) "
                   "the total length is still S x the full one")
    return ("relative error (eq. 11)", "absolute error / size factor S",
            "absolute error / (current total arm length / full arm length)", effect)


def table(aggs: dict, trials: dict, fail_factor: float, postures: dict) -> pd.DataFrame:
    """The conventions' rows from the aggregates, their per-trial curves (figure -> trials),
    aggregate.fail_factor and report.postures (panel -> [[figure, condition], ...])."""
    aggs = {k: a for k, a in aggs.items() if k in figures_declared()}
    fin = finals({k: t for k, t in trials.items() if k in aggs})
    rows, named = [], {}  # named: the numbers the pages quote (the table's attrs["values"])
    sp = spread(fin) if len(fin) else None
    if sp:
        named.update({name: -float(_g(100 * (sp["ratio"][n] - 1)))
                      for n, name in QUOTED_SPREAD.items() if n in sp["ratio"]})
        each = ", ".join(f"{_g(r)} for n = {n} ({_g(100 * (r - 1))} %, {sp['conditions'][n]} "
                         "conditions)" for n, r in sp["ratio"].items())
        rows.append(("spread over trials", "standard deviation with ddof = 1", "ddof = 0",
                     f"std(ddof 0) / std(ddof 1) of the final errors: {each}; equal to "
                     f"sqrt((n - 1) / n) within {sp['deviation']:.1g}"))
    if len(fin):
        fl = flagged(fin, sorted({*FACTORS, fail_factor}))
        counts = ", ".join(f"{f:g} x{' (ours)' if f == fail_factor else ''}: {c}"
                           for f, c in fl["counts"].items())
        rows.append(("failed to bootstrap",
                     f"final relative error > {fail_factor:g} x the condition's median",
                     ", ".join(f"{f:g} x" for f in FACTORS if f != fail_factor),
                     f"trials flagged of {fl['trials']}: {counts}; largest final / median ratio "
                     f"{_g(fl['largest'])} ({fl['where']})"))
    wanted = [(p, f, c) for p, pairs in postures.items() for f, c in pairs if f in aggs]
    ranks = trial0_rank(fin, wanted) if len(fin) else []
    rows += [_postures_row(ranks, named)] if ranks else []
    rows += [r for r in (_sampling_row(aggs), _normalisation_row(aggs)) if r]
    t = pd.DataFrame(rows, columns=COLUMNS)
    t.attrs["values"] = named
    return t


# the numbers of the table the pages quote, named where computed: the spread's change in %
# (negated) per trial count n, and trial 0's error over its condition's median in % per
# (condition, panel) (negated where the sign says so)
QUOTED_SPREAD = {20: "conventions.spread.ddof0.20_trials.below_pct",
                 5: "conventions.spread.ddof0.5_trials.below_pct"}
QUOTED_RANKS = {
    ("fig4 TG1000", "fig3"): ("conventions.postures.fig3.fig4_tg1000.trial0_over_median_pct", 1),
    ("fig5 TG1000", "fig3"): ("conventions.postures.fig3.fig5_tg1000.trial0_below_median_pct", -1),
    ("fig7 TG1000", "fig6"): ("conventions.postures.fig6.fig7_tg1000.trial0_over_median_pct", 1)}


def markdown(t: pd.DataFrame) -> str:
    lines = ["## Reporting conventions: measured effect of the alternative", "",
             "Measured on the paper's figures (" + ", ".join(figures_declared())
             + ", those aggregated) "
             "from the aggregated data, without new runs (pipeline/studies/conventions.py).", "",
             "| convention | ours | alternative | measured effect |", "|---|---|---|---|"]
    lines += ["| " + " | ".join(escape(str(getattr(r, c))) for c in COLUMNS) + " |"
              for r in t.itertuples()]
    return "\n".join(lines) + "\n"
