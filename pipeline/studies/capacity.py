"""The capacity bound (explain.py): the best degree-3 inverse for a body's target grid, fitted
directly to the forward kinematics (least squares on the reaching errors from a learned M, with
the hand's analytic Jacobian where the inverse is linear in M)."""
from __future__ import annotations

import numpy as np
from scipy.optimize import least_squares

from gbmodel.growth import factors

from .figures import final_body


def _errors(body, size, pattern, predict, M, xs):
    q = predict(M, xs)
    return np.linalg.norm(body.forward(q, factors(body, size, pattern)) - xs, axis=-1)


def best_cubic(spec: dict, M0) -> dict:
    """The inverse fitted directly to the targets (scipy least squares from M0), with _jacobian
    where it is linear in M (g(x) = M Phi(x)), else finite differences."""
    body, size, pattern, predict = final_body(spec)
    xs = body.target_set(size)
    M0 = np.asarray(M0, float)
    f = factors(body, size, pattern)

    def residuals(flat):
        q = predict(flat.reshape(M0.shape), xs)
        return (body.forward(q, f) - xs).ravel()

    Phi = _linear_features(predict, M0, xs)
    jac = "2-point" if Phi is None else (lambda flat: _jacobian(body, f, Phi, flat, M0.shape))
    fit = least_squares(residuals, M0.ravel(), jac=jac, method="trf", max_nfev=200 * M0.size)
    d = _errors(body, size, pattern, predict, fit.x.reshape(M0.shape), xs)
    learned = _errors(body, size, pattern, predict, M0, xs)
    return dict(M=fit.x.reshape(M0.shape), best_mean_mm=1e3 * d.mean(), best_worst_mm=1e3 * d.max(),
                learned_mean_mm=1e3 * learned.mean(), learned_worst_mm=1e3 * learned.max())


def _linear_features(predict, M0, xs):
    """Phi (N, p) with predict(M, xs) = Phi @ M.T (read off unit models), None where predict is
    not linear in M (checked at 0, M0 and beside it)."""
    m, p = M0.shape
    unit = np.zeros((m, p))
    if np.any(predict(unit, xs) != 0):
        return None
    cols = []
    for k in range(p):
        unit[0, k] = 1.0
        cols.append(predict(unit, xs)[:, 0])
        unit[0, k] = 0.0
    Phi = np.stack(cols, axis=1)
    linear = all(np.allclose(predict(M, xs), Phi @ M.T, rtol=1e-12, atol=1e-12)
                 for M in (M0, 0.5 * M0 + 0.25))
    return Phi if linear else None


JOINT_STEP = 1e-6  # the central differences of the forward kinematics, per joint command


def _jacobian(body, f, Phi, flat, shape):
    """d residuals / d M (N n, m p) at M = flat: hand_jacobian times dq_j / dM_jk = Phi_k."""
    q = Phi @ flat.reshape(shape).T
    J = hand_jacobian(body, f, q)
    N, m = q.shape
    return (J[:, :, :, None] * Phi[:, None, None, :]).reshape(N * J.shape[1], m * Phi.shape[1])


def hand_jacobian(body, f, q) -> np.ndarray:
    """d forward(q, f) / d q (N, n, m): analytic for a DH or general (URDF) chain, times the
    commands' scaling (zero where clipped); a body in the loop by central differences."""
    q = np.asarray(q, float)
    N, m = q.shape
    if body.loop is not None:
        step = JOINT_STEP * np.eye(m)[:, None, :]
        moved = body.forward(np.concatenate([q[None] + step, q[None] - step]).reshape(-1, m), f)
        moved = moved.reshape(2 * m, N, -1)
        return np.moveaxis((moved[:m] - moved[m:]) / (2 * JOINT_STEP), 0, -1)
    theta = body.joint_angles(q)
    scale = np.ones_like(q)
    if body.normalized:
        scale = np.broadcast_to(0.5 * (body.q_max - body.q_min), q.shape).copy()
        if body.saturates:
            scale[np.abs(q) > 1.0] = 0.0
    k = np.ones(m) if f is None else np.asarray(f, float)
    D = (_chain_jacobian(theta, body.frames, body.tool, k) if body.general
         else _dh_jacobian(theta, **body.chain(k)))
    return D[:, list(body.outputs), :] * scale[:, None, :]


def _dh_jacobian(theta, a, d, cos_alpha, sin_alpha, base) -> np.ndarray:
    """d hand / d theta (N, 3, m) of gbmodel.kinematics.hand_position: its backward pass
    p <- Rz(theta_i) (Rx(alpha_i) p + (a_i, 0, d_i)) with the derivative D (N, 3, m) carried
    along (D <- Rz Rx D), and d/dtheta_i of the new point = (-p_y, p_x, 0)."""
    N, m = theta.shape
    p, D = np.zeros((N, 3)), np.zeros((N, 3, m))
    for i in range(m - 1, -1, -1):
        ca, sa = cos_alpha[i], sin_alpha[i]
        u = p[:, 0] + a[i]
        v = ca * p[:, 1] - sa * p[:, 2]
        w = sa * p[:, 1] + ca * p[:, 2] + d[i]
        du, dv, dw = D[:, 0], ca * D[:, 1] - sa * D[:, 2], sa * D[:, 1] + ca * D[:, 2]
        c, s = np.cos(theta[:, i]), np.sin(theta[:, i])
        p = np.stack([c * u - s * v, s * u + c * v, w], axis=1)
        D = np.stack([c[:, None] * du - s[:, None] * dv, s[:, None] * du + c[:, None] * dv, dw],
                     axis=1)
        D[:, 0, i], D[:, 1, i] = -p[:, 1], p[:, 0]
    return np.einsum("rc,ncm->nrm", base[:, :3], D)


def _chain_jacobian(theta, frames, tool, k) -> np.ndarray:
    """d hand / d theta (N, 3, m) of gbmodel.kinematics.chain_position: its backward pass
    p <- F_i Rz(theta_i) p with the derivative carried along (D <- R_i Rz D), and d/dtheta_i
    of the rotated point = (-y, x, 0)."""
    N, m = theta.shape
    p, D = np.broadcast_to(tool * k[m - 1], (N, 3)), np.zeros((N, 3, m))
    for i in range(m - 1, -1, -1):
        c, s = np.cos(theta[:, i]), np.sin(theta[:, i])
        x, y = c * p[:, 0] - s * p[:, 1], s * p[:, 0] + c * p[:, 1]
        dx = c[:, None] * D[:, 0] - s[:, None] * D[:, 1]
        dy = s[:, None] * D[:, 0] + c[:, None] * D[:, 1]
        dx[:, i], dy[:, i] = -y, x
        R, t = frames[i][:, :3], frames[i][:, 3] * (k[i - 1] if i > 0 else 1.0)
        p = np.stack([x, y, p[:, 2]], axis=1) @ R.T + t
        D = np.einsum("rc,ncm->nrm", R, np.stack([dx, dy, D[:, 2]], axis=1))
    return D


def _extremes(spec, M) -> float:
    body, size, pattern, predict = final_body(spec)
    d = _errors(body, size, pattern, predict, np.asarray(M, float), body.target_set(size))
    return 1e3 * float(max(d[0], d[-1]))
