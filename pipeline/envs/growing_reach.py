"""gbgrowth/GrowingReach-v0: reaching with a body that grows across episodes (docs/gym.md).

Any body of the project grows along gbmodel's schedules with `period` in episodes (episode e has
the pipeline's size of epoch e); kinematics and growth are gbmodel's. action: a posture in [-1,
1]^m (mode=incremental: a move of at most `max_step`, `horizon` steps); observation: posture and
size, achieved_goal the hand, desired_goal the target; reward dense (-distance) or sparse
(within `tolerance` x reach); goals: the target grid at the current size. A reset after a step
starts the next, older episode; a seed starts anew with a newborn body.
"""
from __future__ import annotations

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from gbmodel.bodies import make_body
from gbmodel.evaluation import heldout_points
from gbmodel.growth import Growth
from gbmodel.spec import MAX_SIZE, check_choice
from gbmodel.workspace import reach

MODES = ("posture", "incremental")
REWARDS = ("dense", "sparse")
GOALS = ("grid", "box")


def make_growth(growth, period: int, schedule: str, start_size: float, end_size: float) -> Growth:
    """gbmodel.Growth from a pattern's name (conf/growth's) or a dict of Growth's fields."""
    if isinstance(growth, dict):
        return Growth(**{"period": period, "schedule": schedule, "start_size": start_size,
                         "end_size": end_size, **growth})
    if growth == "none":  # a body of constant size end_size (the pipeline's references)
        return Growth(pattern="proportional", period=0, start_size=end_size, end_size=end_size)
    return Growth(pattern=growth, period=period, schedule=schedule, start_size=start_size,
                  end_size=end_size)


class GrowingReach(gym.Env):
    """Reach a target with a body that grows across episodes (module docstring)."""

    metadata = {"render_modes": []}

    def __init__(self, body="arm5", growth="proportional", period: int = 100,
                 schedule: str = "linear", start_size: float = 0.5, end_size: float = 1.0,
                 mode: str = "posture", reward: str = "dense", tolerance: float = 0.02,
                 horizon: int = 50, max_step: float = 0.1, goals: str = "grid"):
        for name, value, options in (("mode", mode, MODES), ("reward", reward, REWARDS),
                                     ("goals", goals, GOALS)):
            check_choice(name, value, options)
        self.body = make_body(body)
        self.growth = make_growth(growth, period, schedule, start_size, end_size).validate(
            self.body)
        self.mode, self.reward_type, self.goals = mode, reward, goals
        self.horizon, self.max_step = int(horizon), float(max_step)
        self.command_scale = 1.0 if self.body.normalized else np.pi
        self.reach = reach(self.body)  # the full-size body's [m]
        self.tolerance = float(tolerance) * self.reach  # [m]
        m, n = self.body.m, self.body.n
        self.home = np.clip(np.asarray(self.body.home, np.float64) / self.command_scale, -1, 1)
        self.action_space = spaces.Box(-1.0, 1.0, (m,), np.float32)
        # bounds that hold every hand and target: the targets' box and twice the reach around
        # it, at the largest size (a sampled reach: a margin of 2)
        big = max(1.0, self.growth.start_size, self.growth.end_size)
        far = 2.0 * big * (np.abs(self.body.targets).max() + 2.0 * self.reach)
        top = np.append(np.ones(m), MAX_SIZE)
        self.observation_space = spaces.Dict({
            "observation": spaces.Box(np.append(-np.ones(m), 0.0), top, (m + 1,), np.float64),
            "achieved_goal": spaces.Box(-far, far, (n,), np.float64),
            "desired_goal": spaces.Box(-far, far, (n,), np.float64)})
        self.episodes, self.evaluations = 0, 0  # finished episodes; forward evaluations
        self._stepped, self._steps = False, 0
        self._grow()
        self.posture, self.goal = self.home.copy(), self.body.target_set(self.size)[0]

    # ---- growth and kinematics (gbmodel's) -------------------------------------------------------
    def _grow(self) -> None:
        """The size and per-segment factors of the episode about to start (1-based)."""
        self.size = float(self.growth.sizes(np.array([self.episodes + 1]), self.body)[0])
        self.factors = self.growth.scales(self.body, np.array([self.size]))[0]

    def hand(self, postures) -> np.ndarray:
        """The hand [m] at postures in action units, at the current size (not counted)."""
        q = np.clip(np.asarray(postures, np.float64), -1.0, 1.0) * self.command_scale
        return self.body.forward(q, self.factors)

    def heldout_goals(self) -> np.ndarray:
        """The pipeline's held-out set at the current size (gbmodel.evaluation.heldout_points)."""
        return heldout_points(self.body, self.size)

    def observe(self, goals) -> dict:
        """The observations (batched) of an episode's start towards each of `goals` (N, n)."""
        goals = np.asarray(goals, np.float64)
        k = len(goals)
        obs = np.append(self.home, self.size)
        return {"observation": np.tile(obs, (k, 1)),
                "achieved_goal": np.tile(self.hand(self.home), (k, 1)), "desired_goal": goals}

    def _obs(self) -> dict:
        return {"observation": np.append(self.posture, self.size),
                "achieved_goal": self.hand(self.posture), "desired_goal": self.goal.copy()}

    def _info(self, d: float | None = None) -> dict:
        info = {"body_size": self.size, "episode": self.episodes + 1,
                "forward_evaluations": self.evaluations}
        if d is not None:
            info.update(distance=d, is_success=bool(d <= self.tolerance))
        return info

    # ---- the Gymnasium API -----------------------------------------------------------------------
    def compute_reward(self, achieved_goal, desired_goal, info=None):
        """The reward, for single goals or batches (..., n) -> (...)."""
        d = np.linalg.norm(np.asarray(achieved_goal, np.float64)
                           - np.asarray(desired_goal, np.float64), axis=-1)
        if self.reward_type == "dense":
            return -d
        return -(d > self.tolerance).astype(np.float64)

    def reset(self, *, seed=None, options=None):
        super().reset(seed=seed)
        if seed is not None:  # a new start: a newborn body
            self.episodes, self.evaluations = 0, 0
            self._grow()
        elif self._stepped:  # the episode before took a step: the body is one episode older
            self.episodes += 1
            self._grow()
        self._stepped, self._steps = False, 0
        self.posture = self.home.copy()
        goal = (options or {}).get("goal")
        if goal is not None:
            self.goal = np.asarray(goal, np.float64).reshape(self.body.n)
        elif self.goals == "grid":
            targets = self.body.target_set(self.size)
            self.goal = targets[self.np_random.integers(len(targets))]
        else:
            self.goal = self.np_random.uniform(*self.body.target_box(self.size))
        return self._obs(), self._info()

    def step(self, action):
        a = np.clip(np.asarray(action, np.float64).reshape(self.body.m), -1.0, 1.0)
        if self.mode == "posture":
            self.posture = a
        else:
            self.posture = np.clip(self.posture + self.max_step * a, -1.0, 1.0)
        self._stepped, self._steps = True, self._steps + 1
        self.evaluations += 1
        obs = self._obs()
        reward = float(self.compute_reward(obs["achieved_goal"], self.goal))
        d = float(np.linalg.norm(obs["achieved_goal"] - self.goal))
        terminated = self.mode == "posture"  # one reach per episode
        truncated = self.mode == "incremental" and self._steps >= self.horizon
        return obs, reward, terminated, truncated, self._info(d)
