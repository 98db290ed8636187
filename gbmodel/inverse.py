"""Shared by the learners: the polynomial inverse g(x) = M Phi(x) (eq. 7), its initialisation
(sec. 3), the perturbations (eq. 8) and the sample weights (eq. 1-3)."""
from __future__ import annotations

import numpy as np

from functools import lru_cache

from .features import exponents, feature_bounds, features

NO_MOVEMENT = 1e-9  # [m] intended steps shorter than this have no direction (eq. 1)


def predict(M: np.ndarray, x: np.ndarray, exps: np.ndarray) -> np.ndarray:
    return features(x, exps) @ M.T


@lru_cache(maxsize=64)
def _table(n: int, degree: int) -> np.ndarray:
    exps = exponents(n, degree)
    exps.setflags(write=False)
    return exps


def table(params, body) -> np.ndarray:
    """features.exponents(body.n, params.degree), built once (a trial asks ~200 times)."""
    return _table(body.n, params.degree)


def predict_model(model, params, body, x) -> np.ndarray:
    """A learner's predict from what its `model(state)` stored (M; its params.degree)."""
    return predict(np.asarray(model, np.float64), x, table(params, body))


def predict_state(state, params, body, x) -> np.ndarray:
    """A learner's predict, its state holding M."""
    return predict(state.M, x, table(params, body))


def model_of(state) -> np.ndarray:
    """A learner's model, its state holding M: a copy of M."""
    return np.array(state.M, copy=True)


def init_inverse(home, lo, hi, exps, init_range, rng) -> np.ndarray:
    """M (m, p): home plus a random polynomial within init_range on the box (sec. 3), bounded
    for sure: sum_k |D_ik| max |Phi_k| is scaled to init_range."""
    m, p = len(home), len(exps)
    D = rng.uniform(-1.0, 1.0, size=(m, p))
    D *= init_range / (np.abs(D) @ feature_bounds(lo, hi, exps))[:, None]
    D[:, 0] += home
    return D


def scale_perturbations(raw, lo, hi, radius, amp=None):
    """Eq. 8: A, b from raw [A | b], each row scaled so that its max over the box, |A_i c + b_i|
    + sum_j |A_ij| h_j (at a corner), is radius (times amp)."""
    A, b = raw[..., :-1], raw[..., -1]
    c, h = 0.5 * (lo + hi), 0.5 * (hi - lo)
    peak = np.abs(A @ c + b) + np.abs(A) @ h
    k = radius / peak if amp is None else radius * amp / peak
    return A * k[..., None], b * k


def sample_weights(xstar, x, q):
    """w_dir * w_eff (eq. 1-3) of every sample against its predecessor along axis -2, row 0
    (home) 1 (eq. 5); without NaN: a step shorter than NO_MOVEMENT, or no movement, weighs 0."""
    dxs, dx, dq = (np.diff(a, axis=-2) for a in (xstar, x, q))
    nxs, nx, nq = (np.linalg.norm(a, axis=-1) for a in (dxs, dx, dq))
    denom = nxs * nx
    cos = np.where(denom > 0, np.sum(dxs * dx, axis=-1) / np.where(denom > 0, denom, 1.0), 0.0)
    w_dir = np.where(nxs > NO_MOVEMENT, 0.5 * (1.0 + np.clip(cos, -1.0, 1.0)), 0.0)
    w_eff = np.where(nq > 0, nx / np.where(nq > 0, nq, 1.0), 0.0)
    w = np.ones(x.shape[:-1])
    w[..., 1:] = w_dir * w_eff
    return w
