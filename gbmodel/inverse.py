"""The polynomial inverse estimate and Goal Babbling's sample weights, shared by the learners.

g(x) = M Phi(x) (eq. 7) with its initialisation around the home posture (sec. 3), the linear
exploratory perturbations scaled to a radius over the target box (eq. 8), and the weights of a
sample against its predecessor (eq. 1-3). Goal Babbling, online Goal Babbling and motor babbling
use them; gbmodel.learners.goal_babbling.reference states the batch epoch built from them.
"""
from __future__ import annotations

import numpy as np

from .features import feature_bounds, features

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
