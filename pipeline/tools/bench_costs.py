"""Benchmark: CPU time per sample and joint of every learner's path, relative to Goal Babbling's
fast batch path, on arm5 and the iCub: the measurements behind each learner's sample_cost (the
progress ETA's and the shards' weights).

    python -m pipeline.tools.bench_costs

Each case runs one trial without growth, its epochs quadrupled until it takes a second of CPU
time, and divides by the trial's unweighted cost (epochs x samples per epoch x joints).
"""
from __future__ import annotations

import time

import numpy as np

import gbmodel

from ..config import compose
from ..plan import cost, plan

CASES = [("goal_babbling", []), ("goal_babbling", ["learner.fast=false"]),
         ("goal_babbling", ["learner.updates=online"]), ("online_goal_babbling", []),
         ("online_goal_babbling", ["learner.fast=false"]), ("motor_babbling", []),
         ("example_memory", []), ("example_memory", ["learner.window=0"])]


def per_unit(body: str, learner: str, extra: list[str], least_s: float = 1.0) -> float:
    """CPU seconds per unit of unweighted cost."""
    trial = plan(compose([f"body={body}", f"learner={learner}", "growth=none",
                          "trials.count=1", "learner.epochs=10"] + extra))[0]
    gbmodel.run_trial(gbmodel.TrialSpec.from_dict(trial["spec"]), np.random.default_rng(0))
    epochs = 10
    while True:
        spec = {**trial["spec"], "epochs": epochs}
        t0 = time.process_time()
        gbmodel.run_trial(gbmodel.TrialSpec.from_dict(spec), np.random.default_rng(1))
        seconds = time.process_time() - t0
        if seconds > least_s:
            break
        epochs *= 4
    spec = gbmodel.TrialSpec.from_dict(spec)
    module, params = spec.make_learner()
    body_ = spec.make_body()
    return seconds / (epochs * module.samples_per_epoch(params, body_) * body_.m)


def main() -> None:
    for body in ("arm5", "icub"):
        base = None
        for learner, extra in CASES:
            t = per_unit(body, learner, extra)
            base = base or t
            print(f"{body:5s} {learner:21s} {' '.join(extra):24s} {1e9 * t:9.2f} ns per sample "
                  f"and joint, {t / base:8.1f}x Goal Babbling's fast path", flush=True)


if __name__ == "__main__":
    main()
