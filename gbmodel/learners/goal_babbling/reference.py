"""The Goal Babbling learner (paper sec. 2.2 and 3), plain numpy: the reference path.

This module is the readable statement of the algorithm; `gbmodel.fast` computes the same epoch in
compiled loops and is tested against it. One epoch:

1. a target path: K + 1 targets drawn from the target set (at the body's current size), joined by
   L linear steps (eq. 9), T = K * L path targets x*_t;
2. V variations g^v(x) = g(x) + A_v x + b_v (eq. 4, 8), each row scaled so that
   max |e_i| over the target set is exactly R;
3. each variation reaches for the path: q_t = g^v(x*_t) (saturated), x_t = f(q_t); the home example
   (x_home, q_home) is prepended as t = 0 with weight 1 (eq. 5) and is where the movement starts;
4. weights w_t = w_dir * w_eff (eq. 1-3) from the movement between samples t-1 and t;
5. one gradient step on the weighted command error (eq. 6):
       M <- M - eta * sum_vt w (M Phi(x) - q) Phi(x)^T.

Readings of the text that it leaves open are options (Params in __init__.py), the defaults above:
- step: `plain` (as above: the text's gradient descent on eq. 6, eta = 1 / W with W the sum of
  the weights at full-size convergence) or `normalised` (the step divided by sum_vt w, eta 1.0);
- amplitude: `exact` (every row of [A, b] explores at exactly R) or `uniform` (row i of variation
  v at u_vi R, u_vi ~ U(0, 1): the disturbance "never exceeds R", eq. 8);
- updates: `batch` (one step per epoch), `steps` (update_steps steps on the epoch's samples) or
  `online` (one step per sample, in the order the samples were reached);
- solver: `gradient` (step 5) or `lstsq` (solve.py: M solved from the normal equations of
  eq. 6 over the last `window` epochs' samples, instead of step 5);
- the rate schedule (Params.rates: constant, or annealed, not the paper's) and whether successive
  path targets must differ (Params.targets) act through draw and eta, not here.
"""
from __future__ import annotations

import numpy as np

from ...features import feature_bounds, features

NO_MOVEMENT = 1e-9  # [m] intended steps shorter than this have no direction (eq. 1)


def predict(M: np.ndarray, x: np.ndarray, exps: np.ndarray) -> np.ndarray:
    """The inverse estimate g(x) = M Phi(x): commands (..., m) for positions x (..., n)."""
    return features(x, exps) @ M.T


def init_inverse(home, lo, hi, exps, init_range, rng) -> np.ndarray:
    """M (m, p): g(x) = home plus a random polynomial, |g_i(x) - home_i| <= init_range on the box.

    Paper sec. 3: "set M to zero and make some random adaptations such that g produces joint
    angles in a range of 0.1 radian around the home posture". The bound is guaranteed, not hoped
    for: sum_k |D_ik| max|Phi_k| over the box is an upper bound of the deviation, scaled to init_range.
    """
    m, p = len(home), len(exps)
    D = rng.uniform(-1.0, 1.0, size=(m, p))
    D *= init_range / (np.abs(D) @ feature_bounds(lo, hi, exps))[:, None]
    D[:, 0] += home
    return D


def scale_perturbations(raw, lo, hi, radius, amp=None):
    """Linear disturbances E^v(x) = A x + b (eq. 8) from raw draws (..., m, n + 1) = [A | b].

    Each row i is scaled so that max over the box lo <= x <= hi of |A_i x + b_i| is exactly
    `radius` (times amp[..., i] if given, amp in [0, 1]); the box holds the whole target set and
    every path between targets, and a linear function takes its maximum over the box at a corner:
    |A_i c + b_i| + sum_j |A_ij| h_j.
    """
    A, b = raw[..., :-1], raw[..., -1]
    c, h = 0.5 * (lo + hi), 0.5 * (hi - lo)
    peak = np.abs(A @ c + b) + np.abs(A) @ h
    k = radius / peak if amp is None else radius * amp / peak
    return A * k[..., None], b * k


def target_path(targets, idx, steps):
    """Eq. 9: targets[idx[0]] -> targets[idx[1]] -> ... in `steps` linear steps each.

    Returns (len(idx) - 1) * steps path targets, starting at targets[idx[0]] (l = 0 ... L-1).
    """
    tau = targets[idx]
    frac = (np.arange(steps) / steps)[None, :, None]
    path = (1.0 - frac) * tau[:-1, None, :] + frac * tau[1:, None, :]
    return path.reshape(-1, targets.shape[-1])


def sample_weights(xstar, x, q):
    """w_dir * w_eff (eq. 1-3) of every sample against its predecessor along axis -2.

    xstar, x: (..., T+1, n) intended and reached positions, q: (..., T+1, m) postures; row 0 is
    the home example and gets weight 1 (eq. 5). Degenerate cases, without NaN: an intended step
    shorter than NO_MOVEMENT has no direction to judge, and the sample is dropped (w_dir = 0);
    no hand movement gives w_eff = 0 (and cos = 0); no joint movement means no hand movement
    either, and w_eff = 0.
    """
    dxs, dx, dq = (np.diff(a, axis=-2) for a in (xstar, x, q))
    nxs, nx, nq = (np.linalg.norm(a, axis=-1) for a in (dxs, dx, dq))
    denom = nxs * nx
    cos = np.where(denom > 0, np.sum(dxs * dx, axis=-1) / np.where(denom > 0, denom, 1.0), 0.0)
    w_dir = np.where(nxs > NO_MOVEMENT, 0.5 * (1.0 + np.clip(cos, -1.0, 1.0)), 0.0)
    w_eff = np.where(nq > 0, nx / np.where(nq > 0, nq, 1.0), 0.0)
    w = np.ones(x.shape[:-1])
    w[..., 1:] = w_dir * w_eff
    return w


def rollout(M, body, scale, exps, path, A, b):
    """All variations reach along the path, home example first.

    Returns intended xstar (V, T+1, n), reached x (V, T+1, n), postures q (V, T+1, m).
    """
    V = A.shape[0]
    q_home = body.saturate(body.home)
    x_home = body.forward(q_home, scale=scale)
    q = predict(M, path, exps)[None] + path @ A.transpose(0, 2, 1) + b[:, None, :]
    q = np.concatenate([np.broadcast_to(q_home, (V, 1, body.m)), body.saturate(q)], axis=1)
    x = body.forward(q, scale=scale)
    xstar = np.concatenate([np.broadcast_to(x_home, (V, 1, body.n)),
                            np.broadcast_to(path, (V,) + path.shape)], axis=1)
    return xstar, x, q


def gradient_step(M, x, q, w, exps, learning_rate, step="plain"):
    """One gradient-descent step on the weighted command error (eq. 6), plain (step="plain") or
    normalised by sum w (step="normalised")."""
    phi = features(x, exps)
    r = phi @ M.T - q
    grad = np.einsum("vt,vti,vtk->ik", w, r, phi)
    return M - learning_rate * grad / (w.sum() if step == "normalised" else 1.0)


def update(M, x, q, w, exps, learning_rate, step="plain", updates="batch", update_steps=1):
    """The learning step of one epoch on its samples (x, q, w), by the `updates` reading."""
    if updates == "batch":
        return gradient_step(M, x, q, w, exps, learning_rate, step)
    if updates == "steps":
        for _ in range(update_steps):
            M = gradient_step(M, x, q, w, exps, learning_rate, step)
        return M
    # online: one step per sample, variation by variation, in the order they were reached
    eta = learning_rate / (w.sum() if step == "normalised" else 1.0)
    phi = features(x, exps).reshape(-1, len(exps))
    for f, qi, wi in zip(phi, q.reshape(-1, q.shape[-1]), w.reshape(-1)):
        M = M - (eta * wi) * np.outer(M @ f - qi, f)
    return M


def epoch(M, body, size, scale, exps, idx, raw, radius, steps, learning_rate, amp=None,
          step="plain", updates="batch", update_steps=1):
    """One epoch of Goal Babbling with the body at size `size` (per-joint length factors
    `scale`); returns the updated M and the samples (xstar, x, q, w)."""
    xstar, x, q, w = samples(M, body, size, scale, exps, idx, raw, radius, steps, amp)
    M = update(M, x, q, w, exps, learning_rate, step, updates, update_steps)
    return M, (xstar, x, q, w)


def samples(M, body, size, scale, exps, idx, raw, radius, steps, amp=None):
    """Steps 1-4 of an epoch: the samples (xstar, x, q, w) that M's variations collect."""
    lo, hi = body.target_box(size)
    path = target_path(body.target_set(size), idx, steps)
    A, b = scale_perturbations(raw, lo, hi, radius, amp)
    xstar, x, q = rollout(M, body, scale, exps, path, A, b)
    return xstar, x, q, sample_weights(xstar, x, q)

