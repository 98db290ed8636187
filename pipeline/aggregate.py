"""Stage 2, aggregate: the cache into one set of files per figure, under paths.aggregate/<figure>/
(trials, curves and summary Parquet, models.json, manifest.json, index.parquet: docs/running.md).

    python -m pipeline.aggregate              # every figure in the cache
    python -m pipeline.aggregate figure=fig4  # one figure (or experiment=fig4)

A figure's set is rebuilt when its inputs changed, from the trials whose files changed
(aggregate_set.py) and the conditions whose trials changed (aggregate_stats.py); a trial that
diverged or failed is counted and left out of every mean; a damaged or missing file is named.
"""
from __future__ import annotations

import gc
import logging
import os
import sys
from pathlib import Path

if __name__ == "__main__":  # the command: no cyclic collection from here on (run)
    gc.disable()

import hydra
import numpy as np
import pyarrow as pa
from omegaconf import DictConfig

from . import cache, cli, io
from .aggregate_set import (INDEX, Previous, _checksum, _compact, _read, code_of_stage,
                            curves_table, index_table, load_trials, models, models_text,
                            refresh_index)
from .aggregate_stats import statistics, trials_file_table
from .config import CONFIG_PATH

log = logging.getLogger("pipeline.aggregate")
SHOWN_CONDITIONS = 8  # a figure of more conditions (make smoke's) is not listed unless named


def inputs_digest(figure: str, conds: dict, fail_factor: float, paper=None) -> str:
    """What one figure's aggregate is made of (the code of this stage included)."""
    body = dict(figure=figure, fail_factor=fail_factor, code=code_of_stage(), paper=paper,
                conditions=[[k, c["id"], c["variant"], sorted(c["trials"]), c["missing"],
                             c["seals"]] for k, c in conds.items()])
    return _checksum(_compact(body))


def aggregate_figure(cfg: DictConfig, fig: str) -> tuple[list[str], bool]:
    """(problems, whether rebuilt): the figure's set replaced as one unless made of the same
    inputs; a damaged plan record, or no trial where it had some, leaves it as it was."""
    folder = Path(cfg.paths.aggregate) / io.safe_name("figure", fig)
    previous = Previous(folder)
    try:
        conds, paper, problems = load_trials(cfg.paths.cache, fig, previous)
    except io.DamagedFile as err:
        return [f"{err}; the figure's aggregate is left as it was"], False
    digest = inputs_digest(fig, conds, cfg.aggregate.fail_factor, paper)
    try:
        old = io.read_json(folder / "manifest.json")
    except (OSError, ValueError):
        old = {}
    if old.get("inputs") == digest and previous.where is not None:
        refresh_index(conds, previous)
        return problems, False
    if not any(c["trials"] for c in conds.values()) and old.get("trials"):
        return problems + ["no trial of the figure is readable; its aggregate is left as it "
                           "was"], False
    try:
        table, (model_of, sums) = curves_table(conds, previous), models(conds, previous)
    except (OSError, ValueError, KeyError, IndexError):  # the previous aggregate is damaged
        previous = Previous()  # the entries that were to come from it are read from the cache
        for e in (e for c in conds.values() for e in c["entries"] if "table" not in e):
            fresh = _read(cfg.paths.cache, e, e["signature"])
            if not isinstance(fresh, dict):
                raise io.DamagedFile(f"trial {e['key']}: {fresh or 'gone'} while aggregating; "
                                     "run the stage again")
            e.update(fresh)
        table, (model_of, sums) = curves_table(conds, previous), models(conds, previous)
    curves, summary, stats = statistics(table, conds, paper, cfg.aggregate.fail_factor,
                                        previous)
    for c, n in zip(*summary.select(["condition", "n_trials"]).to_pydict().values()):
        if n == 0:
            print(f"note: [{fig}] {c}: every trial diverged or failed; the report marks it "
                  "diverged", file=sys.stderr)
    with io.new_set(folder) as tmp:
        sha256 = {name: io.write_table(tmp / name, t)
                  for name, t in (("trials.parquet", trials_file_table(table)),
                                  ("curves.parquet", curves), ("summary.parquet", summary))}
        io.write_text(tmp / "models.json", models_text(fig, paper, model_of))
        io.write_table(tmp / INDEX, index_table(conds))
        io.write_json(tmp / "manifest.json", dict(
            figure=fig, inputs=digest, code=code_of_stage(), trials=table.num_rows,
            models={k: [conds[k]["id"], sums[k]] for k in model_of}, stats=stats,
            sha256=sha256))
    log.info("[%s] %d conditions, %d trial curves -> %s", fig, summary.num_rows,
             sum(len(c["trials"]) for c in conds.values()), folder)
    return problems, True


def named_figures(cfg: DictConfig, explicit: bool, known: list[str], folder,
                  state: str) -> list[str] | None:
    """The figures experiments= (or `explicit`: figure=) names, or None; one not `known` (`state`
    under `folder`) is a FileNotFoundError."""
    if not cfg.get("experiments") and not explicit:
        return None
    wanted = list(cfg.experiments) if cfg.get("experiments") else [cfg.figure]
    missing = [f for f in wanted if f not in known]  # an experiment's figure is its name
    if missing:
        raise FileNotFoundError(f"figure={missing[0]}: not {state} under {folder} "
                                f"({state}: {', '.join(known) or 'none'})")
    return wanted


def aggregate(cfg: DictConfig, explicit: bool = False) -> list[str]:
    """The problems found aggregating every simulated figure, or those named, that changed."""
    known = cache.figures(cfg.paths.cache)
    if not known:
        raise FileNotFoundError(f"no simulated figure under {cfg.paths.cache}: "
                                "run pipeline.simulate first")
    figures = named_figures(cfg, explicit, known, cfg.paths.cache, "simulated") or known
    problems, rebuilt = [], 0
    for fig in figures:
        found, new = aggregate_figure(cfg, fig)
        problems += [f"[{fig}] {p}" for p in found]
        rebuilt += new
        if not gc.isenabled():  # the command (run): each figure's cycles freed before the next
            gc.collect()
        show_heldout(Path(cfg.paths.aggregate) / io.safe_name("figure", fig), fig,
                     explicit or len(figures) == 1)
    log.info("aggregate: %d of %d figure(s) rebuilt, the others unchanged", rebuilt, len(figures))
    return problems


def show_heldout(folder: Path, fig: str, named: bool) -> None:
    """Log per condition the held-out error (mm, % of the reach), the grid error and the trials
    of a figure named (or the only one) or of few conditions: what a first run wants to read."""
    try:  # a pyarrow table: a figure left as it was loads no pandas
        summary = io.read_table(io.set_of(folder) / "summary.parquet")
    except (OSError, ValueError):
        return  # nothing aggregated (a problem already named)
    if "final_heldout_abs_error_pct_reach" not in summary.column_names or not (
            named or summary.num_rows <= SHOWN_CONDITIONS):
        return
    for r in summary.to_pylist():
        r = {k: np.nan if v is None else v for k, v in r.items()}
        log.info("[%s] %s: %s", fig, r["condition"], "no finished trial" if not np.isfinite(
            r["final_heldout_abs_error_mean"]) else
            f"held out {1e3 * r['final_heldout_abs_error_mean']:.1f} mm"
            f" = {r['final_heldout_abs_error_pct_reach']:.2f} % of the reach "
            f"({r['reach']:.3f} m); grid {1e3 * r['final_abs_error_mean']:.1f} mm; "
            f"{r['n_trials']} trial(s) of {r['epochs']:,} epochs")


def names_a_figure(overrides: list[str]) -> bool:
    return any(o.lstrip("+").startswith(("figure=", "experiment=")) for o in overrides)


def run(cfg: DictConfig) -> int:
    """aggregate() for the command line: a warning per problem, exit status 1 if any. Its one
    process takes Arrow's buffers from the C library and freezes what the imports made out of
    the cyclic collector, which runs once per figure (docs/scale.md: The command's process)."""
    if "ARROW_DEFAULT_MEMORY_POOL" not in os.environ:
        pa.set_memory_pool(pa.system_memory_pool())
    gc.freeze()
    problems = aggregate(cfg, names_a_figure(cli.hydra_run()[0]))
    for p in problems:
        print(f"warning: {p}", file=sys.stderr)
    return 1 if problems else 0


@hydra.main(config_path=CONFIG_PATH, config_name="config", version_base="1.3")
def main(cfg: DictConfig) -> None:
    cli.finish(run, cfg)


if __name__ == "__main__":
    cli.main(main)
