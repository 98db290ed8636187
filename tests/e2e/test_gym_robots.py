"""Gymnasium's Pusher, Reacher and humanoid arm, read from the MJCF files of the gymnasium wheel
(no mujoco needed), learn with the new-robot recipe (their conf/body_learner files) to within
1.5 % of their reach held out in 1,000 epochs, at constant size and growing (docs/bodies.md,
"Robots from MuJoCo models"; tests/gym_robots.py measures 3 seeds each)."""
import importlib.util

import pytest

import gym_robots


@pytest.mark.skipif(importlib.util.find_spec("gymnasium") is None,
                    reason="gymnasium is not installed (the test extra)")
@pytest.mark.parametrize("growth", ["none", "proportional"])
@pytest.mark.parametrize("name", gym_robots.NAMES)
def test_a_gymnasium_robot_learns_with_the_recipe(name, growth):
    r = gym_robots.measure(name, growth, trials=1)
    assert max(r["errors"]) < 0.015 * r["reach"], (name, growth, r)
