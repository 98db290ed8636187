"""Goal Babbling's fast path: blocks of epochs in one compiled (numba) call, computing what
reference.py states with the same draws. core.py: features, M Phi, the register tiles of R Phi^T
and the gradient rule; rollout.py: path, commands, kinematics, weights; online.py, lstsq.py: the
other update rules; the rule is one code (RULES) passed down.

Samples are float32 columns, variation-major, T + 1 per variation (home first; a weight looks
only at the column before), padded to a multiple of LANES with weight-0 home columns; M stays
float64. Bit-identical on every x86-64 CPU, with or without AVX-512 or FMA
(tests/core/test_kernel_targets.py): every loop over samples runs on explicit LANES-wide vectors
(simd.F32x16), so every sum over samples has one partial sum per lane, added in a fixed order;
multiply-adds are explicit llvm.fma; no fastmath, no threads. (Tested with numba 0.68 /
llvmlite 0.50.)
"""
from __future__ import annotations

import numpy as np
from numba import njit

from ...kinematics import kernel_arrays, kernel_body
from ...features import monomial_tree
from ...simd import LANES, box as _box
from .core import _lane_sum, gradient_steps
from .lstsq import solve, solver_work
from .online import online
from .rollout import _distances, _work, rollout, scaled
from .solve import Solved

# the update rule of an epoch, as the kernel takes it: one code for (solver, updates)
GRADIENT, STEPS, ONLINE, LSTSQ = 0, 1, 2, 3
RULES = {("gradient", "batch"): GRADIENT, ("gradient", "steps"): STEPS,
         ("gradient", "online"): ONLINE, ("lstsq", "batch"): LSTSQ}


def rule(params) -> int:
    return RULES[params.solver, params.updates]


@njit(cache=True, inline="always")
def _epoch(M, idx, raw, amp, s, body, targets, home, parent, var, joints, radius, steps,
           rate, plain, rule, update_steps, box, work, ring, slot, ridge, anchor, limit, M0,
           solver_work):
    """One epoch (reference.epoch): the rollout, then M updated in place by `rule` (LSTSQ:
    this epoch's Gram sums into ring[slot]); the samples stay in work (rollout.rollout)."""
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
    """Epochs with sizes[e], length factors scales[e], rates[e] (LSTSQ: `done` epochs in)."""
    m, p = M.shape
    n = targets.shape[1]
    V, T = raw.shape[1], (idx.shape[1] - 1) * steps
    work = _work(m, n, p, V, T)
    solving = solver_work(m, n, p, V, T, rule == LSTSQ)
    box = _box(targets)
    free = not (joints[0] and joints[1])  # no joint limits: the anchor stays (solve.anchor_at)
    held = np.empty((3, m), np.float32)
    for e in range(idx.shape[0]):
        body = scaled(chain, scales[e], held)
        _epoch(M, idx[e], raw[e], amp[e], sizes[e], body, targets, home, parent, var, joints,
               radius, steps, rates[e], plain, rule, update_steps, box, work, ring,
               (done + e) % max(len(ring), 1), ridge,
               anchor if free else anchor * anchor_epochs / (anchor_epochs + done + e),
               0.0 if free else limit, M0, solving)


def _arrays(body, exps):
    """The body as the kernels take it (float32), once per body object and monomial table."""
    exps = np.asarray(exps)
    return kernel_arrays(body, ("f4", exps.shape, exps.tobytes()), lambda: _build(body, exps))


def _build(body, exps):
    chain, joints = kernel_body(body, np.float32)
    parent, var = monomial_tree(exps)
    return dict(chain=chain, targets=np.ascontiguousarray(body.targets, np.float32),
                home=np.ascontiguousarray(body.saturate(body.home), np.float32), parent=parent,
                var=var, joints=joints)


def _amplitudes(raw, amp):
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
    """The epochs of `sizes`: the updated M (solver=lstsq: the next solve.Solved)."""
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
    arr = _arrays(body, exps)
    out = np.empty(len(xs))
    _distances(np.ascontiguousarray(M, np.float64), np.ascontiguousarray(scale, np.float32),
               arr["chain"], np.ascontiguousarray(xs, np.float64), arr["parent"], arr["var"],
               arr["joints"], out)
    return out


def epoch_samples(M, body, params, exps, size, scale, idx, raw, amp=None, rate=None):
    """For tests: one epoch of a gradient rule, (M after, Q, X, w) laid out as reference.epoch's
    samples (rate: params.learning_rate if None)."""
    if _options(params)["rule"] == LSTSQ:
        raise ValueError("epoch_samples runs the gradient rules; solver=lstsq: run_block")
    M = np.array(M, dtype=np.float64, order="C")
    arr = _arrays(body, exps)
    chain = scaled(arr["chain"], np.asarray(scale, np.float32), np.empty((3, body.m), np.float32))
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
