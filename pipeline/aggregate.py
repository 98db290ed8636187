"""Stage 2, aggregate: the cache into one tidy table per figure, its statistics and summary.

    python -m pipeline.aggregate            # every figure in the cache

For every figure (the trials its plan records list, pipeline.cache.figure_trials) it writes,
under paths.aggregate/<figure>/:
    trials.parquet    every trial's learning curve (pipeline.io.CURVE, concatenated)
    curves.parquet    per condition and epoch: mean, std (over trials, ddof 1), 25 % and 75 %
                      quantiles of abs_error and rel_error, and n_trials
    summary.parquet   per condition: final errors, peak error during growth, failures, diverged
    models.json       per condition and trial: the final model M and its snapshots
Only the trials of the plan are read, so stale cache entries never mix in. A trial that diverged
or failed is counted as such and left out of every mean; a damaged or missing file is named.
"""
from __future__ import annotations

import logging
import sys
from pathlib import Path

import hydra
import numpy as np
import pandas as pd
import pyarrow as pa
from omegaconf import DictConfig

from . import cache, cli, io

log = logging.getLogger("pipeline.aggregate")

GROUP = [c for c in io.LABEL_COLUMNS if c != "trial"]
ERRORS = ("abs_error", "rel_error", "heldout_abs_error")


def condition_order(t: dict) -> tuple:
    """Variants in their order, then growing bodies by period, then references by size."""
    l, g = t["labels"], t["spec"]["growth"]
    return (t.get("_variant_index", 0), l["growth"] == "none", l["growth_period"], g["end_size"])


def load_trials(cache_dir, figure: str) -> tuple[pd.DataFrame, dict, dict, list[str]]:
    """(curves of the figure's finished trials, conditions, paper, problems found)."""
    trials, paper, problems = cache.figure_trials(cache_dir, figure)
    variant_order = {}
    for t in trials:
        label = (t.get("variant") or {}).get("label")
        t["_variant_index"] = variant_order.setdefault(label, len(variant_order))
    frames, conds = [], {}
    for t in sorted(trials, key=lambda t: (condition_order(t), t["labels"]["trial"])):
        l = t["labels"]
        c = conds.setdefault(l["condition"], dict(labels={k: l[k] for k in GROUP},
                                                  spec=t["spec"], variant=t.get("variant"),
                                                  trials={}, diverged={}, missing=[]))
        side, damaged = cache.check(cache_dir, t)
        i = str(l["trial"])
        if side is None:
            why = damaged or "not computed (run pipeline.simulate)"
            c["missing"].append(i)
            problems.append(f"{l['condition']} trial {i}: {why}")
        elif side["status"] == "diverged":
            c["diverged"][i] = side["epoch"]
        else:
            frames.append(cache.read_curve(cache_dir, t))
            c["trials"][i] = {"key": t["key"], "M": side["M"], "snapshots": side["snapshots"],
                              "largest_jump": side["largest_jump"]}
    empty = io.CURVE.empty_table().to_pandas()
    df = pd.concat(frames, ignore_index=True) if frames else empty
    return df, conds, paper, problems


def curve_stats(trials: pd.DataFrame) -> pd.DataFrame:
    """Mean, std and quartiles over trials per condition and epoch (condition order kept)."""
    g = trials.groupby(GROUP + ["epoch"], sort=False)
    out = g[["samples", "size"]].mean()
    out["samples"] = out["samples"].astype("int64")
    for col in ERRORS:
        out[f"{col}_mean"] = g[col].mean()
        out[f"{col}_std"] = g[col].std(ddof=1)
        out[f"{col}_q25"] = g[col].quantile(0.25)
        out[f"{col}_q75"] = g[col].quantile(0.75)
    out["n_trials"] = g["trial"].count().astype("int64")
    return out.reset_index()


def rise(values: np.ndarray) -> tuple[int, float]:
    """(index, rise) of the point rising most above the lowest value before it (0, 0 if none):
    the paper's "significant temporary increase" of the error during growth (sec. 3.1)."""
    r = values - np.minimum.accumulate(values)
    i = int(np.argmax(r))
    return i, float(r[i])


def growth_peak(curve: pd.DataFrame) -> tuple[int, float, float]:
    """(epoch, value, rise) of the temporary increase of the mean absolute error during growth."""
    c = curve.sort_values("epoch")
    err = c["abs_error_mean"].to_numpy()
    i, r = rise(err)
    return int(c["epoch"].iloc[i]), float(err[i]), r


def finals(trials: pd.DataFrame) -> pd.DataFrame:
    """Each trial's final row: the rows of every condition at that condition's last epoch."""
    last = trials.groupby("condition", sort=False)["epoch"].transform("max")
    return trials[trials["epoch"] == last]


def summarize(trials: pd.DataFrame, curves: pd.DataFrame, conds: dict, paper: dict,
              fail_factor: float) -> pd.DataFrame:
    """One row per condition: final errors (mean, std over trials), the temporary increase of the
    mean absolute error during growth (epochs 1 ... T_G + 1; growth_peak), trials that diverged
    or are missing, trials that failed to bootstrap, and the paper's stated final accuracy."""
    paper_abs = paper.get("final_abs_error")
    rows, last = [], finals(trials)
    for name, c in conds.items():
        final = last[last["condition"] == name]
        v = c["variant"] or {}
        row = {k: c["labels"][k] for k in GROUP}
        row.update(variant=v.get("label", ""), choice=v.get("choice", ""),
                   chosen=bool(v.get("chosen", False)),
                   start_size=c["spec"]["growth"]["start_size"],
                   end_size=c["spec"]["growth"]["end_size"], epochs=c["spec"]["epochs"],
                   n_trials=int(len(final)), n_diverged=len(c["diverged"]),
                   n_run_failures=len(c["missing"]),
                   diverged_epochs=",".join(str(e) for e in c["diverged"].values()))
        for col in ERRORS:
            row[f"final_{col}_mean"] = float(final[col].mean()) if len(final) else np.nan
            row[f"final_{col}_std"] = float(final[col].std(ddof=1)) if len(final) > 1 else np.nan
        cu = curves[(curves["condition"] == name)
                    & (curves["epoch"] <= c["labels"]["growth_period"] + 1)]
        peak = growth_peak(cu) if c["labels"]["growth"] != "none" and len(cu) else None
        row["peak_abs_error_growth"] = peak[1] if peak else np.nan
        row["rise_abs_error_growth"] = peak[2] if peak else np.nan
        row["peak_epoch_growth"] = peak[0] if peak else -1
        median = final["rel_error"].median() if len(final) else np.nan
        row["n_bootstrap_failures"] = int((final["rel_error"] > fail_factor * median).sum())
        jumps = [t["largest_jump"] for t in c["trials"].values()]
        row["largest_jump_mean"] = float(np.mean(jumps)) if jumps else np.nan
        row["final_samples"] = int(final["samples"].max()) if len(final) else 0
        row["paper_final_abs_error"] = np.nan if paper_abs is None else float(paper_abs)
        rows.append(row)
    return pd.DataFrame(rows)


def aggregate(cfg: DictConfig) -> list[str]:
    """Aggregate every figure in the cache; return the problems found."""
    out_root, problems = Path(cfg.paths.aggregate), []
    figures = cache.figures(cfg.paths.cache)
    if not figures:
        raise FileNotFoundError(f"no simulated figure under {cfg.paths.cache}: "
                                "run pipeline.simulate first")
    for fig in figures:
        trials, conds, paper, found = load_trials(cfg.paths.cache, fig)
        problems += [f"[{fig}] {p}" for p in found]
        curves = curve_stats(trials)
        summary = summarize(trials, curves, conds, paper, cfg.aggregate.fail_factor)
        folder = out_root / fig
        io.write_table(folder / "trials.parquet",
                       pa.Table.from_pandas(trials, schema=io.CURVE, preserve_index=False))
        io.write_table(folder / "curves.parquet", io.frame_to_table(curves))
        io.write_table(folder / "summary.parquet", io.frame_to_table(summary))
        io.write_json(folder / "models.json", {
            "figure": fig, "paper": paper,
            "conditions": {k: {"spec": c["spec"], "trials": c["trials"]}
                           for k, c in conds.items()}})
        log.info("[%s] %d conditions, %d trial curves -> %s", fig, len(summary),
                 trials.groupby(["condition", "trial"]).ngroups if len(trials) else 0, folder)
    return problems


def run(cfg: DictConfig) -> int:
    """aggregate() for the command line: a warning per problem, exit status 1 if any."""
    problems = aggregate(cfg)
    for p in problems:
        print(f"warning: {p}", file=sys.stderr)
    return 1 if problems else 0


@hydra.main(config_path="../conf", config_name="config", version_base="1.3")
def main(cfg: DictConfig) -> None:
    cli.finish(run, cfg)


if __name__ == "__main__":
    cli.main(main)
