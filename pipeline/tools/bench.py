"""Benchmarks of the compiled kernel and its floors (docs/core.md, "The fast path ... and
`make bench`"); two commands beside it.

    python -m pipeline.tools.bench [bench.repeats=5] [bench.parallel=false]     (make bench)
    python -m pipeline.tools.bench compare BASELINE_DIR [ROUNDS] [REPEATS] [LEARNER]
    python -m pipeline.tools.bench costs

make bench: whole trials of arm5 and the iCub on every path (PATHS) interleaved, the medians of
their wall and CPU ratios (RATIOS); the floors (floor.py): a sample's flops over the peak measured
in the run, the compiled epoch stage by stage against them and against its counted floor; with
bench.parallel, one and two workers; into paths.bench/bench.json. compare: another checkout's
kernel beside this one's. costs: every learner's CPU time per sample and joint against Goal
Babbling's fast path.
"""
from __future__ import annotations

import os
import platform
import statistics
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
from gbmodel.learners.goal_babbling.rollout import _commands, _disturbances, _weights, _work, rollout
from gbmodel.simd import (
    F4, LANES, box as _box, chain_kinematics, fresh_cache, vadd, vdiv, vfma, vload, vmul, vsplat,
    vsqrt, vstore, vsum, vwhere,
)

from .. import cli, execute, io
from ..config import CONFIG_PATH, compose
from ..plan import plan
from . import REPO, child, fail, interleaved
from .floor import CLASSES, body_counts, counted_floor, online_sample_flops, sample_flops

# _part holds the kernels it calls, compiled in: its cache (with this folder's other kernels)
# goes when their code changes, or the bench would time the kernels of before an edit
fresh_cache(Path(__file__).parent, sorted(Path(fast.__file__).parent.glob("*.py")))

# epochs per timed trial: long enough to swamp timer noise, short enough for the reference path
# (the path's learner and overrides: PATHS)
EPOCHS = {"fast": {"arm5": 5000, "icub": 1000}, "reference": {"arm5": 100, "icub": 20},
          "online": {"arm5": 5000, "icub": 1000}, "lstsq": {"arm5": 5000, "icub": 1000},
          "updates_online": {"arm5": 5000, "icub": 1000}}

# ---- the probes: one class of operation at full throughput; the peak ---------------------
@njit(cache=True)
def _probe(what, iters):
    """`iters` steps of 6 independent chains of one operation (what: an index of CLASSES but
    logic; load: 12 loads per step, 2 per fma, from two rows in L1; store: 6 vector stores of
    registers per step). Returns (the chains' sum, which stays a normal number, and a value
    that depends on every step)."""
    c, d, up = vsplat(F4(0.999)), vsplat(F4(0.001)), vsplat(F4(1.0000001))
    a0, a1, a2 = vsplat(1.0), vsplat(1.1), vsplat(1.2)
    a3, a4, a5 = vsplat(1.3), vsplat(1.4), vsplat(1.5)
    raw = np.ones(12 * 256 + LANES, np.float32)  # rows on 64-byte boundaries: no split lines
    off = (-(raw.ctypes.data // 4)) % LANES
    buf = raw[off:off + 12 * 256].reshape((12, 256))
    for it in range(iters):
        if what == 0:
            a0, a1, a2 = vfma(a0, c, d), vfma(a1, c, d), vfma(a2, c, d)
            a3, a4, a5 = vfma(a3, c, d), vfma(a4, c, d), vfma(a5, c, d)
        elif what == 1:
            a0, a1, a2, a3, a4, a5 = (vadd(a0, d), vadd(a1, d), vadd(a2, d), vadd(a3, d),
                                      vadd(a4, d), vadd(a5, d))
        elif what == 2:  # by 1 + 2^-23: 0.999 decayed into subnormals, 100x slower on Intel
            a0, a1, a2, a3, a4, a5 = (vmul(a0, up), vmul(a1, up), vmul(a2, up), vmul(a3, up),
                                      vmul(a4, up), vmul(a5, up))
        elif what == 4:  # each chain picks between two others: nothing to fold
            a0, a1, a2, a3, a4, a5 = (vwhere(a0, a1, a2, a3), vwhere(a1, a2, a3, a4),
                                      vwhere(a2, a3, a4, a5), vwhere(a3, a4, a5, a0),
                                      vwhere(a4, a5, a0, a1), vwhere(a5, a0, a1, a2))
        elif what == 5:  # x <- 1 / (x + 0.001): a full mantissa
            a0, a1, a2 = vdiv(c, vadd(a0, d)), vdiv(c, vadd(a1, d)), vdiv(c, vadd(a2, d))
            a3, a4, a5 = vdiv(c, vadd(a3, d)), vdiv(c, vadd(a4, d)), vdiv(c, vadd(a5, d))
        elif what == 6:
            a0, a1, a2 = vsqrt(vadd(a0, d)), vsqrt(vadd(a1, d)), vsqrt(vadd(a2, d))
            a3, a4, a5 = vsqrt(vadd(a3, d)), vsqrt(vadd(a4, d)), vsqrt(vadd(a5, d))
        elif what == 8:  # 12 broadcasts of an array's element per step
            o = (it * LANES) % 256
            a0 = vfma(vsplat(buf[0, o]), vsplat(buf[6, o]), a0)
            a1 = vfma(vsplat(buf[1, o]), vsplat(buf[7, o]), a1)
            a2 = vfma(vsplat(buf[2, o]), vsplat(buf[8, o]), a2)
            a3 = vfma(vsplat(buf[3, o]), vsplat(buf[9, o]), a3)
            a4 = vfma(vsplat(buf[4, o]), vsplat(buf[10, o]), a4)
            a5 = vfma(vsplat(buf[5, o]), vsplat(buf[11, o]), a5)
        elif what == 7:
            o = (it * LANES) % 256
            a0 = vfma(vload(buf, 0, o), vload(buf, 6, o), a0)
            a1 = vfma(vload(buf, 1, o), vload(buf, 7, o), a1)
            a2 = vfma(vload(buf, 2, o), vload(buf, 8, o), a2)
            a3 = vfma(vload(buf, 3, o), vload(buf, 9, o), a3)
            a4 = vfma(vload(buf, 4, o), vload(buf, 10, o), a4)
            a5 = vfma(vload(buf, 5, o), vload(buf, 11, o), a5)
        elif what == 9:
            o = (it * LANES) % 256
            vstore(buf, 0, o, a0)
            vstore(buf, 1, o, a1)
            vstore(buf, 2, o, a2)
            vstore(buf, 3, o, a3)
            vstore(buf, 4, o, a4)
            vstore(buf, 5, o, a5)
            if o == 0:
                a0 = vadd(a0, d)
    chains = vsum(vadd(vadd(vadd(a0, a1), vadd(a2, a3)), vadd(a4, a5)))
    return chains, chains + buf.sum()


@njit(cache=True)
def _probe12(what, iters):
    """_probe's fma (0), add (1), mul (2) in 12 chains: 6 F32x16 chains are 12 registers with
    AVX2 but 6 with AVX-512, whose two pipes need 8 to hide a latency of 4 (6 time the
    latency, not the throughput); 12 would spill AVX2's 16 (probe_ns takes the better)."""
    c, d, up = vsplat(F4(0.999)), vsplat(F4(0.001)), vsplat(F4(1.0000001))
    a0, a1, a2, a3 = vsplat(1.0), vsplat(1.1), vsplat(1.2), vsplat(1.3)
    a4, a5, a6, a7 = vsplat(1.4), vsplat(1.5), vsplat(1.6), vsplat(1.7)
    a8, a9, a10, a11 = vsplat(1.8), vsplat(1.9), vsplat(2.0), vsplat(2.1)
    for _ in range(iters):
        if what == 0:
            a0, a1, a2, a3 = vfma(a0, c, d), vfma(a1, c, d), vfma(a2, c, d), vfma(a3, c, d)
            a4, a5, a6, a7 = vfma(a4, c, d), vfma(a5, c, d), vfma(a6, c, d), vfma(a7, c, d)
            a8, a9, a10, a11 = vfma(a8, c, d), vfma(a9, c, d), vfma(a10, c, d), vfma(a11, c, d)
        elif what == 1:
            a0, a1, a2, a3 = vadd(a0, d), vadd(a1, d), vadd(a2, d), vadd(a3, d)
            a4, a5, a6, a7 = vadd(a4, d), vadd(a5, d), vadd(a6, d), vadd(a7, d)
            a8, a9, a10, a11 = vadd(a8, d), vadd(a9, d), vadd(a10, d), vadd(a11, d)
        else:
            a0, a1, a2, a3 = vmul(a0, up), vmul(a1, up), vmul(a2, up), vmul(a3, up)
            a4, a5, a6, a7 = vmul(a4, up), vmul(a5, up), vmul(a6, up), vmul(a7, up)
            a8, a9, a10, a11 = vmul(a8, up), vmul(a9, up), vmul(a10, up), vmul(a11, up)
    chains = vadd(vadd(vadd(a0, a1), vadd(a2, a3)), vadd(vadd(a4, a5), vadd(a6, a7)))
    return vsum(vadd(chains, vadd(vadd(a8, a9), vadd(a10, a11))))


# operations per step of _probe by class (logic is priced as an add: no probe of its own)
_PROBED = {"fma": 6, "add": 6, "mul": 6, "select": 6, "div": 6, "sqrt": 6, "load": 12,
           "bcast": 12, "store": 6}


def _took(fn, *args, clock=time.process_time) -> float:
    c0 = clock()
    fn(*args)
    return clock() - c0


def _best(fn, args, tries: int) -> float:
    """The least CPU time of `tries` calls, after a short one (compiled or loaded untimed)."""
    fn(*args[:-1], 10)
    return min(_took(fn, *args) for _ in range(tries))


def probe_ns(iters: int = 200_000, tries: int = 3) -> dict:
    """ns of CPU time per F32x16 operation of each class at full throughput, on this CPU (fma,
    add and mul: the better of 6 and 12 chains)."""
    ns = {name: 1e9 * max(_best(_probe, (CLASSES.index(name), iters), tries), 1e-9)
          / (iters * ops) for name, ops in _PROBED.items()}
    for what, name in enumerate(("fma", "add", "mul")):
        ns[name] = min(ns[name], 1e9 * max(_best(_probe12, (what, iters), tries), 1e-9)
                       / (iters * 12))
    return ns


def peak_gflops(iters: int = 2_000_000, tries: int = 3) -> float:
    """The peak of one core in float32 GFLOP/s: the better rate of 6 fma chains (_probe: AVX2's
    12 registers) and of 12 (_probe12: AVX-512's pipes)."""
    dts = ((_best(_probe, (0, iters), tries), 6), (_best(_probe12, (0, iters), tries), 12))
    return max((iters * chains * LANES * 2 / dt / 1e9 for dt, chains in dts if dt > 0), default=0.0)


# ---- whole trials ---------------------------------------------------------------------------
def paper_spec(body: str, epochs: int, fast: bool, learner: str = "goal_babbling", extra=()) -> dict:
    """The TrialSpec (as data) of a full-size trial of `body` at the paper's settings."""
    trial = plan(compose([f"body={body}", f"learner={learner}", "growth=none", "trials.count=1",
                          f"learner.epochs={epochs}", f"learner.fast={str(fast).lower()}",
                          *extra]))[0]
    return trial["spec"]


def time_trial(spec: dict, seed: int = 0) -> tuple[float, float]:
    """Seconds per epoch of one trial: wall clock and this process's CPU time."""
    t0, c0 = time.perf_counter(), time.process_time()
    gbmodel.run_trial(gbmodel.TrialSpec.from_dict(spec), np.random.default_rng(seed))
    return ((time.perf_counter() - t0) / spec["epochs"],
            (time.process_time() - c0) / spec["epochs"])


def paired_ratio(times: dict, a: str, b: str, clock: int = 1) -> float:
    """The median over repeats of a's time over b's in the same repeat (clock 0: wall, 1: CPU)."""
    return float(np.median([ta[clock] / tb[clock] for ta, tb in zip(times[a], times[b])]))


PATHS = {"fast": ("goal_babbling", ()), "online": ("online_goal_babbling", ()),
         "lstsq": ("goal_babbling", ("learner.solver=lstsq",)),
         "updates_online": ("goal_babbling", ("learner.updates=online",)),
         "reference": ("goal_babbling", ())}
RATIOS = {"speedup": ("reference", "fast"), "online_over_batch": ("online", "fast"),
          "lstsq_over_gradient": ("lstsq", "fast"),
          "updates_online_over_batch": ("updates_online", "fast")}  # speedup: fast is b's


# ---- the compiled epoch stage by stage --------------------------------------------------------
# stage -> the flop stages of sample_flops it computes
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
            _commands(gpath, path, work[10], home, T, Npad, Q)
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
    """Where a sample's time goes in the compiled epoch of `spec`: each part alone, many times
    over one epoch's samples, interleaved; CPU time per padded sample (median) against its flops
    over the median of `peak()` before each repeat, and against its counted floor. `rest`: what
    the stages leave of a whole epoch (the path, the home posture, the update of M, the calls)."""
    args = _inputs(spec)
    Npad = _part(0, 1, *args)
    # each part compiled or loaded, and sized to about `seconds`
    reps = [max(4, int(seconds / max(_took(_part, i, 4, *args), 1e-6) * 4))
            for i in range(len(_PARTS))]
    peaks, probe = [], probe_ns()
    ns = interleaved(range(len(_PARTS)), repeats, lambda i, _: 1e9 * _took(
        _part, i, reps[i], *args) / reps[i] / Npad, before=lambda: peaks.append(peak()))
    t = {_PARTS[i]: float(np.median(v)) for i, v in ns.items()}
    peak = float(np.median(peaks))
    times = dict({k: t[k] for k in _PARTS[:4]}, M_phi_error=t["features_predict"] - t["features"],
                 gradient=t["features_predict_gradient"] - t["features_predict"])
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


def floor_row(body, N: int, p: int, V: int, T: int, cpu_s: list, peaks: list,
              count=sample_flops) -> dict:
    """The fast path against its floor: ns and flops (by `count`) per sample; floor_ratio, the
    median over repeats of the time per sample over flops / that repeat's peak."""
    flops = count(body, p, V, T)
    ns, peak = [1e9 * t / N for t in cpu_s], float(np.median(peaks))
    return {"samples_per_epoch": N, "ns_per_sample": float(np.median(ns)),
            "flops_per_sample": flops["total"],
            "flops_per_stage": {k: v for k, v in flops.items() if k != "total"},
            "peak_gflops": peak, "floor_ns_per_sample": flops["total"] / peak,
            "floor_ratio": float(np.median([t / (flops["total"] / g)
                                            for t, g in zip(ns, peaks)]))}


def floor_line(floor: dict) -> str:
    return (f"{floor['ns_per_sample']:.2f} ns per sample (CPU), {floor['flops_per_sample']:.0f} "
            "flops per sample (" + ", ".join(f"{k} {v:.0f}" for k, v in
                                             floor["flops_per_stage"].items())
            + f"): floor {floor['floor_ns_per_sample']:.2f} ns, ratio to the floor "
            f"{floor['floor_ratio']:.2f}")


def draw_time(spec: dict, epochs: int = 200) -> float:
    """Seconds per epoch of the learner's draws alone (median of 3): no kernel removes them."""
    trial = gbmodel.TrialSpec.from_dict(spec)
    body, (learner, params) = trial.make_body(), trial.make_learner()
    return float(np.median([_took(learner.draw, params, body, epochs, np.random.default_rng(seed),
                                  clock=time.perf_counter) / epochs
                            for seed in range(3)]))


def _arm5_trial(job: dict) -> float:
    return time_trial(job["spec"], job["seed"])[0]


def parallel_speedup(trials: int = 8) -> dict:
    """Wall time of `trials` 100,000-epoch arm5 trials on 1 and on 2 local workers."""
    base = paper_spec("arm5", 100_000, True)
    jobs = [dict(spec=base, seed=s, key=str(s)) for s in range(trials)]
    walls = {w: _took(lambda: list(execute.local(jobs, w, fn=_arm5_trial)),
                      clock=time.perf_counter) for w in (1, 2)}
    return {"trials": trials, "wall_s_1_worker": walls[1], "wall_s_2_workers": walls[2],
            "speedup": walls[1] / walls[2]}


def body_row(body: str, repeats: int) -> dict:
    """bench.json's row of one body: every path's times, their ratios and the floors."""
    for path in ("fast", "online", "updates_online"):  # compile or load the kernels untimed
        time_trial(paper_spec(body, 10, True, *PATHS[path]))
    specs = {path: paper_spec(body, EPOCHS[path][body], path != "reference", *PATHS[path])
             for path in PATHS}
    peaks, row = [], {}
    times = interleaved(specs, repeats, lambda path, r: time_trial(specs[path], r),
                        before=lambda: peaks.append(peak_gflops()))
    for path in specs:
        wall, cpu = (np.array(t) for t in zip(*times[path]))
        row[f"{path}_us_per_trial_epoch"] = 1e6 * float(np.median(wall))
        row[f"{path}_us_all"] = [round(1e6 * t, 2) for t in wall]
        row[f"{path}_cpu_us_per_trial_epoch"] = 1e6 * float(np.median(cpu))
    for name, (a, b) in RATIOS.items():
        row[name] = row[f"{a}_us_per_trial_epoch"] / row[f"{b}_us_per_trial_epoch"]
        row[f"{name}_cpu"] = paired_ratio(times, a, b)
    row["online_draw_us_per_epoch"] = 1e6 * draw_time(specs["online"])
    spec = gbmodel.TrialSpec.from_dict(paper_spec(body, 10, True))
    b, (learner, params) = spec.make_body(), spec.make_learner()
    shape = (b, learner.samples_per_epoch(params, b), len(exponents(b.n, params.degree)),
             params.variations, params.targets_per_epoch * params.steps)
    row["floor"] = floor = floor_row(*shape, [t[1] for t in times["fast"]], peaks)
    # where the compiled epoch's time goes, stage by stage against each stage's floors
    floor["stages"] = st = stage_row(paper_spec(body, 10, True), floor["flops_per_stage"],
                                     body_counts(b, *shape[2:]),
                                     lambda: peak_gflops(tries=1), repeats)
    floor["counted_floor_ns"], floor["counted_ratio"] = st["counted_floor_ns"], st["counted_ratio"]
    row["updates_online_floor"] = online = floor_row(
        *shape, [t[1] for t in times["updates_online"]], peaks, online_sample_flops)
    # the online/batch ratio that both at their floors would give
    row["updates_online_over_batch_at_floor"] = (online["floor_ns_per_sample"]
                                                 / floor["floor_ns_per_sample"])
    return row


def row_lines(body: str, row: dict) -> list[str]:
    us = {path: row[f"{path}_us_per_trial_epoch"] for path in EPOCHS}
    floor, st = row["floor"], row["floor"]["stages"]
    out = [f"{body}: us/trial-epoch: " + "   ".join(f"{p} {t:.1f}" for p, t in us.items())
           + f" (online's draws alone {row['online_draw_us_per_epoch']:.1f} us/epoch)",
           f"{body}: ratios, paired: " + "   ".join(
               f"{name} {row[name]:.2f} wall, {row[name + '_cpu']:.2f} CPU" for name in RATIOS),
           f"{body}: floor: " + floor_line(floor)
           + f", peak {floor['peak_gflops']:.1f} GFLOP/s measured",
           f"{body}: the compiled epoch {st['epoch_ns_per_sample']:.2f} ns per sample, "
           f"{st['epoch_floor_ratio']:.2f}x its flop floor (peak {st['peak_gflops']:.0f} "
           f"GFLOP/s), {st['counted_ratio']:.2f}x its counted floor "
           f"({st['counted_floor_ns']:.2f} ns)"]
    for name, s in st["stages"].items():
        ratio = "" if s["ratio"] is None else (
            f"  floor {s['floor_ns']:5.2f} ns ({s['flops']:4.0f} flops)  {s['ratio']:5.2f}x"
            f"  counted {s['counted']['floor_ns']:5.2f} ns ({s['counted']['bound']})"
            f"  {s['counted_ratio']:5.2f}x")
        out.append(f"  {name:12s} {s['ns_per_sample']:6.2f} ns{ratio}")
    return out + [f"{body}: updates=online floor: " + floor_line(row["updates_online_floor"])
                  + "; online/batch at both floors "
                  f"{row['updates_online_over_batch_at_floor']:.2f}"]


def bench(cfg: DictConfig) -> dict:
    result = {"machine": platform.processor() or platform.machine(), "cpus": os.cpu_count(),
              "repeats": cfg.bench.repeats}
    for body in ("arm5", "icub"):
        result[body] = row = body_row(body, cfg.bench.repeats)
        print("\n".join(row_lines(body, row)), flush=True)
    if cfg.bench.parallel:
        result["parallel"] = p = parallel_speedup()
        print(f"parallel: {p['trials']} arm5 trials, 1 worker {p['wall_s_1_worker']:.1f} s, "
              f"2 workers {p['wall_s_2_workers']:.1f} s, speedup {p['speedup']:.2f}x")
    io.write_json(Path(cfg.paths.bench) / "bench.json", result)
    print(f"wrote {Path(cfg.paths.bench) / 'bench.json'}")
    return result


COSTS = [("goal_babbling", []), ("goal_babbling", ["learner.fast=false"]),
         ("goal_babbling", ["learner.updates=online"]), ("online_goal_babbling", []),
         ("online_goal_babbling", ["learner.fast=false"]), ("motor_babbling", []),
         ("example_memory", []), ("example_memory", ["learner.window=0"])]


def per_unit(body: str, learner: str, extra: list[str], least_s: float = 1.0) -> float:
    """CPU seconds per sample and joint of a trial without growth, its epochs quadrupled until
    it takes `least_s`."""
    spec = plan(compose([f"body={body}", f"learner={learner}", "growth=none", "trials.count=1",
                         "learner.epochs=10", *extra]))[0]["spec"]
    time_trial(spec)
    epochs = 10
    while (seconds := time_trial(spec := {**spec, "epochs": epochs}, 1)[1] * epochs) <= least_s:
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


# ---- bench compare: the kernel of another checkout beside this one's ----------------------------
CHILD = r'''
import json, sys
from pipeline.tools.bench import EPOCHS, paper_spec, time_trial

out, learner = {}, sys.argv[2]
path = "online" if learner == "online_goal_babbling" else "fast"
for body in ("arm5", "icub"):
    spec = paper_spec(body, EPOCHS[path][body], True, learner)
    time_trial(paper_spec(body, 10, True, learner))
    out[body] = [time_trial(spec, s)[1] * 1e6 for s in range(int(sys.argv[1]))]
print(json.dumps(out))
'''


def compare(baseline: str, rounds: int = 4, reps: int = 3, learner: str = "goal_babbling") -> dict:
    """`bench compare`: each round `reps` trials per body in a child process (CHILD) of `baseline`
    and of this checkout in turn; prints the medians (CPU) and the rounds' median paired ratio."""
    trees = {"baseline": str(Path(baseline).resolve()), "this": str(REPO)}
    runs = interleaved(trees, rounds, lambda t, _: child(
        trees[t], CHILD, str(reps), learner, env={"PYTHONPATH": trees[t], "PATH": "/usr/bin:/bin"}))
    res = {t: {b: [x for run in rs for x in run[b]] for b in ("arm5", "icub")}
           for t, rs in runs.items()}
    for b in ("arm5", "icub"):
        m = {t: statistics.median(res[t][b]) for t in trees}
        r = statistics.median(statistics.median(a[b]) / statistics.median(z[b])
                              for a, z in zip(runs["this"], runs["baseline"]))  # round by round
        print(f"{b}: baseline {m['baseline']:.1f}, this {m['this']:.1f} us/trial-epoch (medians of "
              f"{len(res['baseline'][b])}); this/baseline {r:.3f} (the median of {rounds} rounds)")
    return res


@hydra.main(config_path=CONFIG_PATH, config_name="config", version_base="1.3")
def main(cfg: DictConfig) -> None:
    with execute.single_threaded_children():
        cli.finish(lambda c: bench(c) and 0, cfg)


if __name__ == "__main__":
    if sys.argv[1:2] == ["compare"]:
        a = sys.argv[2:6]  # DIR: a checkout; ROUNDS, REPEATS: counts
        if not a or not (Path(a[0]) / "pipeline").is_dir() or not all(n.isdigit() for n in a[1:3]):
            sys.exit(fail("usage: bench compare DIR [ROUNDS] [REPEATS] [LEARNER], DIR a checkout"))
        compare(a[0], *(int(n) for n in a[1:3]), *a[3:4])
    elif sys.argv[1:2] == ["costs"]:
        costs()
    else:
        cli.main(main)
