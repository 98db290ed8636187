"""The bodies of the paper, each a short description over the shared DH kinematics.

A body knows its full-size chain, its joint limits, its home posture, its target set and which
segments grow. Growth is a new description (scaled lengths), never new kinematics code.

Commands q are what the inverse estimate outputs. For the planar arms they are joint angles in
radians. For the iCub they are normalised (paper sec. 3.3): q_i in [-1, 1] maps linearly onto
[min_i, max_i] of the joint's limits, and a command outside [-1, 1] saturates at the limit, as
the real robot's position controller does. The example learned from is the posture actually
taken (the saturated one): that is the only posture whose outcome was observed.
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from .kinematics import hand_position

GROWTH_PATTERNS = ("proportional", "nonproportional")


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
    _cos_alpha: np.ndarray = field(init=False, repr=False)
    _sin_alpha: np.ndarray = field(init=False, repr=False)

    def __post_init__(self):
        object.__setattr__(self, "_cos_alpha", np.round(np.cos(self.alpha), 15))
        object.__setattr__(self, "_sin_alpha", np.round(np.sin(self.alpha), 15))

    @property
    def m(self) -> int:
        return len(self.a)

    @property
    def n(self) -> int:
        return len(self.outputs)

    @property
    def normalized(self) -> bool:
        return self.q_min is not None

    # ---- commands -> joint angles ------------------------------------------------------------
    def saturate(self, q: np.ndarray) -> np.ndarray:
        """The posture actually taken for command q (clipped to [-1, 1] when normalised)."""
        if self.normalized and self.saturates:
            return np.clip(q, -1.0, 1.0)
        return np.asarray(q, dtype=np.float64)

    def joint_angles(self, q: np.ndarray) -> np.ndarray:
        """DH joint angles [rad] for (saturated) commands q."""
        q = self.saturate(q)
        if self.normalized:
            q = self.q_min + 0.5 * (q + 1.0) * (self.q_max - self.q_min)
        return q + self.theta_offset

    # ---- growth ----------------------------------------------------------------------------------
    def segment_scale(self, size, pattern: str = "proportional", fixed: float = 1.0) -> np.ndarray:
        """Per-joint length factors (..., m) when the body has `size` (scalar or array) times
        its full total length.

        proportional: every length times size. nonproportional: the non-growing segments stay at
        `fixed` times their full length (1.0: the full-size body is the common end of every
        size; 0.5: the half-size body is the common start), the growing ones change by the
        common factor that makes the total length size * full total.
        """
        size = np.asarray(size, dtype=np.float64)[..., None]
        if pattern == "proportional":
            return np.broadcast_to(size, size.shape[:-1] + (self.m,)).copy()
        if pattern != "nonproportional":
            raise ValueError(f"unknown growth pattern {pattern!r}; choose proportional or "
                             "nonproportional")
        seg = np.hypot(self.a, self.d)
        grow, held = seg[self.growing].sum(), fixed * seg[~self.growing].sum()
        if grow <= 0:
            raise ValueError(f"body {self.name!r} has no growing segment")
        gamma = (size * seg.sum() - held) / grow
        if np.any(gamma <= 0):
            raise ValueError(
                f"size {size.min()} is too small for non-proportional growth of {self.name!r}: "
                f"the fixed segments alone are {held / seg.sum():.2f} of the full length"
            )
        return np.where(self.growing, gamma, fixed)

    def chain(self, size: float = 1.0, pattern: str = "proportional", scale=None) -> dict:
        """Arrays describing the chain at a given size (or per-joint length factors `scale`):
        a, d, cos/sin alpha, base."""
        k = self.segment_scale(size, pattern) if scale is None else np.asarray(scale, np.float64)
        return dict(
            a=self.a * k, d=self.d * k, cos_alpha=self._cos_alpha, sin_alpha=self._sin_alpha,
            base=self.base,
        )

    def forward(self, q: np.ndarray, size: float = 1.0, pattern: str = "proportional",
                scale=None) -> np.ndarray:
        """Hand position (n,) or (N, n) [m] for commands q of shape (m,) or (N, m), with the
        body at `size` grown by `pattern`, or with per-joint length factors `scale` (m,)."""
        q = np.asarray(q, dtype=np.float64)
        if q.shape[-1] != self.m:
            raise ValueError(f"{self.name} takes {self.m} joint commands, got shape {q.shape}")
        p = hand_position(self.joint_angles(q), **self.chain(size, pattern, scale))
        return p[..., list(self.outputs)]

    def target_set(self, size: float = 1.0) -> np.ndarray:
        """The target set scales with the body (paper sec. 3.1)."""
        return self.targets * size

    def target_box(self, size: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
        t = self.target_set(size)
        return t.min(axis=0), t.max(axis=0)


def _grid(*axes) -> np.ndarray:
    mesh = np.meshgrid(*axes, indexing="ij")
    return np.stack([g.ravel() for g in mesh], axis=-1)


def grid_points(lo, hi, num) -> np.ndarray:
    """The regular target grid with num[j] points from lo[j] to hi[j] along axis j: (prod num, n)."""
    if not len(lo) == len(hi) == len(num):
        raise ValueError(f"grid: lo, hi and num need one entry per axis, got {lo}, {hi}, {num}")
    if any(int(k) < 1 for k in num) or any(h < l for l, h in zip(lo, hi)):
        raise ValueError(f"grid: need num >= 1 and lo <= hi per axis, got {lo}, {hi}, {num}")
    return _grid(*(np.linspace(l, h, int(k)) for l, h, k in zip(lo, hi, num)))


def cell_centres(targets: np.ndarray) -> np.ndarray:
    """The centres of the cells of a regular grid (off-grid points between the targets)."""
    axes = [np.unique(targets[:, j]) for j in range(targets.shape[1])]
    return _grid(*[0.5 * (a[1:] + a[:-1]) if len(a) > 1 else a for a in axes])


def _planar(name, lengths, home, targets, outputs, growing, description) -> Body:
    m = len(lengths)
    z = np.zeros(m)
    return Body(
        name=name, a=np.asarray(lengths, float), d=z.copy(), alpha=z.copy(), theta_offset=z.copy(),
        base=np.hstack([np.eye(3), np.zeros((3, 1))]), outputs=tuple(outputs),
        home=np.asarray(home, float), targets=np.asarray(targets, float),
        growing=np.asarray(growing, bool), description=description,
    )


ARM2_GRID = dict(lo=[-1.0], hi=[1.0], num=[21])
ARM5_GRID = dict(lo=[-0.5, 0.2], hi=[0.5, 0.7], num=[11, 6])
ICUB_GRID = dict(lo=[-0.36, 0.06, -0.06], hi=[-0.18, 0.30, 0.18], num=[4, 4, 4])


def arm2() -> Body:
    """Fig. 1-2: two joints, 2 x 0.5 m, only the hand's height is controlled (n = 1).

    Joint 1 turns the arm up from the horizontal; home (0, 0) is the stretched horizontal arm.
    Targets: heights -1.0 ... 1.0 m in 0.1 m steps (the paper's full range).
    """
    return _planar(
        "arm2", [0.5, 0.5], home=[0.0, 0.0],
        targets=grid_points(**ARM2_GRID), outputs=(1,), growing=[True, True],
        description="2-DOF arm, 1 m, hand height",
    )


# Home posture of the 5-DOF arm: "slightly curved" (sec. 3.1), bent by the same angle at each of
# joints 2-5 and turned so that the hand is straight above the base, at (0, 0.77) m at full size,
# just above the middle of the target grid.
ARM5_BEND = 0.5


def arm5() -> Body:
    """Sec. 3.1: planar arm, five 0.2 m segments (1 m at full size), hand position (n = 2).

    Target grid (Fig. 3b, our choice): x in -0.5 ... 0.5 m, y in 0.2 ... 0.7 m, 0.1 m apart
    (66 targets), all within 0.86 of the arm's length from the base, so reachable at every size
    and by both growth patterns. Non-proportional growth: segments 1, 3, 5 grow (sec. 3.2).
    """
    home = [np.pi / 2 - 2 * ARM5_BEND] + [ARM5_BEND] * 4
    return _planar(
        "arm5", [0.2] * 5, home=home,
        targets=grid_points(**ARM5_GRID), outputs=(0, 1),
        growing=[True, False, True, False, True],
        description="5-DOF planar arm, 1 m, hand position",
    )


# iCub torso + right arm, DH "right arm v1" (../shared/reference/icub-right-arm.md).
_ICUB = np.array([
    # a [m],     d [m],    alpha,  offset [deg], min [deg], max [deg]
    [0.032, 0.0, 1, 0, -22.0, 84.0],  # torso_pitch
    [0.0, -0.0055, 1, -90, -39.0, 39.0],  # torso_roll
    [-0.0233647, -0.1433, 1, -105, -59.0, 59.0],  # torso_yaw
    [0.0, -0.10774, 1, -90, -95.5, 5.0],  # r_shoulder_pitch
    [0.0, 0.0, -1, -90, 0.0, 160.8],  # r_shoulder_roll
    [-0.015, -0.15228, -1, -105, -37.0, 100.0],  # r_shoulder_yaw
    [0.015, 0.0, 1, 0, 5.5, 106.0],  # r_elbow
    [0.0, -0.1373, 1, -90, -50.0, 50.0],  # r_wrist_prosup
    [0.0, 0.0, 1, 90, -65.0, 10.0],  # r_wrist_pitch
    [0.0625, 0.016, 0, 180, -25.0, 25.0],  # r_wrist_yaw
])
# The robot's start-up posture: torso 0, shoulder (-30, 30, 0), elbow 45, wrist 0 [deg].
ICUB_HOME_DEG = np.array([0, 0, 0, -30, 30, 0, 45, 0, 0, 0], float)


def icub() -> Body:
    """Sec. 3.3: iCub hip (3) + right arm (7), 10 DOF, 3-D palm position.

    Target set (our choice): a 4 x 4 x 4 grid in front of the right shoulder,
    x in -0.36 ... -0.18 m (x points backwards), y in 0.06 ... 0.30 m, z in -0.06 ... 0.18 m,
    around the palm's start-up position (-0.30, 0.21, 0.03) m; checked reachable in the tests.
    """
    q_min, q_max = np.deg2rad(_ICUB[:, 4]), np.deg2rad(_ICUB[:, 5])
    home_rad = np.deg2rad(ICUB_HOME_DEG)
    return Body(
        name="icub", a=_ICUB[:, 0].copy(), d=_ICUB[:, 1].copy(), alpha=_ICUB[:, 2] * np.pi / 2,
        theta_offset=np.deg2rad(_ICUB[:, 3]),
        base=np.array([[0, -1, 0, 0], [0, 0, -1, 0], [1, 0, 0, 0]], float), outputs=(0, 1, 2),
        home=2 * (home_rad - q_min) / (q_max - q_min) - 1,
        targets=grid_points(**ICUB_GRID),
        growing=np.ones(10, bool), q_min=q_min, q_max=q_max,
        description="iCub torso + right arm (DH v1), 10 DOF, palm position",
    )


BODIES = {"arm2": arm2, "arm5": arm5, "icub": icub}


def make_body(name: str, grid: dict | None = None, home=None, saturate: bool | None = None) -> Body:
    """The full-size body `name` (one of arm2, arm5, icub), or a variant of it.

    grid: dict(lo, hi, num) replaces the target grid; home: a posture (command units) replaces
    the home posture; saturate: False lets normalised commands run past the joint limits.
    None keeps the body's own. Raises ValueError naming the bad field as `body.<field>`.
    """
    try:
        body = BODIES[name]()
    except KeyError:
        raise ValueError(f"body.name={name!r}: unknown body; choose one of {sorted(BODIES)}") from None
    changes = {}
    if grid is not None:
        try:
            targets = grid_points(**grid)
        except (TypeError, ValueError) as err:
            raise ValueError(f"body.grid={grid!r}: {err}") from None
        if targets.shape[1] != body.n:
            raise ValueError(f"body.grid={grid!r}: {name} controls {body.n} coordinate(s)")
        changes["targets"] = targets
    if home is not None:
        home = np.asarray(home, dtype=np.float64)
        if home.shape != (body.m,) or not np.all(np.isfinite(home)):
            raise ValueError(f"body.home={home.tolist()!r}: {name} needs {body.m} finite values")
        changes["home"] = home
    if saturate is not None:
        changes["saturates"] = bool(saturate)
    return replace(body, **changes) if changes else body
