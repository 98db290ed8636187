"""Online Goal Babbling in plain numpy, sample by sample: the readable statement of the learner
(gbmodel.learners.online_goal_babbling states what it computes; fast.py computes the same with
the same draws)."""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from ...features import exponents, features
from ...inverse import predict as predict_inverse, sample_weights, scale_perturbations


def plan(state, params, targets, x_home, hops, coins):
    """The epoch's intended positions x* (T, n), which of them are returns home (T,), and the
    state's target and at_home after it."""
    L = params.steps
    target, at_home, xs, home = state.target, state.at_home, [], []
    for hop, coin in zip(hops, coins):
        start = x_home if at_home else targets[target]
        target = (target + hop) % len(targets)
        frac = np.arange(1, L + 1)[:, None] / L
        xs.append(start + frac * (targets[target] - start))
        home += [False] * L
        at_home = coin < params.home_probability
        if at_home:
            xs.append(x_home[None])
            home.append(True)
    return np.concatenate(xs), np.array(home), target, at_home


def perturbations(P, walk, params, lo, hi):
    """The perturbation of every path sample: A (T, m, n), b (T, m), and P after the walk."""
    keep = 1.0 / np.sqrt(1.0 + params.drift ** 2)
    raw = np.empty_like(walk)
    for t, step in enumerate(walk):
        P = keep * (P + params.drift * step)
        raw[t] = P
    A, b = scale_perturbations(raw, lo, hi, params.radius)
    return A, b, P


def train_reference(state, params, body, sizes, scales, draws):
    """The epochs in plain numpy, sample by sample: the readable statement of `train`."""
    hops, coins, walk = draws
    exps = exponents(body.n, params.degree)
    M, P = state.M.copy(), state.P
    for e in range(len(sizes)):
        q_home = body.saturate(body.home)
        x_home = body.forward(q_home, scales[e])
        xstar, home, target, at_home = plan(state, params, body.target_set(sizes[e]), x_home,
                                            hops[e], coins[e])
        A, b, P = perturbations(P, walk[e], params, *body.target_box(sizes[e]))
        last, j = state.last, 0  # j: the next path sample's perturbation
        for xs, is_home in zip(xstar, home):
            if is_home:  # the home example, weight 1 (eq. 5)
                x, q, w = x_home, q_home, 1.0
            else:
                q = body.saturate(predict_inverse(M, xs, exps) + A[j] @ xs + b[j])
                x = body.forward(q, scales[e])
                w = sample_weights(*(np.stack([a, c]) for a, c in zip(last, (xs, x, q))))[1]
                j += 1
            phi = features(x, exps)
            M -= (params.learning_rate * w) * np.outer(M @ phi - q, phi)
            last = (xs, x, q)
        state = replace(state, M=M, P=P, target=target, at_home=at_home, last=last)
    return replace(state, M=M.copy())


