"""Stage 2, aggregate: the cache into one tidy table per figure, its statistics and summary.

    python -m pipeline.aggregate              # every figure in the cache
    python -m pipeline.aggregate figure=fig4  # one figure (or experiment=fig4)

For every figure (the conditions of its current plan group, pipeline.cache.figure_conditions,
each labelled by what differs between them) whose inputs changed, it writes as one set, under
paths.aggregate/<figure>/:
    trials.parquet    every trial's learning curve (pipeline.io.CURVE, concatenated)
    curves.parquet    per condition and epoch: mean, std (over trials, ddof 1), 25 % and 75 %
                      quantiles of abs_error and rel_error, and n_trials
    summary.parquet   per condition: final errors, peak error during growth, failures, diverged
    models.json       per condition and trial: the final model M and its snapshots
    manifest.json     the digest of the inputs (conditions, trials' seals, code): unchanged
                      inputs leave the figure as it is
Only the trials of the plan are read, so stale cache entries never mix in. A trial that diverged
or failed is counted as such and left out of every mean; a damaged or missing file is named.
"""
from __future__ import annotations

import hashlib
import logging
import sys
from functools import lru_cache
from pathlib import Path

import hydra
import numpy as np
import pandas as pd
import pyarrow as pa
from omegaconf import DictConfig

from . import cache, cli, io
from .plan import condition_labels, source_fingerprint

log = logging.getLogger("pipeline.aggregate")

GROUP = [c for c in io.LABEL_COLUMNS if c != "trial"]
ERRORS = ("abs_error", "rel_error", "heldout_abs_error")


def condition_order(c: dict) -> tuple:
    """Variants in their order, then growing bodies by period, then references by size (a
    stable sort: conditions that tie keep the order they were planned in)."""
    return (c["_variant_index"], c["growth"] == "none", c["growth_period"],
            c["spec"]["growth"]["end_size"])


def figure_conditions(cache_dir, figure: str) -> tuple[list[dict], dict, list[str]]:
    """The figure's conditions in order, each labelled by what differs between them."""
    conds, paper, problems = cache.figure_conditions(cache_dir, figure)
    variant_order = {}
    for c in conds:
        label = (c.get("variant") or {}).get("label")
        c["_variant_index"] = variant_order.setdefault(label, len(variant_order))
    conds = sorted(conds, key=condition_order)
    for c, label in zip(conds, condition_labels(conds)):
        c["label"] = label
    return conds, paper, problems


def load_trials(cache_dir, figure: str, curves: bool = True):
    """(curves of the figure's finished trials, conditions by label, paper, problems found).
    curves=False: the sidecars only (enough for the inputs' digest); the curves are then None."""
    conditions, paper, problems = figure_conditions(cache_dir, figure)
    frames, conds = [], {}
    for cond in conditions:
        name, spec = cond["label"], cond["spec"]
        labels = dict(figure=figure, body=spec["body"]["name"], learner=spec["learner"]["name"],
                      growth=cond["growth"], growth_period=cond["growth_period"], condition=name)
        c = conds[name] = dict(labels=labels, spec=spec, variant=cond.get("variant"), id=cond["id"],
                               trials={}, diverged={}, missing=[], seals=[])
        for t in sorted(cond["trials"], key=lambda t: t["trial"]):
            side, damaged = cache.check(cache_dir, t)
            i = str(t["trial"])
            if side is None:
                why = damaged or "not computed (run pipeline.simulate)"
                c["missing"].append(i)
                problems.append(f"{name} trial {i}: {why}")
                continue
            c["seals"].append(side["seal"])
            if side["status"] == "diverged":
                c["diverged"][i] = side["epoch"]
                continue
            c["trials"][i] = {"key": t["key"], "M": side["M"], "snapshots": side["snapshots"],
                              "largest_jump": side["largest_jump"]}
            if curves:
                curve = cache.read_curve(cache_dir, t)
                for col, value in labels.items():
                    curve[col] = value
                curve["trial"] = t["trial"]
                frames.append(curve[io.CURVE_COLUMNS])
    if not curves:
        return None, conds, paper, problems
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


CODE = ("aggregate.py", "cache.py", "io.py", "plan.py")  # what an aggregate's bytes depend on


@lru_cache(maxsize=1)
def code_of_stage() -> str:
    """The fingerprint of this stage's code: read once per process, not once per figure."""
    here = Path(__file__).parent
    return source_fingerprint((n, (here / n).read_text()) for n in CODE)


def inputs_digest(figure: str, conds: dict, fail_factor: float) -> str:
    """What one figure's aggregate is made of: its conditions (label, settings, trials' seals),
    the failure factor and the code of this stage. The same digest, the same files."""
    body = dict(figure=figure, fail_factor=fail_factor, code=code_of_stage(),
                conditions=[[k, c["id"], c["variant"], sorted(c["trials"]), c["missing"],
                             c["seals"]] for k, c in conds.items()])
    return hashlib.sha256(io.dump_json(body).encode()).hexdigest()[:20]


def aggregate_figure(cfg: DictConfig, fig: str) -> tuple[list[str], bool]:
    """Aggregate one figure, unless its aggregate is already made of the same inputs; (problems,
    whether it was rebuilt). The figure's files are replaced as one set (pipeline.io.new_set); a
    damaged plan record, or no trial at all where the aggregate had some, leaves it as it was."""
    folder = Path(cfg.paths.aggregate) / io.safe_name("figure", fig)
    try:
        _, conds, paper, problems = load_trials(cfg.paths.cache, fig, curves=False)
    except io.DamagedFile as err:
        return [f"{err}; the figure's aggregate is left as it was"], False
    digest = inputs_digest(fig, conds, cfg.aggregate.fail_factor)
    try:
        old = io.read_json(folder / "manifest.json")
    except (OSError, ValueError):
        old = {}
    if old.get("inputs") == digest:
        return problems, False
    if not any(c["trials"] for c in conds.values()) and old.get("trials"):
        return problems + ["no trial of the figure is readable; its aggregate is left as it "
                           "was"], False
    trials, conds, paper, problems = load_trials(cfg.paths.cache, fig)
    curves = curve_stats(trials)
    summary = summarize(trials, curves, conds, paper, cfg.aggregate.fail_factor)
    for c in summary.loc[summary["n_trials"] == 0, "condition"]:
        print(f"note: [{fig}] {c}: every trial diverged or failed; the report marks it "
              "diverged", file=sys.stderr)
    with io.new_set(folder) as tmp:
        io.write_table(tmp / "trials.parquet",
                       pa.Table.from_pandas(trials, schema=io.CURVE, preserve_index=False))
        io.write_table(tmp / "curves.parquet", io.frame_to_table(curves))
        io.write_table(tmp / "summary.parquet", io.frame_to_table(summary))
        io.write_json(tmp / "models.json", {
            "figure": fig, "paper": paper,
            "conditions": {k: {"spec": c["spec"], "id": c["id"], "trials": c["trials"]}
                           for k, c in conds.items()}})
        io.write_json(tmp / "manifest.json", dict(figure=fig, inputs=digest,
                                                  trials=int(len(trials))))
    log.info("[%s] %d conditions, %d trial curves -> %s", fig, len(summary),
             trials.groupby(["condition", "trial"]).ngroups if len(trials) else 0, folder)
    return problems, True


def selected_figures(cfg: DictConfig, explicit: bool) -> list[str]:
    """The figures a stage works on: every simulated one, or (figure= / experiment= /
    experiments= on the command line) those named; an unknown one is a FileNotFoundError."""
    known = cache.figures(cfg.paths.cache)
    if cfg.get("experiments"):
        wanted = list(cfg.experiments)  # an experiment's figure is its name (tested)
    elif explicit:
        wanted = [cfg.figure]
    else:
        wanted = known
    if not known:
        raise FileNotFoundError(f"no simulated figure under {cfg.paths.cache}: "
                                "run pipeline.simulate first")
    missing = [f for f in wanted if f not in known]
    if missing:
        raise FileNotFoundError(f"figure={missing[0]}: not simulated under {cfg.paths.cache} "
                                f"(simulated: {', '.join(known)})")
    return wanted


def aggregate(cfg: DictConfig, explicit: bool = False) -> list[str]:
    """Aggregate the selected figures (selected_figures) whose inputs changed; return the
    problems found."""
    problems, rebuilt, figures = [], 0, selected_figures(cfg, explicit)
    for fig in figures:
        found, new = aggregate_figure(cfg, fig)
        problems += [f"[{fig}] {p}" for p in found]
        rebuilt += new
    log.info("aggregate: %d of %d figure(s) rebuilt, the others unchanged", rebuilt, len(figures))
    return problems


def names_a_figure(overrides: list[str]) -> bool:
    return any(o.lstrip("+").startswith(("figure=", "experiment=")) for o in overrides)


def run(cfg: DictConfig) -> int:
    """aggregate() for the command line: a warning per problem, exit status 1 if any."""
    problems = aggregate(cfg, names_a_figure(cli.hydra_run()[0]))
    for p in problems:
        print(f"warning: {p}", file=sys.stderr)
    return 1 if problems else 0


@hydra.main(config_path="../conf", config_name="config", version_base="1.3")
def main(cfg: DictConfig) -> None:
    cli.finish(run, cfg)


if __name__ == "__main__":
    cli.main(main)
