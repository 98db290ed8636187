"""Forward kinematics in numpy, DH rows (A_i = Rz(theta_i) Tz(d_i) Tx(a_i) Rx(alpha_i)) or a
general chain, the hand point carried backwards (no 4x4 products); chain_layout gives both as
one table for the kernels.
"""
from __future__ import annotations

import numpy as np


def hand_position(theta, a, d, cos_alpha, sin_alpha, base) -> np.ndarray:
    """Hand position (..., 3) for joint angles theta (..., m) [rad]; base: H0's 3x4 part."""
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
    """Hand position (..., 3) of F_0 Rz(theta_0) ... F_{m-1} Rz(theta_{m-1}) tool; scale (m,)
    multiplies segment i, the translation after joint i (never the base or an angle)."""
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


_KERNEL: dict = {}  # (id(body), key) -> (body, arrays); the body kept so its id stays its own


def kernel_arrays(body, key, build):
    """build(), once per body object (bodies are frozen) and key: a trial asks ~100 times."""
    hit = _KERNEL.get((id(body), key))
    if hit is None or hit[0] is not body:
        if len(_KERNEL) >= 64:
            _KERNEL.clear()
        hit = _KERNEL[id(body), key] = (body, build())
    return hit[1]


def chain_layout(body) -> dict:
    """The full-size chain as the kernels step through it: p <- Rz(theta_i) (R_i p + t_i), t_i
    = (a_i, ty_i, d_i) scaled, then the base. DH rows: R_i = Rx(alpha_i), ty = 0; a general
    chain: base F_0, (R_i | t_i) = F_i+1, the tool last (R = I)."""
    m = body.m
    if not body.general:
        ch = body.chain()
        return dict(ch, ty=np.zeros(m), R=np.zeros((m, 3, 3)), general=False)
    after = np.concatenate([body.frames[1:], np.hstack([np.eye(3), body.tool[:, None]])[None]])
    return dict(a=after[:, 0, 3], d=after[:, 2, 3], ty=after[:, 1, 3], R=after[:, :, :3],
                cos_alpha=np.ones(m), sin_alpha=np.zeros(m), base=body.frames[0], general=True)


def kernel_body(body, dtype) -> tuple:
    """(chain, joints) as the kernels take them in `dtype`: chain_layout's table, and the
    commands' mapping (normalized, saturates, q_min, q_span, theta_offset)."""
    f = lambda x: np.ascontiguousarray(x, dtype)  # noqa: E731
    ch, norm = chain_layout(body), body.normalized
    chain = tuple(f(ch[k]) for k in ("a", "d", "cos_alpha", "sin_alpha", "base")) + (
        np.array(body.outputs, np.int64), f(ch["ty"]), f(ch["R"]), bool(ch["general"]))
    joints = (norm, bool(body.saturates), f(body.q_min if norm else np.zeros(body.m)),
              f(body.q_max - body.q_min if norm else np.ones(body.m)), f(body.theta_offset))
    return chain, joints
