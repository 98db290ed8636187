"""A body: its full-size chain (DH rows, a URDF's or MJCF's frames, or a Python forward function),
limits, home, targets and growing segments; growth is per-segment length factors. Commands q are
joint angles [rad], or normalised (the iCub, sec. 3.3): [-1, 1] onto the joint's limits,
saturating beyond as its position controller does; the example learned from is the posture
taken (the saturated one), the only one whose outcome was observed.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .kinematics import chain_position, hand_position
from .urdf import MAX_MAGNITUDE


@dataclass(frozen=True)
class Body:
    name: str
    a: np.ndarray  # (m,) DH link lengths at full size [m]
    d: np.ndarray  # (m,) DH link offsets at full size [m]
    alpha: np.ndarray  # (m,) DH link twists [rad]
    theta_offset: np.ndarray  # (m,) added to every joint angle [rad]
    base: np.ndarray  # (3, 4) root transform H0 (rotation | translation)
    outputs: tuple  # which hand coordinates are controlled (n of x, y, z)
    home: np.ndarray  # (m,) home posture, in command units
    targets: np.ndarray  # (N, n) target set at full size [m]
    growing: np.ndarray  # (m,) bool: segments that grow under non-proportional growth
    q_min: np.ndarray | None = None  # (m,) joint limits [rad] of normalised commands
    q_max: np.ndarray | None = None
    saturates: bool = True  # normalised commands are clipped to [-1, 1] (False: limits ignored)
    description: str = ""
    # or a general chain (gbmodel/urdf.py): per joint a fixed 3x4 transform, then Rz; the tool
    frames: np.ndarray | None = None  # (m, 3, 4)
    tool: np.ndarray | None = None  # (3,)
    # or a body in the loop (gbmodel/body_loop.py) and its segments' lengths
    loop: Any = None  # body_loop.Forward
    lengths: np.ndarray | None = None  # (m,)
    _cos_alpha: np.ndarray = field(init=False, repr=False)
    _sin_alpha: np.ndarray = field(init=False, repr=False)

    def __post_init__(self):
        object.__setattr__(self, "_cos_alpha", np.round(np.cos(self.alpha), 15))
        object.__setattr__(self, "_sin_alpha", np.round(np.sin(self.alpha), 15))

    @property
    def m(self) -> int:
        return len(self.a)

    @property
    def general(self) -> bool:
        return self.frames is not None

    @property
    def segment_lengths(self) -> np.ndarray:
        """Full length of each segment (m,), what growth scales: hypot(a_i, d_i), or the
        translation after joint i, or `callable.lengths`."""
        if self.loop is not None:
            return self.lengths
        if not self.general:
            return np.hypot(self.a, self.d)
        after = np.vstack([self.frames[1:, :, 3], self.tool[None]])
        return np.linalg.norm(after, axis=1)

    @property
    def n(self) -> int:
        return len(self.outputs)

    @property
    def normalized(self) -> bool:
        return self.q_min is not None

    @property
    def limited(self) -> bool:
        """A command stops at the joint limits (normalised and saturating)."""
        return self.normalized and self.saturates

    # ---- commands -> joint angles ------------------------------------------------------------
    def saturate(self, q: np.ndarray) -> np.ndarray:
        if self.limited:
            return np.clip(q, -1.0, 1.0)
        return np.asarray(q, dtype=np.float64)

    def joint_angles(self, q: np.ndarray) -> np.ndarray:
        q = self.saturate(q)
        if self.normalized:
            q = self.q_min + 0.5 * (q + 1.0) * (self.q_max - self.q_min)
        return q + self.theta_offset

    # ---- kinematics ------------------------------------------------------------------------------
    def _factors(self, factors) -> np.ndarray:
        return np.ones(self.m) if factors is None else np.asarray(factors, np.float64)

    def chain(self, factors=None) -> dict:
        """The DH chain (a, d, cos/sin alpha, base) at length factors `factors`."""
        if self.loop is not None:
            raise ValueError(f"body {self.name!r} is a body in the loop (a Python forward "
                             "function): only the numpy reference path takes it "
                             "(learner.fast=false)")
        if self.general:
            raise ValueError(f"body {self.name!r} is a general (URDF) chain, not DH rows: this "
                             "learner or kernel takes DH chains only so far")
        k = self._factors(factors)
        return dict(
            a=self.a * k, d=self.d * k, cos_alpha=self._cos_alpha, sin_alpha=self._sin_alpha,
            base=self.base,
        )

    def forward(self, q: np.ndarray, factors=None) -> np.ndarray:
        """Hand positions (..., n) [m] for commands q (..., m) at length factors `factors` (None:
        full size; gbmodel.growth.factors gives them)."""
        q = np.asarray(q, dtype=np.float64)
        if q.shape[-1] != self.m:
            raise ValueError(f"{self.name} takes {self.m} joint commands, got shape {q.shape}")
        if self.loop is not None:
            from .body_loop import positions
            p = positions(self.loop, self.joint_angles(q), self._factors(factors), self.name)
        elif self.general:
            p = chain_position(self.joint_angles(q), self.frames, self.tool,
                               self._factors(factors))
        else:
            p = hand_position(self.joint_angles(q), **self.chain(factors))
        return p[..., list(self.outputs)]

    def frame_points(self, q: np.ndarray, factors=None) -> np.ndarray:
        """Root-frame points (m + 1, 3), every joint's origin then the hand, for drawing (a body
        in the loop: the hand only)."""
        theta = self.joint_angles(np.asarray(q, float))
        k = self._factors(factors)
        if self.loop is not None:
            from .body_loop import positions
            return positions(self.loop, theta[None], k, self.name)
        if self.general:
            joints = [chain_position(theta[:j], self.frames[:j], self.frames[j][:, 3], k[:j])
                      for j in range(1, self.m)]
            return np.stack([self.frames[0][:, 3], *joints,
                             chain_position(theta, self.frames, self.tool, k)])
        ch = self.chain(k)
        return np.stack([hand_position(theta[:j], ch["a"][:j], ch["d"][:j], ch["cos_alpha"][:j],
                                       ch["sin_alpha"][:j], ch["base"])
                         for j in range(self.m + 1)])

    def target_set(self, size: float = 1.0) -> np.ndarray:
        return self.targets * size

    def target_box(self, size: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
        t = self.target_set(size)
        return t.min(axis=0), t.max(axis=0)


def _grid(*axes) -> np.ndarray:
    mesh = np.meshgrid(*axes, indexing="ij")
    return np.stack([g.ravel() for g in mesh], axis=-1)


MAX_GRID_POINTS = 4096  # targets of one grid (64 x 64, 16 x 16 x 16): memory grows with them


def grid_points(lo, hi, num) -> np.ndarray:
    """The regular target grid (prod num, n), num[j] >= 2 points from lo[j] to hi[j]."""
    if not len(lo) == len(hi) == len(num):
        raise ValueError(f"grid: lo, hi and num need one entry per axis, got {lo}, {hi}, {num}")
    if any(isinstance(k, bool) or not isinstance(k, (int, np.integer)) or k < 2 for k in num):
        raise ValueError(f"grid: need num >= 2 (an integer) per axis, got {num}")
    if math.prod(int(k) for k in num) > MAX_GRID_POINTS:
        raise ValueError(f"grid: {math.prod(int(k) for k in num):,} points; at most "
                         f"{MAX_GRID_POINTS:,}")
    bounds = np.asarray([lo, hi], dtype=np.float64)
    if not np.all(np.abs(bounds) <= MAX_MAGNITUDE) or any(h <= l for l, h in zip(lo, hi)):
        raise ValueError(f"grid: need finite lo < hi within +-{MAX_MAGNITUDE:g} m per axis, got "
                         f"{lo}, {hi}")
    return _grid(*(np.linspace(l, h, int(k)) for l, h, k in zip(lo, hi, num)))


def cell_centres(targets: np.ndarray) -> np.ndarray:
    axes = [np.unique(targets[:, j]) for j in range(targets.shape[1])]
    return _grid(*[0.5 * (a[1:] + a[:-1]) if len(a) > 1 else a for a in axes])


def unreachable(body: Body, rng: np.random.Generator, size: float = 1.0, samples: int = 4000,
                steps: int = 30, tol: float = 1e-3, starts: int = 6) -> np.ndarray:
    """Indices of the targets at `size` no posture within the limits reaches to `tol` m: damped
    Gauss-Newton from the `starts` nearest of `samples` random postures (one start gets stuck at
    a limit on 7-DOF arms; six miss nothing on tests/new_robots.py's). A local search: callers
    warn, never refuse."""
    targets, k = body.target_set(size), np.full(body.m, float(size))  # proportional at `size`
    box = 1.0 if body.normalized else np.pi
    Q = rng.uniform(-box, box, size=(samples, body.m))
    X = body.forward(Q, k)
    nearest = np.argsort(((targets[:, None, :] - X[None]) ** 2).sum(-1), axis=1)[:, :starts]
    q = Q[nearest].reshape(-1, body.m)  # (targets x starts, m)
    goal = np.repeat(targets, nearest.shape[1], axis=0)
    eye, h = 1e-4 * np.eye(body.m), 1e-6
    for _ in range(steps):
        x = body.forward(q, k)
        J = np.stack([(body.forward(q + h * e, k) - x) / h for e in np.eye(body.m)], axis=-1)
        JT = J.transpose(0, 2, 1)
        dq = np.linalg.solve(JT @ J + eye, JT @ (goal - x)[..., None])[..., 0]
        q = np.clip(q + dq, -box, box) if body.limited else q + dq
    miss = np.linalg.norm(body.forward(q, k) - goal, axis=-1).reshape(len(targets), -1).min(1)
    return np.flatnonzero(miss > tol)
