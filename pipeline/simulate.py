"""Stage 1, simulate: run every trial of the config that is not cached yet.

    python -m pipeline.simulate experiment=fig4                 # one paper figure
    python -m pipeline.simulate -m growth.period=10,100 trials.count=2   # a Hydra sweep

Trials run longest first on `workers` processes (spawned, BLAS/OpenMP/numba threads pinned to 1),
so two workers stay busy to the end. Each finished trial is written to the cache at once, so an
interrupted run loses only the trials in flight. A failing trial is recorded with its error, the
others go on, and the stage exits non-zero with a summary.
"""
from __future__ import annotations

import logging
import multiprocessing
import os
import signal
import sys
import time
import traceback
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path

import hydra
import numpy as np
from omegaconf import DictConfig, OmegaConf

import gbmodel

from . import cli, cache
from .plan import cost, plan

log = logging.getLogger("pipeline.simulate")

THREAD_VARS = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS",
               "NUMBA_NUM_THREADS", "VECLIB_MAXIMUM_THREADS")


def run_one(trial: dict) -> dict:
    """Run one trial (in a worker): plain data in, plain data out, errors returned as text."""
    start = time.perf_counter()
    try:
        spec = dict(trial["spec"], snapshot_epochs=tuple(trial["spec"]["snapshot_epochs"]))
        seed = np.random.SeedSequence(trial["seed"]["entropy"],
                                      spawn_key=tuple(trial["seed"]["spawn_key"]))
        res = gbmodel.run_trial(gbmodel.TrialSpec(**spec), np.random.default_rng(seed),
                                fast=trial["fast"])
        out = dict(ok=True, epoch=res.epoch, size=res.size, abs_error=res.abs_error,
                   rel_error=res.rel_error, M=res.M, snapshots=res.snapshots)
    except Exception as err:  # recorded and reported; the other trials go on
        out = dict(ok=False, error=f"{type(err).__name__}: {err}", traceback=traceback.format_exc())
    out["key"], out["seconds"] = trial["key"], time.perf_counter() - start
    return out


@contextmanager
def _single_threaded_children():
    """Children inherit the environment: one BLAS/OpenMP/numba thread each."""
    old = {k: os.environ.get(k) for k in THREAD_VARS}
    os.environ.update({k: "1" for k in THREAD_VARS})
    try:
        yield
    finally:
        for k, v in old.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v


def _ignore_sigint():
    """Workers leave Ctrl-C to the parent, which stops them all at once."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)


def _results(todo: list[dict], workers: int):
    """Yield (trial, result) as trials finish; in-process when one worker suffices."""
    if workers == 1 or len(todo) <= 1:
        for t in todo:
            yield t, run_one(t)
        return
    by_key = {t["key"]: t for t in todo}
    ctx = multiprocessing.get_context("spawn")
    with _single_threaded_children():
        pool = ctx.Pool(min(workers, len(todo)), initializer=_ignore_sigint)
        try:
            # chunksize 1: tasks are handed out in order (longest first) as workers become free
            for result in pool.imap_unordered(run_one, todo, chunksize=1):
                yield by_key[result["key"]], result
            pool.close()
        finally:
            pool.terminate()  # idle workers after the last result; on Ctrl-C or error: stop now
            pool.join()


def _fmt(seconds: float) -> str:
    seconds = int(round(seconds))
    h, rest = divmod(seconds, 3600)
    return f"{h}h{rest // 60:02d}m{rest % 60:02d}s" if h else f"{rest // 60}m{rest % 60:02d}s"


@dataclass
class Summary:
    figure: str
    total: int
    cached: int
    ran: int = 0
    failed: dict = field(default_factory=dict)  # key -> error
    labels: dict = field(default_factory=dict)  # key -> "condition trial i", for messages

    def lines(self) -> list[str]:
        head = (f"[{self.figure}] {self.total} trials: {self.cached} cached, {self.ran} run, "
                f"{len(self.failed)} failed")
        return [head] + [f"  FAILED {self.labels[k]}: {e}" for k, e in self.failed.items()]


def simulate(cfg: DictConfig) -> Summary:
    """Run the config's trials that are not cached; return what was done."""
    trials = plan(cfg)  # raises ConfigError before anything is written
    cache_dir = Path(cfg.paths.cache)
    figure = cfg.figure
    todo = [t for t in trials if not cache.is_done(cache_dir, t)]
    todo.sort(key=cost, reverse=True)
    summary = Summary(figure=figure, total=len(trials), cached=len(trials) - len(todo))
    summary.labels = {t["key"]: f"{t['labels']['condition']} trial {t['labels']['trial']}"
                      for t in trials}
    log.info("[%s] %d trials: %d cached, %d to run on %d worker(s)", figure, len(trials),
             summary.cached, len(todo), min(cfg.workers, max(len(todo), 1)))
    (cache_dir / figure).mkdir(parents=True, exist_ok=True)
    cache.remove_stale_tmp(cache_dir / figure)

    start, total_cost, done_cost = time.perf_counter(), sum(map(cost, todo)), 0.0
    for trial, result in _results(todo, cfg.workers):
        key = trial["key"]
        if result["ok"]:
            cache.write_trial(cache_dir, trial, result)
        else:
            summary.failed[key] = result["error"]
            log.error("[%s] %s failed:\n%s", figure, summary.labels[key], result["traceback"])
        summary.ran += 1
        done_cost += cost(trial)
        elapsed = time.perf_counter() - start
        eta = elapsed * (total_cost - done_cost) / done_cost if done_cost else 0.0
        print(f"[{figure}] {summary.cached + summary.ran}/{summary.total} trials done"
              f"{f', {len(summary.failed)} failed' if summary.failed else ''}"
              f" | elapsed {_fmt(elapsed)} | ETA {_fmt(eta)}"
              f" | {summary.labels[key]} {'ok' if result['ok'] else 'FAILED'}"
              f" in {result['seconds']:.1f} s", file=sys.stderr, flush=True)

    paper = OmegaConf.to_container(cfg.paper)
    # An experiment lists its conditions and defines the figure; a single-condition run adds to it.
    whole = bool(cfg.conditions.periods or cfg.conditions.references)
    cache.update_manifest(cache_dir, figure, paper, trials, summary.failed, replace=whole)
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
