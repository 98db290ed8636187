"""Stage 2, aggregate: the cache into one tidy table per figure, its statistics and summary.

    python -m pipeline.aggregate            # every figure with a manifest in the cache

For every figure (a manifest under paths.cache) it writes, under paths.aggregate/<figure>/:
    trials.parquet    every trial's learning curve (the cache's columns, concatenated)
    curves.parquet    per condition and epoch: mean, std (over trials, ddof 1), 25 % and 75 %
                      quantiles of abs_error and rel_error, and n_trials
    summary.parquet   per condition: final errors, peak error during growth, failures
    models.json       per condition and trial: the final inverse estimate M and its snapshots
Only the trials the manifest lists are read, so stale cache entries never mix in.
"""
from __future__ import annotations

import logging
import sys
from pathlib import Path

import hydra
import numpy as np
import pandas as pd
import pyarrow.parquet as pq
from omegaconf import DictConfig

from . import cli, cache
from .cache import LABEL_COLUMNS

log = logging.getLogger("pipeline.aggregate")

GROUP = [c for c in LABEL_COLUMNS if c != "trial"]
ERRORS = ("abs_error", "rel_error")


def condition_order(labels: dict, spec: dict) -> tuple:
    """Growing bodies by period, then constant references by size."""
    return (labels["growth"] == "none", labels["growth_period"], spec["end_size"])


def load_trials(cache_dir, manifest: dict) -> tuple[pd.DataFrame, dict, list[str]]:
    """The figure's curves (one frame), models per condition, and problems found."""
    frames, models, problems = [], {}, []
    conds = sorted(manifest["conditions"].items(),
                   key=lambda kv: condition_order(kv[1]["labels"], kv[1]["spec"]))
    for name, cond in conds:
        models[name] = {"spec": cond["spec"], "trials": {}}
        for i, entry in sorted(cond["trials"].items(), key=lambda kv: int(kv[0])):
            if entry["status"] != "ok":
                continue
            folder = Path(cache_dir) / manifest["figure"]
            curve, side = folder / f"{entry['key']}.parquet", folder / f"{entry['key']}.json"
            if not (curve.exists() and side.exists()):
                problems.append(f"{name} trial {i}: cache file {curve.name} is missing")
                continue
            frames.append(pq.read_table(curve).to_pandas())
            s = cache.read_sidecar(side)
            models[name]["trials"][i] = {"M": s["M"], "snapshots": s["snapshots"]}
    df = pd.concat(frames, ignore_index=True) if frames else pd.DataFrame(columns=cache.CURVE_COLUMNS)
    return df, models, problems


def curve_stats(trials: pd.DataFrame) -> pd.DataFrame:
    """Mean, std and quartiles over trials per condition and epoch (condition order kept)."""
    g = trials.groupby(GROUP + ["epoch"], sort=False)
    out = g["size"].mean().to_frame()
    for col in ERRORS:
        out[f"{col}_mean"] = g[col].mean()
        out[f"{col}_std"] = g[col].std(ddof=1)
        out[f"{col}_q25"] = g[col].quantile(0.25)
        out[f"{col}_q75"] = g[col].quantile(0.75)
    out["n_trials"] = g["trial"].count().astype("int64")
    return out.reset_index()


def growth_peak(curve: pd.DataFrame) -> tuple[int, float, float]:
    """(epoch, value, rise) of the temporary increase of the mean absolute error during growth:
    the point that rises most above the lowest error reached before it (paper sec. 3.1, "a
    significant temporary increase"). With no increase: the first epoch, rise 0."""
    err = curve.sort_values("epoch")["abs_error_mean"].to_numpy()
    rise = err - np.minimum.accumulate(err)
    i = int(np.argmax(rise))
    return int(curve.sort_values("epoch")["epoch"].iloc[i]), float(err[i]), float(rise[i])


def summarize(trials: pd.DataFrame, curves: pd.DataFrame, manifest: dict,
              fail_factor: float) -> pd.DataFrame:
    """One row per condition: final errors (mean, std over trials), the temporary increase of the
    mean absolute error during growth (epochs 1 ... T_G + 1; growth_peak), trials that failed to
    run, trials that failed to bootstrap, and the paper's stated final accuracy."""
    paper = manifest.get("paper", {}).get("final_abs_error")
    rows = []
    for name, cond in sorted(manifest["conditions"].items(),
                             key=lambda kv: condition_order(kv[1]["labels"], kv[1]["spec"])):
        tr = trials[trials["condition"] == name]
        final = tr[tr["epoch"] == tr["epoch"].max()] if len(tr) else tr
        row = {k: cond["labels"][k] for k in GROUP}
        row.update(start_size=cond["spec"]["start_size"],
                   end_size=cond["spec"]["end_size"], epochs=cond["spec"]["epochs"],
                   n_trials=int(len(final)),
                   n_run_failures=sum(e["status"] != "ok" for e in cond["trials"].values()))
        for col in ERRORS:
            row[f"final_{col}_mean"] = float(final[col].mean()) if len(final) else np.nan
            row[f"final_{col}_std"] = float(final[col].std(ddof=1)) if len(final) > 1 else np.nan
        cu = curves[(curves["condition"] == name)
                    & (curves["epoch"] <= cond["labels"]["growth_period"] + 1)]
        peak = growth_peak(cu) if cond["labels"]["growth"] != "none" and len(cu) else None
        row["peak_abs_error_growth"] = peak[1] if peak else np.nan
        row["rise_abs_error_growth"] = peak[2] if peak else np.nan
        row["peak_epoch_growth"] = peak[0] if peak else -1
        median = final["rel_error"].median() if len(final) else np.nan
        row["n_bootstrap_failures"] = int((final["rel_error"] > fail_factor * median).sum())
        row["paper_final_abs_error"] = np.nan if paper is None else float(paper)
        rows.append(row)
    return pd.DataFrame(rows)


def aggregate(cfg: DictConfig) -> list[str]:
    """Aggregate every figure in the cache; return the problems found (missing files)."""
    out_root, problems = Path(cfg.paths.aggregate), []
    manifests = cache.read_manifests(cfg.paths.cache)
    if not manifests:
        raise FileNotFoundError(f"no manifest under {cfg.paths.cache}: run pipeline.simulate first")
    for man in manifests:
        fig = man["figure"]
        trials, models, missing = load_trials(cfg.paths.cache, man)
        problems += [f"[{fig}] {p}" for p in missing]
        curves = curve_stats(trials)
        summary = summarize(trials, curves, man, cfg.aggregate.fail_factor)
        folder = out_root / fig
        cache.write_table(folder / "trials.parquet", cache.frame_to_table(trials))
        cache.write_table(folder / "curves.parquet", cache.frame_to_table(curves))
        cache.write_table(folder / "summary.parquet", cache.frame_to_table(summary))
        cache.write_text(folder / "models.json", cache.dump_json(
            {"figure": fig, "paper": man.get("paper", {}), "conditions": models}))
        log.info("[%s] %d conditions, %d trial curves -> %s", fig, len(summary),
                 trials.groupby(["condition", "trial"]).ngroups if len(trials) else 0, folder)
    return problems


def run(cfg: DictConfig) -> int:
    """aggregate() for the command line: warnings for missing cache files, exit status."""
    problems = aggregate(cfg)
    for p in problems:
        print(f"warning: {p}", file=sys.stderr)
    return 0


@hydra.main(config_path="../conf", config_name="config", version_base="1.3")
def main(cfg: DictConfig) -> None:
    cli.finish(run, cfg)


if __name__ == "__main__":
    cli.main(main)
