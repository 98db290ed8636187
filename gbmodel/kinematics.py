"""Forward kinematics of a serial chain, in numpy, and the chain's layout for the kernels.

A body is either a chain in standard Denavit-Hartenberg form (hand_position)
    A_i = Rz(theta_i) . Tz(d_i) . Tx(a_i) . Rx(alpha_i),   T = H0 . A_0 ... A_{m-1}
or a general chain read from a URDF (chain_position): per joint a fixed transform, then a
rotation about the local z axis. Only the hand *position* is needed, so the hand point is
carried backwards through the chain, one rotation about z per joint and no 4x4 products.
chain_layout gives both kinds as one table for the compiled kernels (gbmodel.simd).
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


def chain_position(theta: np.ndarray, frames: np.ndarray, tool: np.ndarray,
                   scale=None) -> np.ndarray:
    """Hand position (..., 3) of a general serial chain (a URDF's; gbmodel/urdf.py): per joint a
    fixed 3x4 transform F_i, then a rotation about the local z axis by theta_i, then the tool
    point: hand = F_0 Rz(theta_0) ... F_{m-1} Rz(theta_{m-1}) tool, carried backwards.

    scale (m,): per-segment length factors; segment i is the translation after joint i (the next
    transform's, or the tool's for the last joint), so growth lengthens the links and never
    changes the base's placement or any angle."""
    theta = np.asarray(theta, dtype=np.float64)
    m = theta.shape[-1]
    k = np.ones(m) if scale is None else np.asarray(scale, np.float64)
    p = np.broadcast_to(tool * k[m - 1], theta.shape[:-1] + (3,))
    for i in range(m - 1, -1, -1):
        c, s = np.cos(theta[..., i]), np.sin(theta[..., i])
        x, y, z = c * p[..., 0] - s * p[..., 1], s * p[..., 0] + c * p[..., 1], p[..., 2]
        t = frames[i][:, 3] * (k[i - 1] if i > 0 else 1.0)
        R = frames[i][:, :3]
        p = np.stack([R[r, 0] * x + R[r, 1] * y + R[r, 2] * z + t[r] for r in range(3)], axis=-1)
    return p


def chain_layout(body) -> dict:
    """The chain at full size as the compiled kernels step through it (gbmodel.simd.chain_step,
    chain_forward64): p <- Rz(theta_i) (R_i p + t_i), t_i = (a_i, ty_i, d_i) scaled by segment
    i's growth, then the base (3x4). DH rows: R_i = Rx(alpha_i) (cos_alpha, sin_alpha, the rows'
    own branch), ty = 0, general False. A general chain (a URDF's: hand = F_0 Rz(q_0) F_1 ...
    Rz(q_{m-1}) tool): the base is F_0, (R_i | t_i) is F_{i+1}, and the tool the last joint's
    translation (R = I), general True."""
    m = body.m
    if not body.general:
        ch = body.chain()
        return dict(ch, ty=np.zeros(m), R=np.zeros((m, 3, 3)), general=False)
    after = np.concatenate([body.frames[1:], np.hstack([np.eye(3), body.tool[:, None]])[None]])
    return dict(a=after[:, 0, 3], d=after[:, 2, 3], ty=after[:, 1, 3], R=after[:, :, :3],
                cos_alpha=np.ones(m), sin_alpha=np.zeros(m), base=body.frames[0], general=True)
