"""gbgrowth/GrowingReach-v0 (pipeline/envs): Gymnasium's own checker, growth across episodes,
gbmodel's kinematics to 1e-12, goal-conditioned rewards in batches, and the Gymnasium API it
relies on (pinned here: a Gymnasium release that changes it fails this file, not a user)."""
import inspect
import tomllib
from importlib import metadata

import numpy as np
import pytest

gym = pytest.importorskip("gymnasium")

import pipeline.envs  # noqa: E402  (registers the id)
from gbmodel import make_body  # noqa: E402
from gbmodel.evaluation import heldout_points  # noqa: E402
from gbmodel.growth import Growth  # noqa: E402
from pipeline.config import REPO_ROOT  # noqa: E402
from pipeline.envs.growing_reach import GrowingReach  # noqa: E402

BODIES = [dict(body="arm5", growth="proportional", period=3),
          dict(body="icub", growth="proportional", period=3, mode="incremental", reward="sparse"),
          dict(body="icub_urdf", growth="proximal_first", period=3)]


@pytest.mark.parametrize("kw", BODIES, ids=lambda kw: kw["body"])
def test_gymnasiums_checker_passes_and_the_body_grows_over_period_episodes(kw):
    from gymnasium.utils.env_checker import check_env

    env = gym.make(pipeline.envs.ID, **kw)
    check_env(env.unwrapped)
    env.reset(seed=0)
    sizes = []
    for _ in range(6):
        _, info = env.reset()
        assert info["body_size"] == env.unwrapped.size
        sizes.append(env.step(env.action_space.sample())[-1]["body_size"])
    assert np.allclose(sizes, [0.5, 2 / 3, 5 / 6, 1, 1, 1], rtol=0, atol=1e-15), sizes
    env.reset()  # a reset without a step does not age the body; a seeded one starts anew
    assert env.reset()[1]["episode"] == 7 and env.reset(seed=1)[1]["body_size"] == 0.5


@pytest.mark.parametrize("body,growth", [("arm5", "nonproportional"), ("icub", "proportional"),
                                         ("icub_urdf", "proportional")])
def test_the_hand_and_the_sizes_are_gbmodels(body, growth):
    env = GrowingReach(body=body, growth=growth, period=5, schedule="infant")
    b = make_body(body)
    g = Growth(pattern=growth, period=5, schedule="infant").validate(b)
    env.reset(seed=3)
    rng = np.random.default_rng(0)
    for episode in range(1, 8):
        size = g.sizes(np.array([episode]), b)[0]
        assert env.size == size
        a = rng.uniform(-1, 1, b.m).astype(np.float32)
        obs, reward, *_ , info = env.step(a)
        q = np.asarray(a, np.float64) * (1.0 if b.normalized else np.pi)
        want = b.forward(q, g.scales(b, np.array([size]))[0])
        assert np.max(np.abs(obs["achieved_goal"] - want)) < 1e-12
        # to 1e-12: a batch's norm (axis=-1) and a vector's (BLAS's dot) differ in a last bit
        # on some CPUs (an Intel Xeon with AVX-512)
        assert reward == pytest.approx(-np.linalg.norm(want - obs["desired_goal"]), rel=1e-12)
        assert np.array_equal(env.heldout_goals(), heldout_points(b, size))
        assert info["forward_evaluations"] == episode
        env.reset()


def test_compute_reward_takes_batches_and_goals_are_the_grid_never_the_heldout_set():
    env = GrowingReach(period=10, reward="sparse", tolerance=0.02)
    a, g = np.zeros((4, 7, 2)), np.zeros((4, 7, 2))
    g[0, 0, 0] = 1.0
    r = env.compute_reward(a, g, [{}] * 28)
    assert r.shape == (4, 7) and r[0, 0] == -1 and (r.sum() == -1)
    assert env.tolerance == pytest.approx(0.02 * env.reach) and 0.95 < env.reach <= 1.0
    env.reset(seed=5)
    grid = {tuple(t) for t in env.body.target_set(env.size)}
    held = {tuple(t) for t in env.heldout_goals()}
    for _ in range(20):
        goal = tuple(env.reset()[0]["desired_goal"])
        assert goal in grid and goal not in held
    goal = env.heldout_goals()[3]
    assert np.array_equal(env.reset(options={"goal": goal})[0]["desired_goal"], goal)
    obs = env.observe(env.heldout_goals())
    assert obs["observation"].shape == (len(held), 6) and env.hand(np.zeros((3, 5))).shape == (3, 2)


def test_incremental_mode_moves_by_max_step_and_truncates_at_the_horizon():
    env = GrowingReach(mode="incremental", horizon=4, max_step=0.25, growth="none")
    obs, _ = env.reset(seed=0)
    start = obs["observation"][:5].copy()
    for i in range(4):
        obs, _, terminated, truncated, info = env.step(np.ones(5, np.float32))
        assert not terminated and truncated == (i == 3)
    assert np.allclose(obs["observation"][:5], np.minimum(start + 1.0, 1.0))
    assert info["body_size"] == 1.0


@pytest.mark.parametrize("kw,msg", [(dict(mode="torque"), "mode='torque': choose one of"),
                                    (dict(growth="sideways"), "growth.pattern='sideways'"),
                                    (dict(body="octopus"), "body.name='octopus': unknown body")])
def test_a_bad_argument_is_one_line(kw, msg):
    with pytest.raises(ValueError) as err:
        GrowingReach(**kw)
    assert msg in str(err.value) and "\n" not in str(err.value)


def test_the_gymnasium_api_it_relies_on():
    """Gymnasium 1.x: reset -> (obs, info) with keyword-only seed and options, step -> (obs,
    reward, terminated, truncated, info), spaces.Dict of Box, registration by module import
    (1.0 dropped the `gymnasium.envs` entry points, which 0.26 ... 0.29 load; the extra pins
    >= 1.0 and the entry point stays declared for the older loader)."""
    major = int(gym.__version__.split(".")[0])
    assert major == 1, gym.__version__
    assert list(inspect.signature(gym.Env.reset).parameters) == ["self", "seed", "options"]
    assert all(p.kind is p.KEYWORD_ONLY
               for p in list(inspect.signature(gym.Env.reset).parameters.values())[1:])
    env = gym.make("pipeline.envs:gbgrowth/GrowingReach-v0", period=2)
    out = env.reset(seed=0)
    assert len(out) == 2 and isinstance(out[1], dict)
    out = env.step(env.action_space.sample())
    assert len(out) == 5 and isinstance(out[2], bool) and isinstance(out[3], bool)
    space = env.observation_space
    assert isinstance(space, gym.spaces.Dict) and set(space) == {"observation", "achieved_goal",
                                                                 "desired_goal"}
    assert isinstance(env.action_space, gym.spaces.Box) and env.action_space.dtype == np.float32
    assert env.spec.id == pipeline.envs.ID
    project = tomllib.loads((REPO_ROOT / "pyproject.toml").read_text())["project"]
    assert project["entry-points"]["gymnasium.envs"] == {"gbgrowth": "pipeline.envs:register_envs"}
    assert any(r.startswith("gymnasium>=1.0,<2") for r in project["optional-dependencies"]["gym"])
    assert metadata.version("gymnasium").startswith("1.")
