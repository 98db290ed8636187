"""Benchmark: microseconds per trial-epoch, fast path against the numpy reference path.

    python -m pipeline.bench [--repeats 5] [--out outputs/bench/bench.json] [--no-parallel]

For arm5 and iCub at the paper's settings (conf/learner: V=20, K=15, L=7, R=0.2 and V=20, K=30,
L=10, R=0.1)
it times whole trials (draws, epochs and the evaluation schedule) on one core, divides by the
number of epochs, and reports the median over repeats for both paths, measured in the same run,
and their ratio. With parallel scaling on, it also times the same batch of arm5 trials on one and
on two worker processes. Results go to stdout and to a JSON file.
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import numpy as np  # noqa: E402

import gbmodel  # noqa: E402

from .config import REPO_ROOT, learner_settings  # noqa: E402

PAPER = {body: learner_settings(body) for body in ("arm5", "icub")}
# epochs per timed trial: long enough to swamp timer noise, short enough for the reference path
EPOCHS = {"fast": {"arm5": 5000, "icub": 1000}, "reference": {"arm5": 100, "icub": 20}}


def time_trial(body: str, fast: bool, epochs: int, seed: int = 0) -> float:
    """Seconds per epoch of one trial (start and end size 1, i.e. no growth)."""
    spec = gbmodel.TrialSpec(**{**PAPER[body], "epochs": epochs, "start_size": 1.0,
                                "end_size": 1.0})
    rng = np.random.default_rng(seed)
    t0 = time.perf_counter()
    gbmodel.run_trial(spec, rng, fast=fast)
    return (time.perf_counter() - t0) / epochs


def _arm5_trial(seed: int) -> float:
    return time_trial("arm5", True, 20_000, seed)  # about 1 s: long against process start-up


def parallel_speedup(trials: int = 8) -> dict:
    """Wall time of `trials` arm5 trials on 1 and on 2 worker processes."""
    walls = {}
    for workers in (1, 2):
        with ProcessPoolExecutor(workers) as pool:
            list(pool.map(_arm5_trial, range(workers)))  # warm up: import and load the kernels
            t0 = time.perf_counter()
            list(pool.map(_arm5_trial, range(trials)))
            walls[workers] = time.perf_counter() - t0
    return {"trials": trials, "wall_s_1_worker": walls[1], "wall_s_2_workers": walls[2],
            "speedup": walls[1] / walls[2]}


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--out", default=str(REPO_ROOT / "outputs" / "bench" / "bench.json"))
    ap.add_argument("--no-parallel", action="store_true", help="skip the 1-vs-2-worker timing")
    args = ap.parse_args(argv)

    result = {"machine": platform.processor() or platform.machine(), "cpus": os.cpu_count(),
              "repeats": args.repeats}
    for body in PAPER:
        time_trial(body, True, 10)  # compile or load the kernels outside the timing
        row = {}
        for path, fast in (("fast", True), ("reference", False)):
            per_epoch = [time_trial(body, fast, EPOCHS[path][body], seed)
                         for seed in range(args.repeats)]
            row[f"{path}_us_per_trial_epoch"] = 1e6 * float(np.median(per_epoch))
            row[f"{path}_us_all"] = [round(1e6 * t, 2) for t in per_epoch]
        row["speedup"] = row["reference_us_per_trial_epoch"] / row["fast_us_per_trial_epoch"]
        result[body] = row
        print(f"{body}: fast {row['fast_us_per_trial_epoch']:8.1f} us/trial-epoch   "
              f"reference {row['reference_us_per_trial_epoch']:9.1f} us/trial-epoch   "
              f"ratio fast/reference {1 / row['speedup']:.4f} ({row['speedup']:.0f}x faster)",
              flush=True)
    if not args.no_parallel:
        result["parallel"] = parallel_speedup()
        p = result["parallel"]
        print(f"parallel: {p['trials']} arm5 trials, 1 worker {p['wall_s_1_worker']:.1f} s, "
              f"2 workers {p['wall_s_2_workers']:.1f} s, speedup {p['speedup']:.2f}x")
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.with_suffix(".tmp")
    tmp.write_text(json.dumps(result, indent=2) + "\n")
    tmp.replace(out)
    print(f"wrote {out}")
    return result


if __name__ == "__main__":
    main()
