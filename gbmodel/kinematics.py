"""Forward kinematics of a serial chain in standard Denavit-Hartenberg form, written once.

Every body of the project (the planar arms included) is a DH chain
    A_i = Rz(theta_i) . Tz(d_i) . Tx(a_i) . Rx(alpha_i),   T = H0 . A_0 ... A_{m-1}
and only the hand *position* is needed, so the hand point is carried backwards through the
chain, p <- A_i p, which costs one rotation about z per joint and no 4x4 products.
"""
from __future__ import annotations

import numpy as np


def hand_position(
    theta: np.ndarray,
    a: np.ndarray,
    d: np.ndarray,
    cos_alpha: np.ndarray,
    sin_alpha: np.ndarray,
    base: np.ndarray,
) -> np.ndarray:
    """Hand position (..., 3) in the root frame for joint angles theta (..., m) in radians.

    base is the 3x4 upper part of the root transform H0.
    """
    theta = np.asarray(theta, dtype=np.float64)
    px = np.zeros(theta.shape[:-1])
    py = np.zeros_like(px)
    pz = np.zeros_like(px)
    for i in range(theta.shape[-1] - 1, -1, -1):
        u = px + a[i]
        v = cos_alpha[i] * py - sin_alpha[i] * pz
        w = sin_alpha[i] * py + cos_alpha[i] * pz + d[i]
        c, s = np.cos(theta[..., i]), np.sin(theta[..., i])
        px, py, pz = c * u - s * v, s * u + c * v, w
    p = np.stack([px, py, pz], axis=-1)
    return p @ base[:, :3].T + base[:, 3]
