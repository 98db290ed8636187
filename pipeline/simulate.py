"""Stage 1, simulate: run every trial of the config that is not cached yet.

    python -m pipeline.simulate experiment=fig4                 # one paper figure
    python -m pipeline.simulate -m growth.period=10,100 trials.count=2   # a Hydra sweep

Trials run longest first on the executor (pipeline.execute), and each finished trial is written
to the cache at once, so an interrupted run loses only the trials in flight. A trial another run
is computing (its claim is held) is left to that run and waited for. A failing or diverging
trial is recorded with its error, the others go on, and the stage exits non-zero with a summary.
"""
from __future__ import annotations

import logging
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

import hydra
from omegaconf import DictConfig, OmegaConf

from . import cache, cli, execute, io
from .plan import cost, plan
from .progress import Progress, fmt_duration  # noqa: F401 - fmt_duration: was here

log = logging.getLogger("pipeline.simulate")
WAIT_POLL_S = 2.0


@dataclass
class Summary:
    figure: str
    total: int
    cached: int
    ran: int = 0
    failed: dict = field(default_factory=dict)  # key -> error (failed or diverged)
    labels: dict = field(default_factory=dict)  # key -> "condition trial i", for messages

    def lines(self) -> list[str]:
        head = (f"[{self.figure}] {self.total} trials: {self.cached} cached, {self.ran} run, "
                f"{len(self.failed)} failed or diverged")
        return [head] + [f"  FAILED {self.labels[k]}: {e}" for k, e in self.failed.items()]


def record(cache_dir, trial: dict, result: dict, summary: Summary) -> None:
    """Write a finished trial (ok or diverged) to the cache, or its failure beside it."""
    key, failure = trial["key"], cache.trial_paths(cache_dir, trial)[1].parent / "failed"
    if result["status"] in ("ok", "diverged"):
        cache.write_trial(cache_dir, trial, result)
        (failure / f"{key}.json").unlink(missing_ok=True)
    if result["status"] != "ok":
        summary.failed[key] = result["error"]
        where = summary.labels[key]
        log.error("[%s] %s %s: %s", summary.figure, where, result["status"],
                  result.get("traceback", result["error"]))
    if result["status"] == "failed":
        io.write_json(failure / f"{key}.json", dict(key=key, labels=trial["labels"],
                                                    error=result["error"]))
    summary.ran += 1


def simulate(cfg: DictConfig) -> Summary:
    """Run the config's trials that are not cached; return what was done."""
    trials = plan(cfg)  # raises ConfigError before anything is written
    cache_dir = Path(cfg.paths.cache)
    figure = cfg.figure
    (cache_dir / figure).mkdir(parents=True, exist_ok=True)
    io.remove_stale_tmp(cache_dir / figure)
    todo, diverged = [], {}
    for t in trials:
        done, damaged = cache.check(cache_dir, t)
        if damaged:
            print(f"[{figure}] recomputing {t['labels']['condition']} trial "
                  f"{t['labels']['trial']}: {damaged}", file=sys.stderr)
        if done is None:
            todo.append(t)
        elif done["status"] == "diverged":
            diverged[t["key"]] = f"{done['error']} (cached)"
    todo.sort(key=cost, reverse=True)
    summary = Summary(figure=figure, total=len(trials), cached=len(trials) - len(todo),
                      failed=diverged)
    summary.labels = {t["key"]: f"{t['labels']['condition']} trial {t['labels']['trial']}"
                      for t in trials}
    claims = {t["key"]: cache.Claim(cache_dir, t) for t in todo}
    mine = [t for t in todo if claims[t["key"]].acquire()]
    elsewhere = [t for t in todo if claims[t["key"]].fh is None]
    finished = [t for t in mine if cache.check(cache_dir, t)[0] is not None]  # by another run
    for t in finished:  # between our look at the cache and our claim
        claims[t["key"]].release()
        mine.remove(t)
        summary.cached += 1
    log.info("[%s] %d trials: %d cached, %d to run on %d worker(s)%s", figure, len(trials),
             summary.cached, len(mine), min(cfg.workers, max(len(mine), 1)),
             f", {len(elsewhere)} being computed by another run" if elsewhere else "")
    progress = Progress(summary, todo)  # a heartbeat line when nothing finishes for a while
    try:
        if mine:
            execute.warm_up(mine)
        for trial, result in execute.results(
                mine, cfg.workers, cfg.executor.backend, cfg.executor.address,
                options=OmegaConf.to_container(cfg.executor.slurm),
                logs=Path(cfg.paths.out) / "logs" / "submitit"):
            record(cache_dir, trial, result, summary)
            claims[trial["key"]].release()
            progress.update(trial, result)
        while elsewhere:  # trials another run claimed: wait for them, or take over if it died
            trial = elsewhere.pop(0)
            claim = claims[trial["key"]]
            if cache.check(cache_dir, trial)[0] is not None:
                summary.cached += 1
            elif claim.acquire() and cache.check(cache_dir, trial)[0] is not None:
                claim.release()
                summary.cached += 1
            elif claim.fh is not None:
                result = execute.run_one(trial)
                record(cache_dir, trial, result, summary)
                claim.release()
                progress.update(trial, result)
            else:
                elsewhere.append(trial)
                time.sleep(WAIT_POLL_S)
    finally:
        progress.close()
        for c in claims.values():
            c.release()
    whole = bool(cfg.conditions.periods or cfg.conditions.references or cfg.conditions.variants)
    cache.write_plan(cache_dir, figure, trials, whole, OmegaConf.to_container(cfg.paper))
    return summary


def run(cfg: DictConfig) -> int:
    """simulate() for the command line: the summary, and exit status 1 if a trial failed."""
    summary = simulate(cfg)
    print("\n".join(summary.lines()), file=sys.stderr)
    return 1 if summary.failed else 0


@hydra.main(config_path="../conf", config_name="config", version_base="1.3")
def main(cfg: DictConfig) -> None:
    cli.finish(run, cfg)


if __name__ == "__main__":
    cli.main(main)
