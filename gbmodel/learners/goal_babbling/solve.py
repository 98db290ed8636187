"""M solved from eq. 6's weighted normal equations (learner.solver=lstsq; the paper: "any
regression algorithm can be used for this step"), over the last `window` epochs' samples:

    min_M  sum_{e in window} sum_t w_t |M Phi(x_t) - q_t|^2  +  ridge sum_k G_kk |M_:k - Mc_:k|^2
           +  a W mean_{x* in targets} |(M - M0) Phi(x*)|^2
           +  l W mean_{x* in targets} |M Phi(x*) - clip(Mc Phi(x*))|^2

with Mc the M before the solve, M0 the initial M, W the window's sum of weights, a the anchor
(anchor_at) and l the limit pull (0 without joint limits). Each epoch's Gram sums G_e = sum_t
w Phi Phi^T and H_e = sum_t w q Phi^T fill a slot of a ring of `window`; the solve sums the
slots in slot order and solves (G + D + (a + l) W P) M^T = H^T + D Mc^T + a W P M0^T + l W PC,
D = ridge diag(G) (1 where G_kk = 0), P = target_gram, PC = limit_gram. Ridge and anchor are
relative to the data, so neither depends on the body's units or sample count. Why the anchor
and the pull: docs/bodies.md, "The exact solver". lstsq.py computes the same in the kernel.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...features import features


@dataclass(frozen=True)
class Solved:
    """The state under solver=lstsq: ring (window, p + m, p) of [G_e; H_e], the next slot
    epochs % window, M0 the initial M."""
    M: np.ndarray
    ring: np.ndarray
    epochs: int = 0
    M0: np.ndarray | None = None


def start(M: np.ndarray, window: int) -> Solved:
    m, p = M.shape
    M = np.array(M, dtype=np.float64)
    return Solved(M, np.zeros((window, p + m, p)), 0, M.copy())


def grams(x, q, w, exps) -> np.ndarray:
    """[G; H] (p + m, p) of one epoch's samples x (..., n), q (..., m), w (...)."""
    phi = features(x, exps).reshape(-1, len(exps))
    q, w = q.reshape(len(phi), -1), w.reshape(-1)
    wphi = w[:, None] * phi
    return np.concatenate([wphi.T @ phi, (w[:, None] * q).T @ phi])


def target_gram(targets, exps) -> np.ndarray:
    """P = mean over the targets of Phi(x*) Phi(x*)^T (p x p)."""
    phi = features(targets, exps)
    return phi.T @ phi / len(phi)


def limit_gram(targets, exps, M, clip: bool) -> np.ndarray:
    """PC = mean over the targets of Phi(x*) c(x*)^T, c = M Phi(x*) (clipped where `clip`)."""
    phi = features(targets, exps)
    c = phi @ M.T
    if clip:
        c = np.clip(c, -1.0, 1.0)
    return phi.T @ c / len(phi)


def system(M, total, ridge, P=None, M0=None, anchor=0.0, PC=None, limit=0.0):
    """(A, B) of A M^T = B for the summed Gram sums `total`: the ridge towards M, with P the
    anchor towards M0 and with PC the limit pull, both times the weight sum G_00."""
    p = total.shape[1]
    G, H = total[:p], total[p:]
    diag = np.diag(G)
    D = np.where(diag > 0, ridge * diag, 1.0)
    A, B = G + np.diag(D), H.T + D[:, None] * M.T
    if P is None:
        return A, B
    la, lc = anchor * G[0, 0], limit * G[0, 0]
    A, B = A + la * P, B + la * (P @ M0.T)
    if PC is None:
        return A, B
    return A + lc * P, B + lc * PC


def anchor_at(anchor, anchor_epochs, epoch, body) -> float:
    """anchor, decaying as tau / (tau + epoch - 1) on a body with limits (they hold the
    joints; the anchor keeps only the first solves within them)."""
    if not body.limited:
        return anchor
    return anchor * anchor_epochs / (anchor_epochs + epoch - 1)


def solve(state: Solved, slot_grams: np.ndarray, ridge: float, P=None, anchor=0.0, PC=None,
          limit=0.0) -> Solved:
    """The state after an epoch whose Gram sums are slot_grams."""
    window = len(state.ring)
    ring = state.ring.copy()
    ring[state.epochs % window] = slot_grams
    total = ring[0].copy()
    for k in range(1, window):
        total += ring[k]
    A, B = system(state.M, total, ridge, P, state.M0, anchor, PC, limit)
    return Solved(np.linalg.solve(A, B).T, ring, state.epochs + 1, state.M0)


def cholesky_solve(A, B, L, out):
    """out = A^-1 B by A's Cholesky factor L: plain loops in a fixed order (compiled by
    lstsq.py, the same bits on every CPU)."""
    p, r = B.shape
    for j in range(p):
        s = A[j, j]
        for k in range(j):
            s -= L[j, k] * L[j, k]
        # a pivot lost to rounding (A nearly singular, its Gram sums from float32 lanes): the
        # smallest positive one instead of a square root of a negative number
        L[j, j] = np.sqrt(max(s, 1e-12 * A[j, j]))
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
