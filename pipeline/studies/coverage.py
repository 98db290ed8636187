"""The measured coverage of the scorecard's intervals, per measure type and trial count.

    python -m pipeline.studies.coverage AGGREGATE_FOLDER FIGURE [FIGURE ...] [--trials 3 5 10]
        [--draws 400] [--out pipeline/studies/coverage.csv]

For each figure (aggregated with at least 20 trials per condition, say fig4 and fig7_20trials),
every claim's measure is computed on all its trials: the value to cover. Then, `draws` times per
trial count n, each condition's trials are subsampled to n (without replacement, each condition
on its own), the same measures and their 95 % intervals (scorecard.interval) are recomputed, and
each interval is scored on whether it covers the all-trials value. The table holds, per measure
type (claims.Test.kind) and n, the fraction covered on the figure where it is lowest; the
scorecard says "not reproduced" only where it is at least scorecard.MIN_COVERAGE.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
import pandas as pd

from . import scorecard
from .claims import tests

SEED = 27  # the draws: fixed, so the same aggregates give the same table


def _subset(trials: pd.DataFrame, summary: pd.DataFrame, n: int, rng) -> pd.DataFrame:
    keep = []
    for c in summary["condition"]:
        have = np.sort(trials.loc[trials["condition"] == c, "trial"].unique())
        keep += [(c, int(t)) for t in rng.choice(have, n, replace=False)]
    idx = pd.MultiIndex.from_frame(trials[["condition", "trial"]])
    return trials[idx.isin(keep)]


def coverage(aggs: dict, counts=(3, 5, 10), draws: int = 400,
             seed: int = SEED) -> tuple[pd.DataFrame, pd.DataFrame]:
    """(per kind and n: draws, covered fraction; per measure: the same), over the figures of
    `aggs` (figure -> aggregate with trials and summary)."""
    rng = np.random.default_rng(seed)
    rows = []
    for name, agg in aggs.items():
        full = {(t.claim, t.where): t for t in tests(name, agg["trials"], agg["summary"])
                if not t.exact}
        truth = {k: float(np.mean(t.values)) for k, t in full.items()}
        for n in counts:
            for _ in range(draws):
                sub = _subset(agg["trials"], agg["summary"], n, rng)
                for t in tests(name, sub, agg["summary"]):
                    if t.exact or (t.claim, t.where) not in truth:
                        continue
                    _, low, high = scorecard.interval(t.values)
                    rows.append(dict(figure=name, claim=t.claim, where=t.where, kind=t.kind,
                                     trials=n, covered=bool(low <= truth[(t.claim, t.where)]
                                                        <= high)))
    df = pd.DataFrame(rows)
    per_measure = (df.groupby(["figure", "claim", "where", "kind", "trials"], sort=False)
                   ["covered"].mean().rename("coverage").reset_index())
    per_figure = (df.groupby(["figure", "kind", "trials"])["covered"].agg(["size", "mean"])
                  .rename(columns={"size": "draws", "mean": "coverage"}).reset_index())
    per_kind = (per_figure.groupby(["kind", "trials"])  # the worst figure's: a body may differ
                .agg(draws=("draws", "sum"), coverage=("coverage", "min")).reset_index())
    return per_kind, per_measure


BEGIN, END = "<!-- coverage table: pipeline.studies.coverage -->", "<!-- end of coverage table -->"


def markdown(per_kind: pd.DataFrame) -> str:
    """The coverage table as docs/scorecard.md shows it (between BEGIN and END)."""
    counts = sorted(per_kind["trials"].unique())
    lines = ["| measure type | " + " | ".join(f"{n} of 20 trials" for n in counts) + " |",
             "|---|" + "---|" * len(counts)]
    for kind, g in per_kind.groupby("kind", sort=True):
        by = dict(zip(g["trials"], g["coverage"]))
        lines.append(f"| {kind} | " + " | ".join(
            f"{100 * by[n]:.1f} %" if n in by else "" for n in counts) + " |")
    return "\n".join([BEGIN, *lines, END])


def main(argv=None) -> int:
    p = argparse.ArgumentParser(prog="python -m pipeline.studies.coverage",
                                description=__doc__.split("\n\n")[0])
    p.add_argument("aggregate", type=Path, help="the aggregate folder (paths.aggregate)")
    p.add_argument("figures", nargs="+", help="figures with >= 20 trials per condition")
    p.add_argument("--trials", type=int, nargs="+", default=[3, 5, 10])
    p.add_argument("--draws", type=int, default=400)
    p.add_argument("--out", type=Path, default=scorecard.COVERAGE)
    a = p.parse_args(argv)
    from .. import io
    from ..report import aggregated, load_aggregates

    missing = [f for f in a.figures if f not in aggregated(a.aggregate)]
    if missing:
        print(f"error: {missing[0]}: not aggregated under {a.aggregate}", file=sys.stderr)
        return 2
    aggs = load_aggregates(a.aggregate, a.figures)
    for name, agg in aggs.items():
        least = int(agg["trials"].groupby("condition")["trial"].nunique().min())
        if least <= max(a.trials):
            print(f"error: {name} has {least} trials in a condition; --trials must stay below "
                  "that", file=sys.stderr)
            return 2
    per_kind, per_measure = coverage(aggs, a.trials, a.draws)
    io.write_text(a.out, per_kind.to_csv(index=False, float_format="%.4f"))
    print(markdown(per_kind))
    print(per_measure.to_string(index=False))
    return 0


if __name__ == "__main__":
    sys.exit(main())
