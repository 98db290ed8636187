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

The floor: per body, the flops of one sample counted from the kernel's code (`sample_flops`, stage
by stage, from m, n, p and the chain) over the peak of one core measured on this machine in the
same run (`peak_gflops`: independent fused multiply-add chains on the kernel's vector type, before
every repeat); `floor_ratio` is the fast path's CPU time per sample over flops / peak, the median
of the repeats' ratios (a loaded machine slows the peak and the trial alike). Beside it
(`floor.stages`, pipeline.tools.kernel_stages) the compiled epoch stage by stage, each against
its own flops over the peak.
"""
from __future__ import annotations

import os
import platform
import time
from pathlib import Path

import hydra
import numpy as np
from numba import njit
from omegaconf import DictConfig

import gbmodel
from gbmodel.features import exponents
from gbmodel.kinematics import chain_layout
from gbmodel.simd import LANES, W8, F4, vadd, vfma, vsplat, vsum

from .. import cli, execute, io
from . import kernel_stages
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


def paired(specs: dict, repeats: int, before=None) -> dict:
    """Whole trials of every spec in `specs` (name -> spec), interleaved: repeat r runs them in
    turn, in reversed order every other repeat, all with seed r, so that a machine that speeds up
    or slows down during the run shifts them alike. name -> (wall, cpu) seconds per epoch, one
    per repeat. `before()`, if given, runs at the start of every repeat."""
    out = {name: [] for name in specs}
    for r in range(repeats):
        if before is not None:
            before()
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


# ---- the floor: flops of a sample over the peak of one core -------------------------------------
# Counted from the kernel's code (gbmodel/learners/goal_babbling: rollout.py, core.py, gradient.py;
# gbmodel/simd.py): a fused multiply-add is 2 flops; an add, subtract, multiply, divide or square
# root 1; a sign flip, compare, select (the clips, the guards of eq. 1-3) or a store 0.
SINCOS_FLOPS = 23  # simd.sincos: 4 fma + 1 sub + 1 mul (reduction, r^2), 3 fma + 1 mul (sin),
#                   4 fma (cos)


def sample_flops(body, p: int, V: int, T: int) -> dict:
    """Flops of one sample of an epoch of the batch kernel (solver=gradient), stage by stage, for
    a body's chain (m joints, n outputs), p features, V variations of T + 1 samples: what the
    kernel computes per sample column (simd.chain_kinematics, rollout._commands and _weights,
    core._features, _predict and _accumulate); g along the path (once per path column, shared by
    the V variations) is counted per sample."""
    chain, m, n = chain_layout(body), body.m, body.n
    kinematics = 0
    for i in range(m):
        theta = 2 if body.normalized else 1  # q (span / 2) + ... : an fma; q + offset: an add
        if chain["general"]:
            step = 3 * 6 + 6  # R_i p + t_i (9 fma), then Rz: 2 fma + 2 mul
        else:
            ca, sa = chain["cos_alpha"][i], chain["sin_alpha"][i]
            twist = 1 if (ca, sa) in ((1, 0), (0, 1), (0, -1)) else 7  # pz +- d; or Rx(alpha)
            step = 1 + twist + 6  # u = p_x + a; Rz: 2 fma + 2 mul
        kinematics += theta + SINCOS_FLOPS + step
    kinematics += 6 * n  # the base: 3 fma per output
    path_columns = -(-(T + 1) // LANES) * LANES
    flops = {
        # g + A x* + b: an add and n fma per joint; g along the path (features, M Phi) per sample
        "commands": m * (1 + 2 * n) + (p - 1 + m * (2 * p - 1)) * path_columns / (V * (T + 1)),
        "kinematics": kinematics,  # theta, sin and cos, the chain step per joint, the base
        # eq. 1-3: dx, dot, |dx|^2 per output; dq, |dq|^2 per joint; 2 sqrt, 2 div, 2 mul, 1 add
        "weights": 5 * n + 3 * m + 8,
        "features": p - 1,  # one product per monomial
        "M_phi": m * (2 * p - 1),  # a product and p - 1 fma per row
        "error": 2 * m,  # w (M phi - q): a subtract and a multiply per row
        "gradient": 2 * m * p,  # one fma per entry of R Phi^T
    }
    flops["total"] = sum(flops.values())
    return flops


def online_sample_flops(body, p: int, V: int, T: int) -> dict:
    """Flops of one sample of an epoch with learner.updates=online: the rollout's stages of
    sample_flops (the same float32 kernel), then the online step in float64
    (goal_babbling/online.py), counted from its code on the W = m rounded up to W8 lanes it
    computes: per pair of samples s_t, g_t+1, s_t+1 (6 W), per feature the two steps and the two
    predictions (4 fma: 8 W p), then g and P (4 W); per sample eta w (1), the features (p - 1)
    and d = phi_t . phi_t+1 (2 p - 1). A float64 flop counts as two float32 ones: a vector holds
    half as many lanes, and the peak is measured in float32."""
    batch = sample_flops(body, p, V, T)
    W = -(-body.m // W8) * W8
    step = 4 * W * p + 5 * W + 1 + (p - 1) + (2 * p - 1)
    flops = {k: batch[k] for k in ("commands", "kinematics", "weights")}
    flops["online_step_float64_x2"] = 2 * step
    flops["total"] = sum(flops.values())
    return flops


@njit(cache=True)
def _fma_chains(iters):
    """6 independent chains of vfma on the kernel's vector type (F32x16: 12 ymm or 6 zmm
    registers), iters steps each: 6 * LANES * 2 flops per step."""
    m, c = vsplat(F4(0.999)), vsplat(F4(0.001))
    a0, a1, a2, a3 = vsplat(1.0), vsplat(1.1), vsplat(1.2), vsplat(1.3)
    a4, a5 = vsplat(1.4), vsplat(1.5)
    for _ in range(iters):
        a0, a1, a2 = vfma(a0, m, c), vfma(a1, m, c), vfma(a2, m, c)
        a3, a4, a5 = vfma(a3, m, c), vfma(a4, m, c), vfma(a5, m, c)
    return vsum(vadd(vadd(vadd(a0, a1), vadd(a2, a3)), vadd(a4, a5)))


@njit(cache=True)
def _fma_chains8(iters):
    """8 chains (for a CPU whose fma latency times its fma units exceeds 6 vectors)."""
    m, c = vsplat(F4(0.999)), vsplat(F4(0.001))
    a0, a1, a2, a3 = vsplat(1.0), vsplat(1.1), vsplat(1.2), vsplat(1.3)
    a4, a5, a6, a7 = vsplat(1.4), vsplat(1.5), vsplat(1.6), vsplat(1.7)
    for _ in range(iters):
        a0, a1, a2, a3 = vfma(a0, m, c), vfma(a1, m, c), vfma(a2, m, c), vfma(a3, m, c)
        a4, a5, a6, a7 = vfma(a4, m, c), vfma(a5, m, c), vfma(a6, m, c), vfma(a7, m, c)
    return vsum(vadd(vadd(vadd(a0, a1), vadd(a2, a3)), vadd(vadd(a4, a5), vadd(a6, a7))))


def peak_gflops(iters: int = 2_000_000, tries: int = 3) -> float:
    """The peak of one core in float32 GFLOP/s, measured: the best CPU-time rate of `tries` runs
    of 6 and of 8 independent fma chains on F32x16 (about 10 ms each at 100 GFLOP/s)."""
    best = 0.0
    for fn, chains in ((_fma_chains, 6), (_fma_chains8, 8)):
        fn(10)  # compiled or loaded outside the timing
        for _ in range(tries):
            c0 = time.process_time()
            fn(iters)
            dt = time.process_time() - c0
            if dt > 0:
                best = max(best, iters * chains * LANES * 2 / dt / 1e9)
    return best


def floor_row(body_name: str, cpu_s: list, peaks: list, count=sample_flops) -> dict:
    """The fast path against the floor: ns per sample (median CPU time), flops per sample (total
    and per stage, by `count`: sample_flops, or online_sample_flops for updates=online), the peak
    (median of the repeats) and floor_ratio, the median over repeats of the time per sample over
    flops / that repeat's peak."""
    spec = gbmodel.TrialSpec.from_dict(paper_spec(body_name, 10, True))
    body, (learner, params) = spec.make_body(), spec.make_learner()
    N = learner.samples_per_epoch(params, body)
    p = len(exponents(body.n, params.degree))
    flops = count(body, p, params.variations, params.targets_per_epoch * params.steps)
    ns = [1e9 * t / N for t in cpu_s]
    return {"samples_per_epoch": N, "ns_per_sample": float(np.median(ns)),
            "flops_per_sample": flops["total"],
            "flops_per_stage": {k: v for k, v in flops.items() if k != "total"},
            "peak_gflops": float(np.median(peaks)),
            "floor_ns_per_sample": flops["total"] / float(np.median(peaks)),
            "floor_ratio": float(np.median([t / (flops["total"] / g)
                                            for t, g in zip(ns, peaks)]))}


def floor_line(floor: dict) -> str:
    """A floor_row as one line: time and flops per sample, its floor and the ratio."""
    return (f"{floor['ns_per_sample']:.2f} ns per sample (CPU), {floor['flops_per_sample']:.0f} "
            "flops per sample (" + ", ".join(f"{k} {v:.0f}" for k, v in
                                             floor["flops_per_stage"].items())
            + f"): floor {floor['floor_ns_per_sample']:.2f} ns, ratio to the floor "
            f"{floor['floor_ratio']:.2f}")


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
        peaks = []
        times, row = paired(specs, repeats, before=lambda: peaks.append(peak_gflops())), {}
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
        row["floor"] = floor = floor_row(body, [t[1] for t in times["fast"]], peaks)
        # where the compiled epoch's time goes, stage by stage against each stage's floor
        floor["stages"] = kernel_stages.stage_row(paper_spec(body, 10, True),
                                                  floor["flops_per_stage"],
                                                  lambda: peak_gflops(tries=1), repeats)
        row["updates_online_floor"] = online = floor_row(
            body, [t[1] for t in times["updates_online"]], peaks, online_sample_flops)
        # the online/batch ratio that both at their floors would give
        row["updates_online_over_batch_at_floor"] = (online["floor_ns_per_sample"]
                                                     / floor["floor_ns_per_sample"])
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
        print(f"{body}: floor: " + floor_line(floor)
              + f", peak {floor['peak_gflops']:.1f} GFLOP/s measured", flush=True)
        print("\n".join(kernel_stages.lines(body, floor["stages"])), flush=True)
        print(f"{body}: updates=online floor: " + floor_line(online) + "; online/batch at both "
              f"floors {row['updates_online_over_batch_at_floor']:.2f}", flush=True)
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
