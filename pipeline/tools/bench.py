"""Benchmarks of the compiled kernel (`make bench`), and two commands beside it.

    python -m pipeline.tools.bench [bench.repeats=5] [bench.parallel=false]     (make bench)
    python -m pipeline.tools.bench compare BASELINE_DIR [ROUNDS] [REPEATS] [LEARNER]
    python -m pipeline.tools.bench costs

make bench: for arm5 and the iCub at the paper's settings it times whole trials (draws, epochs
and the evaluation schedule) on one core per epoch, the fast path against the numpy reference,
online Goal Babbling, learner.solver=lstsq and learner.updates=online against the batch epoch,
all interleaved (`paired`: a shared machine's drifting speed moves them alike); beside each ratio
of the wall-clock medians stands the median of the pairs' CPU-time ratios (`*_cpu`). Then the
floors (pipeline.tools.floor): the flops of a sample over the peak of one core measured in the
same run (`floor_ratio`), and the compiled epoch stage by stage (`floor.stages`, `stage_row`),
each stage against its flops over the peak and against its counted floor (every class of
operation the formula needs, at the throughputs measured on this CPU: `floor.counted_ratio`).
With bench.parallel, the same arm5 trials on one and two workers. Writes paths.bench/bench.json.

compare: the fast path's time per trial-epoch of both bodies, a baseline checkout (`git archive
<commit> | tar -x -C /tmp/base`) against this one, each in child processes timed in CPU seconds,
interleaved A B B A ...; LEARNER goal_babbling (default) or online_goal_babbling.
costs: every learner's CPU time per sample and joint against Goal Babbling's fast path (each
learner's sample_cost).
"""
from __future__ import annotations

import json
import os
import platform
import statistics
import subprocess
import sys
import time
from pathlib import Path

import hydra
import numpy as np
from numba import njit
from omegaconf import DictConfig

import gbmodel
from gbmodel.features import exponents
from gbmodel.learners import goal_babbling as gb
from gbmodel.learners.goal_babbling import fast
from gbmodel.learners.goal_babbling.core import _BLOCK, _accumulate, _features, _predict
from gbmodel.learners.goal_babbling.fast import _epoch
from gbmodel.learners.goal_babbling.lstsq import solver_work
from gbmodel.learners.goal_babbling.rollout import (
    _box, _commands, _disturbances, _weights, _work, rollout,
)
from gbmodel.simd import LANES, chain_kinematics, fresh_cache

from .. import cli, execute, io
from ..config import CONFIG_PATH, compose
from ..plan import plan
from .floor import (  # noqa: F401 (the floors' names, as bench.json's keys call them)
    CLASSES, body_counts, counted_floor, online_sample_flops, peak_gflops, probe_ns, sample_counts, sample_flops,
)

# _part holds the kernels it calls, compiled in: its cache (with this folder's other kernels)
# goes when their code changes, or the bench would time the kernels of before an edit
fresh_cache(Path(__file__).parent, sorted(Path(fast.__file__).parent.glob("*.py")))

REPO = Path(__file__).resolve().parents[2]
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


# ---- the compiled epoch stage by stage --------------------------------------------------------
# stage -> the flop stages of bench.sample_flops it computes
STAGES = {"commands": ("commands",), "kinematics": ("kinematics",), "weights": ("weights",),
          "features": ("features",), "M_phi_error": ("M_phi", "error"),
          "gradient": ("gradient",)}
_PARTS = ("commands", "kinematics", "weights", "features", "features_predict",
          "features_predict_gradient", "epoch")


@njit(cache=True)
def _part(what, reps, M, idx, raw, amp, chain, targets, home, parent, var, joints, radius,
          steps, rate, plain, rule, ring, M0):
    """`reps` times one part of the epoch (what: an index of _PARTS) on the samples of the
    first epoch's rollout; 'epoch' runs the kernel's own epoch (fast._epoch: rollout and update)
    over the draws in turn, on a copy of M. Returns the epoch's padded sample count."""
    m, p = M.shape
    n = targets.shape[1]
    V, T = raw.shape[1], (idx.shape[1] - 1) * steps
    work = _work(m, n, p, V, T)
    box = _box(targets)
    solving = solver_work(m, n, p, V, T, False)
    rollout(M, idx[0], raw[0], amp[0], 1.0, chain, targets, home, parent, var, joints, radius,
            steps, box, work)
    Q, X, w, Phi, Rw, path, gpath, M32, GL = (work[0], work[1], work[2], work[3], work[4],
                                              work[5], work[7], work[12], work[13])
    Npad = len(w) - LANES
    for e in range(reps):
        if what == 0:  # the disturbances, g along the path, the commands
            _disturbances(raw[0], amp[0], 1.0, box[0], box[1], radius, work[10], work[11])
            _features(path, 0, gpath.shape[1], parent, var, work[6])
            _predict(M32, work[6], gpath.shape[1], gpath, Q, w[:0], 0)
            _commands(gpath, path, work[10], work[11], home, T, Npad, Q)
        elif what == 1:
            chain_kinematics(Q, X, Npad, joints, chain)
        elif what == 2:
            _weights(work[8], work[9], X, Q, V, T, Npad, w)
        elif what == 6:
            k = e % len(idx)
            _epoch(M.copy(), idx[k], raw[k], amp[k], 1.0, chain, targets, home, parent,
                   var, joints, radius, steps, rate, plain, rule, 1, box, work, ring, 0,
                   0.0, 0.0, 0.0, M0, solving)
        else:
            for c0 in range(0, Npad, _BLOCK):
                C = min(_BLOCK, Npad - c0)
                _features(X, c0, C, parent, var, Phi)
                if what >= 4:
                    _predict(M32, Phi, C, Rw, Q, w, c0)
                if what == 5:
                    _accumulate(Rw, Phi, C, GL)
    return Npad


def _inputs(spec: dict, epochs: int = 64):
    spec = gbmodel.TrialSpec.from_dict(spec)
    body, (_, params) = spec.make_body(), spec.make_learner()
    rng = np.random.default_rng(0)
    M = gb.init(params, body, 1.0, rng)
    idx, raw = gb.draw(params, body, epochs, rng)[:2]
    exps = exponents(body.n, params.degree)
    arr, opts = fast._arrays(body, exps), fast._options(params)
    if opts["rule"] != fast.GRADIENT:
        raise ValueError("the stages are the batch gradient rule's (solver=gradient, "
                         "updates=batch)")
    return (M, idx, raw, fast._amplitudes(raw, None), arr["chain"], arr["targets"], arr["home"],
            arr["parent"], arr["var"], arr["joints"], opts["radius"], opts["steps"],
            float(params.learning_rate), opts["plain"], opts["rule"], fast._NO_RING,
            fast._NO_M0)


def stage_row(spec: dict, flops: dict, counts: dict, peak, repeats: int = 5,
              seconds: float = 0.1) -> dict:
    """Where a sample's time goes in the compiled epoch of `spec` (a TrialSpec as data:
    paper_spec): each stage (rollout.py: the commands with the disturbances and g along the
    path, the kinematics, the weights; gradient.py with core.py: the features, M Phi and the
    weighted residuals, the gradient's register tiles) runs alone, many times over one epoch's
    samples, in turn, in reversed order every other repeat; its CPU time per padded sample
    (median) beside its flops (`flops`, by flop stage) over the peak measured before every
    repeat (`peak()`), and beside its counted floor (`counts`, by flop stage: floor.
    sample_counts, priced by floor.probe_ns measured here). What the stages leave of a whole
    epoch (the path, the home posture, the update of M, the calls) is the `rest`."""
    args = _inputs(spec)
    Npad = _part(0, 1, *args)
    reps = {}
    for i in range(len(_PARTS)):  # compiled or loaded, and sized to about `seconds` each
        t0 = time.process_time()
        _part(i, 4, *args)
        reps[i] = max(4, int(seconds / max(time.process_time() - t0, 1e-6) * 4))
    ns, peaks, probe = {name: [] for name in _PARTS}, [], probe_ns()
    for r in range(repeats):
        peaks.append(peak())
        for i in (range(len(_PARTS)) if r % 2 == 0 else reversed(range(len(_PARTS)))):
            t0 = time.process_time()
            _part(i, reps[i], *args)
            ns[_PARTS[i]].append(1e9 * (time.process_time() - t0) / reps[i] / Npad)
    t = {k: float(np.median(v)) for k, v in ns.items()}
    peak = float(np.median(peaks))
    times = {"commands": t["commands"], "kinematics": t["kinematics"], "weights": t["weights"],
             "features": t["features"],
             "M_phi_error": t["features_predict"] - t["features"],
             "gradient": t["features_predict_gradient"] - t["features_predict"]}
    stages = {}
    for name, parts in STAGES.items():
        f = sum(flops[k] for k in parts)
        counted = counted_floor({c: sum(counts[k].get(c, 0) for k in parts)
                                 for c in CLASSES}, probe)
        stages[name] = {"ns_per_sample": times[name], "flops": f, "floor_ns": f / peak,
                        "ratio": times[name] / (f / peak), "counted": counted,
                        "counted_ratio": times[name] / counted["floor_ns"]}
    stages["rest"] = {"ns_per_sample": t["epoch"] - sum(times.values()), "flops": 0,
                      "floor_ns": 0.0, "ratio": None}
    floor = sum(s["counted"]["floor_ns"] for s in stages.values() if "counted" in s)
    return {"samples_padded": Npad, "peak_gflops": peak, "epoch_ns_per_sample": t["epoch"],
            "epoch_floor_ratio": t["epoch"] / (sum(flops.values()) / peak), "stages": stages,
            "probe_ns_per_vector": probe, "counted_floor_ns": floor,
            "counted_ratio": t["epoch"] / floor}


def stage_lines(body_name: str, row: dict) -> list[str]:
    out = [f"{body_name}: the compiled epoch {row['epoch_ns_per_sample']:.2f} ns per sample, "
           f"{row['epoch_floor_ratio']:.2f}x its flop floor (peak {row['peak_gflops']:.0f} "
           f"GFLOP/s), {row['counted_ratio']:.2f}x its counted floor "
           f"({row['counted_floor_ns']:.2f} ns)"]
    for name, s in row["stages"].items():
        ratio = "" if s["ratio"] is None else (
            f"  floor {s['floor_ns']:5.2f} ns ({s['flops']:4.0f} flops)  {s['ratio']:5.2f}x"
            f"  counted {s['counted']['floor_ns']:5.2f} ns ({s['counted']['bound']})"
            f"  {s['counted_ratio']:5.2f}x")
        out.append(f"  {name:12s} {s['ns_per_sample']:6.2f} ns{ratio}")
    return out


def shape(body_name: str) -> tuple:
    """(body, samples per epoch, features p, variations V, path steps T) at paper_spec's."""
    spec = gbmodel.TrialSpec.from_dict(paper_spec(body_name, 10, True))
    body, (learner, params) = spec.make_body(), spec.make_learner()
    return (body, learner.samples_per_epoch(params, body), len(exponents(body.n, params.degree)),
            params.variations, params.targets_per_epoch * params.steps)


def floor_row(body_name: str, cpu_s: list, peaks: list, count=sample_flops) -> dict:
    """The fast path against the floor: ns per sample (median CPU time), flops per sample (total
    and per stage, by `count`: sample_flops, or online_sample_flops for updates=online), the peak
    (median of the repeats) and floor_ratio, the median over repeats of the time per sample over
    flops / that repeat's peak."""
    body, N, p, V, T = shape(body_name)
    flops = count(body, p, V, T)
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
        # where the compiled epoch's time goes, stage by stage against each stage's floors
        b, _, p, V, T = shape(body)
        floor["stages"] = st = stage_row(paper_spec(body, 10, True), floor["flops_per_stage"],
                                         body_counts(b, p, V, T), lambda: peak_gflops(tries=1),
                                         repeats)
        floor["counted_floor_ns"], floor["counted_ratio"] = (st["counted_floor_ns"],
                                                             st["counted_ratio"])
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
        print("\n".join(stage_lines(body, floor["stages"])), flush=True)
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


# ---- compare: two checkouts side by side; costs: every learner against the fast path --------
CHILD = r'''
import json, sys, time
import numpy as np, gbmodel
from pipeline.tools.bench import EPOCHS, paper_spec


def time_trial(spec, seed=0):
    t0 = time.process_time()
    gbmodel.run_trial(gbmodel.TrialSpec.from_dict(spec), np.random.default_rng(seed))
    return (time.process_time() - t0) / spec["epochs"]


out, learner = {}, sys.argv[2]
path = "online" if learner == "online_goal_babbling" else "fast"
for body in ("arm5", "icub"):
    spec = paper_spec(body, EPOCHS[path][body], True, learner)
    time_trial(paper_spec(body, 10, True, learner))
    out[body] = [time_trial(spec, s) * 1e6 for s in range(int(sys.argv[1]))]
print(json.dumps(out))
'''


def compare(baseline: str, rounds: int = 4, reps: int = 3, learner: str = "goal_babbling") -> dict:
    """Medians [us per trial-epoch, CPU] per body of `baseline` and this checkout, each round
    `reps` trials per body in a child process of each, in turn; prints them with the ratios."""
    trees = {"baseline": str(Path(baseline).resolve()), "this": str(REPO)}
    res = {t: {"arm5": [], "icub": []} for t in trees}
    for r in range(rounds):
        for t, path in (trees.items() if r % 2 == 0 else reversed(list(trees.items()))):
            p = subprocess.run([sys.executable, "-c", CHILD, str(reps), learner], cwd=path,
                               capture_output=True, text=True,
                               env={"PYTHONPATH": path, "PATH": "/usr/bin:/bin"})
            assert p.returncode == 0, p.stderr[-2000:]
            for b, times in json.loads(p.stdout.strip().splitlines()[-1]).items():
                res[t][b] += times
    for b in ("arm5", "icub"):
        m = {t: statistics.median(res[t][b]) for t in trees}
        print(f"{b}: baseline {m['baseline']:.1f} us/trial-epoch, this {m['this']:.1f} "
              f"us/trial-epoch, ratio this/baseline {m['this'] / m['baseline']:.3f} "
              f"(medians of {len(res['baseline'][b])})")
    return res


COSTS = [("goal_babbling", []), ("goal_babbling", ["learner.fast=false"]),
         ("goal_babbling", ["learner.updates=online"]), ("online_goal_babbling", []),
         ("online_goal_babbling", ["learner.fast=false"]), ("motor_babbling", []),
         ("example_memory", []), ("example_memory", ["learner.window=0"])]


def per_unit(body: str, learner: str, extra: list[str], least_s: float = 1.0) -> float:
    """CPU seconds per unit of unweighted cost (epochs x samples per epoch x joints) of one
    trial without growth, its epochs quadrupled until it takes `least_s` of CPU time."""
    spec = plan(compose([f"body={body}", f"learner={learner}", "growth=none", "trials.count=1",
                         "learner.epochs=10", *extra]))[0]["spec"]
    gbmodel.run_trial(gbmodel.TrialSpec.from_dict(spec), np.random.default_rng(0))
    epochs = 10
    while True:
        spec = {**spec, "epochs": epochs}
        t0 = time.process_time()
        gbmodel.run_trial(gbmodel.TrialSpec.from_dict(spec), np.random.default_rng(1))
        seconds = time.process_time() - t0
        if seconds > least_s:
            break
        epochs *= 4
    trial = gbmodel.TrialSpec.from_dict(spec)
    (module, params), b = trial.make_learner(), trial.make_body()
    return seconds / (epochs * module.samples_per_epoch(params, b) * b.m)


def costs() -> None:
    for body in ("arm5", "icub"):
        base = None
        for learner, extra in COSTS:
            t = per_unit(body, learner, extra)
            base = base or t
            print(f"{body:5s} {learner:21s} {' '.join(extra):24s} {1e9 * t:9.2f} ns per sample "
                  f"and joint, {t / base:8.1f}x Goal Babbling's fast path", flush=True)


def run(cfg: DictConfig) -> int:
    bench(cfg)
    return 0


@hydra.main(config_path=CONFIG_PATH, config_name="config", version_base="1.3")
def main(cfg: DictConfig) -> None:
    with execute.single_threaded_children():
        cli.finish(run, cfg)


if __name__ == "__main__":
    if sys.argv[1:2] == ["compare"]:
        compare(sys.argv[2], *(int(a) for a in sys.argv[3:5]), *sys.argv[5:6])
    elif sys.argv[1:2] == ["costs"]:
        costs()
    else:
        cli.main(main)
