"""M solved from the weighted normal equations of eq. 6 (learner.solver=lstsq), plain numpy.

The paper updates M by a gradient step on the weighted command error (eq. 6) and notes that
"any regression algorithm can be used for this step (e.g. linear regression schemes)". Here M
minimises that error exactly over the samples of the last `window` epochs:

    min_M  sum_{e in window} sum_t w_t |M Phi(x_t) - q_t|^2  +  ridge sum_k G_kk |M_:k - M0_:k|^2

with M0 the M before the solve. Each epoch contributes its Gram sums G_e = sum_t w Phi Phi^T
(p x p) and H_e = sum_t w q Phi^T (m x p), the home example (weight 1, eq. 5) included, as a
slot of a ring of `window` slots (the oldest is overwritten); the solve sums the slots in slot
order and solves (G + D) M^T = H^T + D M0^T, D = ridge diag(G) (1 where a feature never varies,
G_kk = 0: its column keeps M0's). The ridge is relative to each feature's own scale, so it does
not depend on the body's units; it pulls towards the current M, not towards zero.

The fast path (fast.py) accumulates G_e and H_e in the kernel and solves the same p x p system
by `cholesky_solve` below, compiled; this module states it with numpy's solver.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...features import features


@dataclass(frozen=True)
class Solved:
    """The state under solver=lstsq: M and the ring of per-epoch Gram sums.

    ring (window, p + m, p): rows 0 ... p-1 of a slot are G_e, rows p ... p+m-1 are H_e;
    epochs: the epochs learned so far (the next slot is epochs % window)."""
    M: np.ndarray
    ring: np.ndarray
    epochs: int = 0


def start(M: np.ndarray, window: int) -> Solved:
    m, p = M.shape
    return Solved(np.array(M, dtype=np.float64), np.zeros((window, p + m, p)), 0)


def grams(x, q, w, exps) -> np.ndarray:
    """[G; H] (p + m, p) of one epoch's samples x (..., n), q (..., m), w (...)."""
    phi = features(x, exps).reshape(-1, len(exps))
    q, w = q.reshape(len(phi), -1), w.reshape(-1)
    wphi = w[:, None] * phi
    return np.concatenate([wphi.T @ phi, (w[:, None] * q).T @ phi])


def system(M, total, ridge):
    """The p x p system (A, B) of A M^T = B for the summed Gram sums `total` (p + m, p)."""
    p = total.shape[1]
    G, H = total[:p], total[p:]
    diag = np.diag(G)
    D = np.where(diag > 0, ridge * diag, 1.0)
    return G + np.diag(D), H.T + D[:, None] * M.T


def solve(state: Solved, slot_grams: np.ndarray, ridge: float) -> Solved:
    """The state after one epoch whose Gram sums are slot_grams: the slot stored, M solved."""
    window = len(state.ring)
    ring = state.ring.copy()
    ring[state.epochs % window] = slot_grams
    total = ring[0].copy()
    for k in range(1, window):
        total += ring[k]
    A, B = system(state.M, total, ridge)
    return Solved(np.linalg.solve(A, B).T, ring, state.epochs + 1)


def cholesky_solve(A, B, L, out):
    """out = A^-1 B by the Cholesky factor L of A (A symmetric positive definite; plain loops in
    a fixed order, compiled by fast.py so that every CPU computes the same bits)."""
    p, r = B.shape
    for j in range(p):
        s = A[j, j]
        for k in range(j):
            s -= L[j, k] * L[j, k]
        L[j, j] = np.sqrt(s)
        for i in range(j + 1, p):
            s = A[i, j]
            for k in range(j):
                s -= L[i, k] * L[j, k]
            L[i, j] = s / L[j, j]
    for c in range(r):
        for i in range(p):  # L y = b
            s = B[i, c]
            for k in range(i):
                s -= L[i, k] * out[k, c]
            out[i, c] = s / L[i, i]
        for i in range(p - 1, -1, -1):  # L^T x = y
            s = out[i, c]
            for k in range(i + 1, p):
                s -= L[k, i] * out[k, c]
            out[i, c] = s / L[i, i]
