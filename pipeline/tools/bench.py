"""Benchmark: microseconds per trial-epoch, fast path against the numpy reference path, and online
Goal Babbling's epoch against a batch epoch.

    python -m pipeline.tools.bench [bench.repeats=5] [bench.parallel=false]     (make bench)

For arm5 and the iCub at the paper's settings (the configs `body=arm5` and `body=icub` compose)
it times whole trials (draws, epochs and the evaluation schedule) on one core, divides by the
number of epochs, and reports the median over repeats for both paths, measured in the same run,
and their ratio. Then the same for online Goal Babbling's compiled path (its epoch: K L path
samples and the returns home, its random walk drawn with it) and the ratio of its median to the
batch fast path's median of the same run (the target: at most 2), in wall-clock and in CPU
time, and Goal Babbling with learner.solver=lstsq (its epoch: the Gram sums and the p x p solve
instead of the gradient step) against the gradient epoch, and Goal Babbling with
learner.updates=online (one step per sample) against the batch epoch. The paths' trials are
interleaved (pipeline.tools.bench.paired), so that a shared machine's drifting speed moves them alike;
beside each ratio of the wall-clock medians (`speedup`, `*_over_*`) stands the median over repeats
of the same ratio in CPU time, pair by pair (`*_cpu`, paired_ratio): on a loaded machine a path's
wall clock also counts the time it waited for a core, which hides a regression that CPU time shows.
With bench.parallel, it also times the same batch of arm5 trials on one and on two worker
processes of the pipeline's local engine. Writes paths.bench/bench.json.
"""
from __future__ import annotations

import os
import platform
import time
from pathlib import Path

import hydra
import numpy as np
from omegaconf import DictConfig

import gbmodel

from .. import cli, execute, io
from ..config import CONFIG_PATH, compose
from ..plan import plan

# epochs per timed trial: long enough to swamp timer noise, short enough for the reference path
EPOCHS = {"fast": {"arm5": 5000, "icub": 1000}, "reference": {"arm5": 100, "icub": 20},
          "online": {"arm5": 5000, "icub": 1000}, "lstsq": {"arm5": 5000, "icub": 1000},
          "updates_online": {"arm5": 5000, "icub": 1000}}


def paper_spec(body: str, epochs: int, fast: bool, learner: str = "goal_babbling",
               extra: tuple = ()) -> dict:
    """The TrialSpec (as data) of a full-size trial of `body` at the paper's settings (online
    Goal Babbling: conf/learner/online_goal_babbling.yaml with the body's settings), with
    `extra` overrides."""
    trial = plan(compose([f"body={body}", f"learner={learner}", "growth=none", "trials.count=1",
                          f"learner.epochs={epochs}", f"learner.fast={str(fast).lower()}",
                          *extra]))[0]
    return trial["spec"]


def time_trial(spec: dict, seed: int = 0) -> float:
    """Seconds per epoch of one trial."""
    return time_trial_both(spec, seed)[0]


def time_trial_both(spec: dict, seed: int = 0) -> tuple[float, float]:
    """Seconds per epoch of one trial: wall clock and this process's CPU time (less sensitive to
    a shared machine)."""
    t0, c0 = time.perf_counter(), time.process_time()
    gbmodel.run_trial(gbmodel.TrialSpec.from_dict(spec), np.random.default_rng(seed))
    return ((time.perf_counter() - t0) / spec["epochs"],
            (time.process_time() - c0) / spec["epochs"])


def paired(specs: dict, repeats: int) -> dict:
    """Whole trials of every spec in `specs` (name -> spec), interleaved: repeat r runs them in
    turn, in reversed order every other repeat, all with seed r, so that a machine that speeds up
    or slows down during the run shifts them alike. name -> (wall, cpu) seconds per epoch, one
    per repeat."""
    out = {name: [] for name in specs}
    for r in range(repeats):
        for name in (list(specs) if r % 2 == 0 else list(reversed(specs))):
            out[name].append(time_trial_both(specs[name], r))
    return out


def paired_ratio(times: dict, a: str, b: str, clock: int = 1) -> float:
    """The median over repeats of a's time over b's in the same repeat (`paired` times; clock 0:
    wall, 1: CPU), each pair run back to back under the same load."""
    return float(np.median([ta[clock] / tb[clock] for ta, tb in zip(times[a], times[b])]))


RATIOS = {"speedup": ("reference", "fast"), "online_over_batch": ("online", "fast"),
          "lstsq_over_gradient": ("lstsq", "fast"),
          "updates_online_over_batch": ("updates_online", "fast")}  # speedup: fast is b's


def draw_time(spec: dict, epochs: int = 200) -> float:
    """Seconds per epoch of the learner's random draws alone (median of 3): the share of a
    trial-epoch that no kernel can remove (online Goal Babbling draws m (n + 1) normals per
    sample for its random walk)."""
    trial = gbmodel.TrialSpec.from_dict(spec)
    body, (learner, params) = trial.make_body(), trial.make_learner()
    times = []
    for seed in range(3):
        rng = np.random.default_rng(seed)
        t0 = time.perf_counter()
        learner.draw(params, body, epochs, rng)
        times.append((time.perf_counter() - t0) / epochs)
    return float(np.median(times))


def _arm5_trial(job: dict) -> float:
    return time_trial(job["spec"], job["seed"])


def parallel_speedup(trials: int = 8) -> dict:
    """Wall time of `trials` 100,000-epoch arm5 trials (about 2 s each, long against a worker's
    start-up) on 1 and on 2 workers of the local engine."""
    base = paper_spec("arm5", 100_000, True)
    jobs = [dict(spec=base, seed=s, key=str(s)) for s in range(trials)]
    walls = {}
    for workers in (1, 2):
        t0 = time.perf_counter()
        list(execute.local(jobs, workers, fn=_arm5_trial))
        walls[workers] = time.perf_counter() - t0
    return {"trials": trials, "wall_s_1_worker": walls[1], "wall_s_2_workers": walls[2],
            "speedup": walls[1] / walls[2]}


def bench(cfg: DictConfig) -> dict:
    repeats = cfg.bench.repeats
    result = {"machine": platform.processor() or platform.machine(), "cpus": os.cpu_count(),
              "repeats": repeats}
    for body in ("arm5", "icub"):
        for learner in ("goal_babbling", "online_goal_babbling"):  # compile or load the kernels
            time_trial(paper_spec(body, 10, True, learner))       # outside the timing
        time_trial(paper_spec(body, 10, True, extra=("learner.updates=online",)))
        specs = {"fast": paper_spec(body, EPOCHS["fast"][body], True),
                 "online": paper_spec(body, EPOCHS["online"][body], True, "online_goal_babbling"),
                 "lstsq": paper_spec(body, EPOCHS["lstsq"][body], True,
                                     extra=("learner.solver=lstsq",)),
                 "updates_online": paper_spec(body, EPOCHS["updates_online"][body], True,
                                              extra=("learner.updates=online",)),
                 "reference": paper_spec(body, EPOCHS["reference"][body], False)}
        times, row = paired(specs, repeats), {}
        for path in specs:
            wall, cpu = (np.array(t) for t in zip(*times[path]))
            row[f"{path}_us_per_trial_epoch"] = 1e6 * float(np.median(wall))
            row[f"{path}_us_all"] = [round(1e6 * t, 2) for t in wall]
            row[f"{path}_cpu_us_per_trial_epoch"] = 1e6 * float(np.median(cpu))
        row["speedup"] = row["reference_us_per_trial_epoch"] / row["fast_us_per_trial_epoch"]
        row["online_over_batch"] = row["online_us_per_trial_epoch"] / row["fast_us_per_trial_epoch"]
        for name, (a, b) in RATIOS.items():
            row[f"{name}_cpu"] = paired_ratio(times, a, b)
        row["online_draw_us_per_epoch"] = 1e6 * draw_time(specs["online"])
        row["lstsq_over_gradient"] = (row["lstsq_us_per_trial_epoch"]
                                      / row["fast_us_per_trial_epoch"])
        row["updates_online_over_batch"] = (row["updates_online_us_per_trial_epoch"]
                                            / row["fast_us_per_trial_epoch"])
        result[body] = row
        print(f"{body}: fast {row['fast_us_per_trial_epoch']:8.1f} us/trial-epoch   "
              f"reference {row['reference_us_per_trial_epoch']:9.1f} us/trial-epoch   "
              f"ratio fast/reference {1 / row['speedup']:.4f} ({row['speedup']:.0f}x faster)   "
              f"online {row['online_us_per_trial_epoch']:8.1f} us/trial-epoch, "
              f"online/batch {row['online_over_batch']:.2f} (CPU time "
              f"{row['online_over_batch_cpu']:.2f}; its draws alone "
              f"{row['online_draw_us_per_epoch']:.1f} us/epoch)   "
              f"lstsq {row['lstsq_us_per_trial_epoch']:8.1f} us/trial-epoch, lstsq/gradient "
              f"{row['lstsq_over_gradient']:.2f}   updates=online "
              f"{row['updates_online_us_per_trial_epoch']:8.1f} us/trial-epoch, online/batch "
              f"{row['updates_online_over_batch']:.2f}", flush=True)
        print(f"{body}: CPU time, paired: " + "   ".join(
            f"{name} {row[name]:.2f} wall, {row[name + '_cpu']:.2f} CPU" for name in RATIOS),
            flush=True)
    if cfg.bench.parallel:
        result["parallel"] = p = parallel_speedup()
        print(f"parallel: {p['trials']} arm5 trials, 1 worker {p['wall_s_1_worker']:.1f} s, "
              f"2 workers {p['wall_s_2_workers']:.1f} s, speedup {p['speedup']:.2f}x")
    out = Path(cfg.paths.bench) / "bench.json"
    io.write_json(out, result)
    print(f"wrote {out}")
    return result


def run(cfg: DictConfig) -> int:
    bench(cfg)
    return 0


@hydra.main(config_path=CONFIG_PATH, config_name="config", version_base="1.3")
def main(cfg: DictConfig) -> None:
    with execute.single_threaded_children():
        cli.finish(run, cfg)


if __name__ == "__main__":
    cli.main(main)
