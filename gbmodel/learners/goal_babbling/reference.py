"""Goal Babbling (paper sec. 2.2 and 3) in plain numpy, the readable statement; fast.py computes
the same epoch compiled. One epoch:

1. a target path: K + 1 targets drawn from the target set (at the body's current size), joined by
   L linear steps (eq. 9), T = K * L path targets x*_t;
2. V variations g^v(x) = g(x) + A_v x + b_v (eq. 4, 8), each row scaled so that
   max |e_i| over the target set is exactly R;
3. each variation reaches for the path: q_t = g^v(x*_t) (saturated), x_t = f(q_t); the home example
   (x_home, q_home) is prepended as t = 0 with weight 1 (eq. 5) and is where the movement starts;
4. weights w_t = w_dir * w_eff (eq. 1-3) from the movement between samples t-1 and t;
5. one gradient step on the weighted command error (eq. 6):
       M <- M - eta * sum_vt w (M Phi(x) - q) Phi(x)^T.

Readings the text leaves open are options of Params; the defaults are the above.
"""
from __future__ import annotations

import numpy as np

from ...features import features
from ...inverse import (  # noqa: F401 (the statement of an epoch names them here too)
    NO_MOVEMENT, init_inverse, predict, sample_weights, scale_perturbations,
)


def target_path(targets, idx, steps):
    """Eq. 9: (len(idx) - 1) steps path targets, targets[idx[0]] -> targets[idx[1]] -> ..."""
    tau = targets[idx]
    frac = (np.arange(steps) / steps)[None, :, None]
    path = (1.0 - frac) * tau[:-1, None, :] + frac * tau[1:, None, :]
    return path.reshape(-1, targets.shape[-1])


def rollout(M, body, scale, exps, path, A, b):
    """All variations along the path, home first: xstar, x (V, T+1, n), q (V, T+1, m)."""
    V = A.shape[0]
    q_home = body.saturate(body.home)
    x_home = body.forward(q_home, scale)
    q = predict(M, path, exps)[None] + path @ A.transpose(0, 2, 1) + b[:, None, :]
    q = np.concatenate([np.broadcast_to(q_home, (V, 1, body.m)), body.saturate(q)], axis=1)
    x = body.forward(q, scale)
    xstar = np.concatenate([np.broadcast_to(x_home, (V, 1, body.n)),
                            np.broadcast_to(path, (V,) + path.shape)], axis=1)
    return xstar, x, q


def gradient_step(M, x, q, w, exps, learning_rate, step="plain"):
    """One gradient step on eq. 6, plain or normalised by sum w."""
    phi = features(x, exps)
    r = phi @ M.T - q
    grad = np.einsum("vt,vti,vtk->ik", w, r, phi)
    return M - learning_rate * grad / (w.sum() if step == "normalised" else 1.0)


def update(M, x, q, w, exps, learning_rate, step="plain", updates="batch", update_steps=1):
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
    """One epoch: the updated M and the samples (xstar, x, q, w)."""
    xstar, x, q, w = samples(M, body, size, scale, exps, idx, raw, radius, steps, amp)
    M = update(M, x, q, w, exps, learning_rate, step, updates, update_steps)
    return M, (xstar, x, q, w)


def samples(M, body, size, scale, exps, idx, raw, radius, steps, amp=None):
    lo, hi = body.target_box(size)
    path = target_path(body.target_set(size), idx, steps)
    A, b = scale_perturbations(raw, lo, hi, radius, amp)
    xstar, x, q = rollout(M, body, scale, exps, path, A, b)
    return xstar, x, q, sample_weights(xstar, x, q)

