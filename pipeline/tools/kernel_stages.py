"""Where a sample's time goes in the batch kernel, stage by stage, against each stage's floor
(part of `make bench`: bench.json's `floor.stages`, printed under each body's floor line).

`make bench` states the whole trial's time per sample over the floor (the flops counted from the
kernel's code over the peak of one core). This breaks the compiled epoch down: each stage of
gbmodel/learners/goal_babbling (rollout.py: the commands with the disturbances and g along the
path, the kinematics, the weights; gradient.py with core.py: the features, M Phi and the
weighted residuals, the gradient's register tiles) runs alone, many times over one epoch's
samples at the paper's settings, and its CPU time per sample is set beside its flops
(bench.sample_flops) over the measured peak. What the stages leave of a whole epoch (the path,
the home posture, the update of M, the calls) is the `rest`. The stages are timed in turn,
in reversed order every other repeat; medians over repeats.

A stage far above its floor is bound by something the flop count does not see: divisions and
square roots (a vector division costs several fused multiply-adds' time), selects, sign flips
and address arithmetic on the same vector ports, or stores to L2.
"""
from __future__ import annotations

import time
from pathlib import Path

import numpy as np
from numba import njit

import gbmodel
from gbmodel.features import exponents
from gbmodel.learners import goal_babbling as gb
from gbmodel.learners.goal_babbling import fast
from gbmodel.learners.goal_babbling.fast import _epoch
from gbmodel.learners.goal_babbling.core import _BLOCK, _accumulate, _features, _predict
from gbmodel.learners.goal_babbling.lstsq import solver_work
from gbmodel.learners.goal_babbling.rollout import (
    _box, _commands, _disturbances, _weights, _work, rollout,
)
from gbmodel.simd import LANES, chain_kinematics, fresh_cache

# _part holds the kernels it calls, compiled in: its cache (with this folder's other kernels)
# goes when their code changes, or the bench would time the kernels of before an edit
fresh_cache(Path(__file__).parent, sorted(Path(fast.__file__).parent.glob("*.py")))

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
        raise ValueError("kernel_stages times the batch gradient rule (solver=gradient, "
                         "updates=batch)")
    return (M, idx, raw, fast._amplitudes(raw, None), arr["chain"], arr["targets"], arr["home"],
            arr["parent"], arr["var"], arr["joints"], opts["radius"], opts["steps"],
            float(params.learning_rate), opts["plain"], opts["rule"], fast._NO_RING,
            fast._NO_M0)


def stage_row(spec: dict, flops: dict, peak, repeats: int = 5, seconds: float = 0.1) -> dict:
    """Per stage of the fast path of `spec` (a TrialSpec as data: bench.paper_spec): ns per
    padded sample (median CPU time over repeats), its flops per sample (`flops`, by flop stage:
    the floor row's flops_per_stage, bench.sample_flops), the floor (flops over `peak()`, the
    peak measured before every repeat: bench.peak_gflops) and their ratio; and the whole epoch."""
    args = _inputs(spec)
    Npad = _part(0, 1, *args)
    reps = {}
    for i in range(len(_PARTS)):  # compiled or loaded, and sized to about `seconds` each
        t0 = time.process_time()
        _part(i, 4, *args)
        reps[i] = max(4, int(seconds / max(time.process_time() - t0, 1e-6) * 4))
    ns, peaks = {name: [] for name in _PARTS}, []
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
        stages[name] = {"ns_per_sample": times[name], "flops": f, "floor_ns": f / peak,
                        "ratio": times[name] / (f / peak)}
    stages["rest"] = {"ns_per_sample": t["epoch"] - sum(times.values()), "flops": 0,
                      "floor_ns": 0.0, "ratio": None}
    return {"samples_padded": Npad, "peak_gflops": peak, "epoch_ns_per_sample": t["epoch"],
            "epoch_floor_ratio": t["epoch"] / (sum(flops.values()) / peak), "stages": stages}


def lines(body_name: str, row: dict) -> list[str]:
    out = [f"{body_name}: the compiled epoch {row['epoch_ns_per_sample']:.2f} ns per sample, "
           f"{row['epoch_floor_ratio']:.2f}x its floor (peak {row['peak_gflops']:.0f} GFLOP/s)"]
    for name, s in row["stages"].items():
        ratio = "" if s["ratio"] is None else (f"  floor {s['floor_ns']:5.2f} ns "
                                               f"({s['flops']:4.0f} flops)  {s['ratio']:5.2f}x")
        out.append(f"  {name:12s} {s['ns_per_sample']:6.2f} ns{ratio}")
    return out
