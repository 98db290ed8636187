"""The fast path of Goal Babbling: whole blocks of epochs in one compiled (numba) call.

One file per part of an epoch, around a shared core, this one driving them:
- core.py: features, M Phi and the weighted residuals, the register tiles of R Phi^T;
- rollout.py: the target path, the variations' commands, the kinematics, the weights;
- the update rules, one file each: gradient.py (solver=gradient, updates=batch | steps),
  online.py (updates=online), lstsq.py (solver=lstsq); which one runs is one code (RULES),
  derived from the learner's settings once (`rule`) and passed down as that code.

It computes what `reference.py` states, epoch by epoch and with the same random numbers, in
float32 vector loops over the samples of an epoch:

- samples are columns, laid out variation-major, T + 1 columns per variation: the home example,
  then the path; the weight of a sample only looks at the column before it. After the last
  variation, padding up to a multiple of LANES (the home posture, weight 0, so that it adds
  exactly nothing);
- every step of the epoch is one pass over all columns (commands, kinematics, weights), the
  last ones in blocks of _BLOCK columns that stay in cache (features, weighted residuals,
  gradient);
- the rollout runs in float32; M stays float64 and is updated once per epoch (updates=batch;
  updates=steps repeats the gradient pass, updates=online goes sample by sample in float64
  vectors over M's rows, _online). Positions agree with the float64 reference to ~2e-7 m
  (tests/core/test_fast.py states the tolerances);
- the hand is carried backwards through the chain, one rotation about z per joint, joint by
  joint over blocks of columns whose points stay in L1, LANES samples at a time: DH rows, or a
  general (URDF) chain's fixed rotation and translation per joint
  (gbmodel.kinematics.chain_layout, simd.chain_kinematics);
- sin and cos are a branch-free polynomial (Cephes' kernels after a Cody-Waite reduction);
- features are built monomial by monomial, each a parent monomial times one coordinate;
- the gradient sum_t w (M Phi - q) Phi^T: the weighted residuals (rows in register tiles of 5),
  then tiles of vector accumulators shaped to the target's registers (core._accumulate: 5 x 5
  with AVX-512, 2 x 2 with AVX2), float32 lanes over the epoch whose sum is float64.

Bit-identical results on every x86-64 CPU, with or without AVX-512, whatever vector width LLVM
prefers (tests/core/test_kernel_targets.py: AVX2 + FMA, AVX-512, and the SSE2 baseline without FMA):
- every loop over samples is written on explicit LANES-wide vectors (`F32x16`, gbmodel/simd.py:
  LLVM <16 x float>, one zmm register, or two ymm halves without AVX-512, with the same result lane
  by lane), so the compiler never chooses how to split a sum: every sum over samples (the
  gradient, sum w) has one partial sum per lane, added up lane by lane in a fixed order at the
  end;
- multiply-adds are explicit fused multiply-adds (llvm.fma: one instruction on an FMA CPU, a
  correctly rounded libm call without), divisions and square roots exact IEEE operations;
- nothing is compiled with fastmath: no reassociation, no contraction of a * b + c, no
  approximate reciprocals, no NaN/inf assumptions (a diverging learner stays visible);
- no threads.
(Tested with numba 0.68 / llvmlite 0.50; LLVM may not change what these operations compute.)
"""
from __future__ import annotations

import numpy as np
from numba import njit

from ...kinematics import chain_layout
from ...features import monomial_tree
from ...simd import LANES
from .core import _lane_sum
from .gradient import gradient_steps
from .lstsq import solve, solver_work
from .online import online
from .rollout import _box, _distances, _work, rollout
from .solve import Solved

# the update rule of an epoch, as the kernel takes it: one code for (solver, updates)
GRADIENT, STEPS, ONLINE, LSTSQ = 0, 1, 2, 3
RULES = {("gradient", "batch"): GRADIENT, ("gradient", "steps"): STEPS,
         ("gradient", "online"): ONLINE, ("lstsq", "batch"): LSTSQ}


def rule(params) -> int:
    """The update rule's code of these settings (Params.validate refuses the other pairs)."""
    return RULES[params.solver, params.updates]


@njit(cache=True)
def _epoch(M, idx, raw, amp, s, body, targets, home, parent, var, joints, radius, steps,
           rate, plain, rule, update_steps, box, work, ring, slot, ridge, anchor, limit, M0,
           solver_work):
    """One epoch (see reference.epoch): rolls out and weights (rollout.rollout), then updates M
    in place by the rule `rule`: GRADIENT or STEPS, 1 or update_steps gradient steps at rate
    eta; ONLINE, one step per sample; LSTSQ, the solve of the Gram sums of the ring (this
    epoch's into ring[slot]).

    Leaves the samples in work: Q (m, N) postures, X (n, N) reached positions, w (N) weights,
    variation v in the columns v (T + 1) ... v (T + 1) + T (N = V (T + 1); then columns of
    padding up to a multiple of LANES, and LANES spare ones).
    """
    rollout(M, idx, raw, amp, s, body, targets, home, parent, var, joints, radius, steps, box,
            work)
    Q, X, w, Phi, Rw, M32, GL = work[0], work[1], work[2], work[3], work[4], work[12], work[13]
    Npad = len(w) - LANES
    if rule == LSTSQ:
        solve(M, M0, ring, slot, ridge, anchor, limit, joints[0] and joints[1], X, Q, w, Npad,
              parent, var, Phi, targets, s, solver_work)
        return
    # gradient descent on the weighted command error (eq. 6), plain or normalised by sum w
    eta = rate if plain else rate / _lane_sum(w, Npad)
    if rule == ONLINE:
        online(M, X, Q, w, raw.shape[0] * ((len(idx) - 1) * steps + 1), parent, var, eta)
        return
    gradient_steps(M, M32, X, Q, w, Npad, parent, var, Phi, Rw, GL, eta,
                   update_steps if rule == STEPS else 1)


@njit(cache=True)
def _block(M, idx, raw, amp, sizes, scales, rates, chain, targets, home, parent, var, joints,
           radius, steps, plain, rule, update_steps, ring, done, ridge, anchor, anchor_epochs,
           limit, M0):
    """Epochs e = 0 ... B-1 with sizes[e], per-joint length factors scales[e] and rates[e]
    (rule LSTSQ: ring, the Gram sums of the window, after `done` epochs learned)."""
    a, d, ca, sa, base, outputs, ty, R, general = chain
    m, p = M.shape
    n = targets.shape[1]
    V, T = raw.shape[1], (idx.shape[1] - 1) * steps
    work = _work(m, n, p, V, T)
    solving = solver_work(m, n, p, V, T, rule == LSTSQ)
    box = _box(targets)
    free = not (joints[0] and joints[1])  # no joint limits: the anchor stays (solve.anchor_at)
    ae = np.empty(m, np.float32)
    de = np.empty(m, np.float32)
    ye = np.empty(m, np.float32)
    for e in range(idx.shape[0]):
        for i in range(m):
            ae[i] = a[i] * scales[e, i]
            de[i] = d[i] * scales[e, i]
            ye[i] = ty[i] * scales[e, i]
        body = (ae, de, ca, sa, base, outputs, ye, R, general)
        _epoch(M, idx[e], raw[e], amp[e], sizes[e], body, targets, home, parent, var, joints,
               radius, steps, rates[e], plain, rule, update_steps, box, work, ring,
               (done + e) % max(len(ring), 1), ridge,
               anchor if free else anchor * anchor_epochs / (anchor_epochs + done + e),
               0.0 if free else limit, M0, solving)


_ARRAYS: dict = {}  # (id(body), exps) -> (body, arrays); the body is kept so its id stays its own


def _arrays(body, exps):
    """The body as the kernels take it: float32 chain and joint map, plus the monomial tree.
    Built once per body object (bodies are frozen) and monomial table."""
    exps = np.asarray(exps)
    key = (id(body), exps.shape, exps.tobytes())
    hit = _ARRAYS.get(key)
    if hit is not None and hit[0] is body:
        return hit[1]
    f4 = lambda x: np.ascontiguousarray(x, np.float32)  # noqa: E731
    chain = chain_layout(body)
    normalized = body.normalized
    joints = (normalized, body.saturates,
              f4(body.q_min if normalized else np.zeros(body.m)),
              f4(body.q_max - body.q_min if normalized else np.ones(body.m)),
              f4(body.theta_offset))
    parent, var = monomial_tree(exps)
    arr = dict(
        chain=(f4(chain["a"]), f4(chain["d"]), f4(chain["cos_alpha"]), f4(chain["sin_alpha"]),
               f4(chain["base"]), np.array(body.outputs, np.int64), f4(chain["ty"]),
               f4(chain["R"]), chain["general"]),
        targets=f4(body.targets), home=f4(body.saturate(body.home)), parent=parent, var=var,
        joints=joints,
    )
    if len(_ARRAYS) >= 32:
        _ARRAYS.clear()
    _ARRAYS[key] = (body, arr)
    return arr


def _amplitudes(raw, amp):
    """The amplitude factors (..., V, m): the drawn ones (uniform reading), or 1 (exact)."""
    if amp is None:
        return np.ones(raw.shape[:-1])
    return np.ascontiguousarray(amp, np.float64)



def _options(params):
    return dict(radius=float(params.radius), steps=int(params.steps),
                plain=params.step == "plain", rule=rule(params),
                update_steps=int(params.update_steps))


_NO_RING = np.zeros((0, 1, 1))
_NO_M0 = np.zeros((1, 1))


def run_block(M, body, params, exps, sizes, scales, rates, idx, raw, amp=None):
    """Epochs with sizes `sizes`, per-joint length factors `scales` (B, m), rates eta (B,) and
    draws idx, raw (and amp, the amplitude factors of the uniform reading). Returns the
    updated M, or under solver=lstsq (M a solve.Solved state) the next Solved state."""
    options = _options(params)
    solving = options["rule"] == LSTSQ
    if solving != isinstance(M, Solved):
        raise TypeError(f"learner.solver={params.solver!r} with a state of type {type(M)}")
    ring = np.array(M.ring, dtype=np.float64, order="C") if solving else _NO_RING
    M0 = np.ascontiguousarray(M.M0, np.float64) if solving else _NO_M0
    done = M.epochs if solving else 0
    out = np.array(M.M if solving else M, dtype=np.float64, order="C")
    _block(out, np.ascontiguousarray(idx, np.int64), np.ascontiguousarray(raw, np.float64),
           _amplitudes(raw, amp), np.ascontiguousarray(sizes, np.float64),
           np.ascontiguousarray(scales, np.float32).reshape(len(sizes), body.m),
           np.ascontiguousarray(rates, np.float64), **options, **_arrays(body, exps),
           ring=ring, done=done, ridge=float(params.ridge), anchor=float(params.anchor),
           anchor_epochs=float(params.anchor_epochs), limit=float(params.limit_pull), M0=M0)
    return Solved(out, ring, done + len(sizes), M.M0) if solving else out


def distances(M, body, exps, scale, xs):
    """|f(g(x*)) - x*| for every row of xs (N, n): the evaluation on the fast path."""
    arr = _arrays(body, exps)
    out = np.empty(len(xs))
    _distances(np.ascontiguousarray(M, np.float64), np.ascontiguousarray(scale, np.float32),
               arr["chain"], np.ascontiguousarray(xs, np.float64), arr["parent"], arr["var"],
               arr["joints"], out)
    return out


def epoch_samples(M, body, params, exps, size, scale, idx, raw, amp=None, rate=None):
    """One epoch on the fast path, for tests: returns (M after, Q, X, w) with the samples laid
    out as (V, T + 1, ...) like reference.epoch's (rate: eta, params.learning_rate if None).
    The gradient rules only (solver=lstsq keeps a ring: run_block)."""
    if _options(params)["rule"] == LSTSQ:
        raise ValueError("epoch_samples runs the gradient rules; solver=lstsq: run_block")
    M = np.array(M, dtype=np.float64, order="C")
    arr = _arrays(body, exps)
    a, d, ca, sa, base, outputs, ty, R, general = arr["chain"]
    k = np.asarray(scale, np.float32)
    chain = (a * k, d * k, ca, sa, base, outputs, ty * k, R, general)
    T = (len(idx) - 1) * params.steps
    V = raw.shape[0]
    work = _work(body.m, body.n, len(exps), V, T)
    _epoch(M, np.asarray(idx, np.int64), np.ascontiguousarray(raw, np.float64),
           _amplitudes(raw, amp), float(size), chain, arr["targets"], arr["home"], arr["parent"],
           arr["var"], arr["joints"], rate=float(params.learning_rate if rate is None else rate),
           box=_box(arr["targets"]), work=work, ring=_NO_RING, slot=0, ridge=0.0, anchor=0.0,
           limit=0.0, M0=_NO_M0,
           solver_work=solver_work(body.m, body.n, len(exps), V, T, False), **_options(params))
    Q, X, w = work[0], work[1], work[2]
    N = V * (T + 1)
    return (M, Q[:, :N].T.reshape(V, T + 1, -1), X[:, :N].T.reshape(V, T + 1, -1),
            w[:N].reshape(V, T + 1))
