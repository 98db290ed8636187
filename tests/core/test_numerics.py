"""Unit tests of the numerical core: features, bodies, growth, the learner's pieces, a trial.

Trials here run Goal Babbling's numpy reference path (learner.fast=false); tests/core/test_fast.py
checks the compiled path against it.
"""
import numpy as np
import pytest
from scipy.optimize import least_squares

import gbmodel
from gbmodel import Growth, SpecError
from gbmodel.growth import factors
from gbmodel.evaluation import eval_epochs, evaluate
from gbmodel.features import exponents, feature_bounds, features
from gbmodel.learners import goal_babbling
from gbmodel.learners.goal_babbling import reference as learner
from gbmodel.trial import TrialSpec, run_trial

BODY_NAMES = ["arm2", "arm5", "icub"]


# ---- features ---------------------------------------------------------------------------------
@pytest.mark.parametrize("n, p", [(1, 4), (2, 10), (3, 20)])
def test_feature_count(n, p):
    exps = exponents(n, 3)
    assert exps.shape == (p, n)
    assert (exps[0] == 0).all(), "the constant comes first"
    assert len({tuple(e) for e in exps}) == p and exps.sum(axis=1).max() == 3


def test_features_values_and_bounds():
    exps = exponents(2, 3)
    x = np.array([0.5, -2.0])
    phi = features(x, exps)
    assert phi[0] == 1.0
    assert phi[list(map(tuple, exps)).index((2, 1))] == pytest.approx(0.5**2 * -2.0)
    lo, hi = np.array([-1.0, 0.2]), np.array([0.5, 0.7])
    grid = np.stack(np.meshgrid(np.linspace(-1, 0.5, 31), np.linspace(0.2, 0.7, 31)), -1)
    observed = np.abs(features(grid.reshape(-1, 2), exps)).max(axis=0)
    np.testing.assert_allclose(observed, feature_bounds(lo, hi, exps))


# ---- kinematics -------------------------------------------------------------------------------
def test_planar_closed_forms():
    arm5, arm2 = gbmodel.make_body("arm5"), gbmodel.make_body("arm2")
    np.testing.assert_allclose(arm5.forward(np.zeros(5)), [1.0, 0.0], atol=1e-15)
    np.testing.assert_allclose(arm5.forward([np.pi / 2, 0, 0, 0, 0]), [0.0, 1.0], atol=1e-15)
    np.testing.assert_allclose(arm5.forward([0, np.pi, 0, 0, 0]), [-0.6, 0.0], atol=1e-15)
    assert arm2.forward(arm2.home) == pytest.approx([0.0], abs=1e-15)
    assert arm2.forward([np.pi / 2, 0.0]) == pytest.approx([1.0])
    assert arm2.forward([-np.pi / 2, 0.0]) == pytest.approx([-1.0])
    # against the textbook formula of a planar chain
    q = np.random.default_rng(0).uniform(-3, 3, size=(50, 5))
    cum = np.cumsum(q, axis=1)
    expected = 0.2 * np.stack([np.cos(cum).sum(1), np.sin(cum).sum(1)], -1)
    np.testing.assert_allclose(arm5.forward(q), expected, atol=1e-14)


@pytest.mark.parametrize("name", BODY_NAMES)
def test_batch_and_single_shapes_agree(name):
    body = gbmodel.make_body(name)
    q = np.random.default_rng(1).uniform(-1, 1, size=(7, body.m))
    batch = body.forward(q)
    assert batch.shape == (7, body.n)
    for row, qi in zip(batch, q):
        single = body.forward(qi)
        assert single.shape == (body.n,)
        np.testing.assert_array_equal(single, row)
    assert body.forward(q.reshape(7, 1, body.m)).shape == (7, 1, body.n)
    with pytest.raises(ValueError, match="joint commands"):
        body.forward(np.zeros(body.m + 1))


def test_icub_saturates_at_joint_limits():
    icub = gbmodel.make_body("icub")
    q = np.random.default_rng(2).uniform(-3, 3, size=(20, 10))
    np.testing.assert_array_equal(icub.forward(q), icub.forward(np.clip(q, -1, 1)))
    np.testing.assert_allclose(icub.joint_angles(-np.ones(10)), icub.q_min + icub.theta_offset)
    np.testing.assert_allclose(icub.joint_angles(np.ones(10)), icub.q_max + icub.theta_offset)


# ---- growth -----------------------------------------------------------------------------------
@pytest.mark.parametrize("name", BODY_NAMES)
def test_proportional_growth_scales_the_hand(name):
    body = gbmodel.make_body(name)
    q = np.random.default_rng(3).uniform(-1, 1, size=(10, body.m))
    np.testing.assert_allclose(body.forward(q, factors(body, 0.5)), 0.5 * body.forward(q), atol=1e-15)


def test_nonproportional_growth_of_arm5():
    arm5 = gbmodel.make_body("arm5")
    for size in (0.5, 0.75, 1.0):
        lengths = arm5.a * factors(arm5, size, "nonproportional")
        assert lengths.sum() == pytest.approx(size)
        assert lengths[1] == lengths[3] == pytest.approx(0.2), "segments 2 and 4 do not grow"
    start = arm5.a * factors(arm5, 0.5, "nonproportional")
    np.testing.assert_allclose(start[[0, 2, 4]], 0.1 / 3)
    # the straight arm reaches exactly its total length
    assert arm5.forward(np.zeros(5), factors(arm5, 0.5, "nonproportional")) == pytest.approx([0.5, 0.0])
    with pytest.raises(ValueError, match="too small"):
        factors(arm5, 0.3, "nonproportional")


def test_size_schedule():
    s = Growth(period=10, start_size=0.5, end_size=1.0).sizes(np.arange(1, 51))
    assert s[0] == 0.5 and s[10] == 1.0 and (s[10:] == 1.0).all()
    assert np.all(np.diff(s[:11]) == pytest.approx(0.05))
    assert (Growth(period=0, end_size=0.5).sizes(np.arange(1, 6)) == 0.5).all()


@pytest.mark.parametrize("name", ["arm2", "icub"])
def test_nonproportional_growth_refused_where_every_segment_grows(name):
    body = gbmodel.make_body(name)
    assert body.growing.all()
    with pytest.raises(SpecError, match="^growth.pattern='nonproportional': every segment"):
        Growth(pattern="nonproportional", period=10).validate(body)
    Growth(pattern="proportional", period=10).validate(body)


@pytest.mark.parametrize("name", BODY_NAMES)
def test_target_set_reachable_at_every_size(name):
    """Every target is reached (to 0.1 mm) by some posture within the joint limits; growth
    scales hand and targets alike, so this holds at every size for proportional growth."""
    body = gbmodel.make_body(name)
    lo, hi = (-np.ones(body.m), np.ones(body.m)) if body.normalized else (-np.pi, np.pi)
    for pattern, sizes in [("proportional", [1.0])] + (
            [("nonproportional", [0.5, 0.75, 1.0])] if name == "arm5" else []):
        for size in sizes:
            q = body.home.copy()
            for x in body.target_set(size):  # walk the grid from posture to posture
                sol = least_squares(lambda q: body.forward(q, factors(body, size, pattern)) - x,
                                    q,
                                    bounds=(lo, hi) if body.normalized else (-np.inf, np.inf))
                assert np.abs(sol.fun).max() < 1e-4, f"{name} cannot reach {x} at size {size}"
                q = sol.x


# ---- learner pieces ---------------------------------------------------------------------------
def _weights_for(step_intended, step_actual, joint_step):
    """Weight of a sample that follows the home example at the origin."""
    n, m = len(step_intended), len(joint_step)
    xstar = np.stack([np.zeros(n), step_intended])
    x = np.stack([np.zeros(n), step_actual])
    q = np.stack([np.zeros(m), joint_step])
    return learner.sample_weights(xstar, x, q)


def test_direction_weight():
    dq = np.array([0.1, 0.0])  # w_eff = |dx| / |dq| = 1 for a hand step of 0.1
    assert _weights_for([0.1, 0.0], [0.1, 0.0], dq)[1] == pytest.approx(1.0)  # parallel
    assert _weights_for([0.1, 0.0], [0.0, 0.1], dq)[1] == pytest.approx(0.5)  # perpendicular
    assert _weights_for([0.1, 0.0], [-0.1, 0.0], dq)[1] == pytest.approx(0.0)  # opposite
    assert _weights_for([0.1, 0.0], [0.1, 0.0], dq)[0] == 1.0  # the home example


def test_efficiency_weight_and_degenerate_cases():
    w = _weights_for([0.1, 0.0], [0.05, 0.0], [0.2, 0.0])
    assert w[1] == pytest.approx(0.25)  # 0.05 m of hand per 0.2 rad of joints, parallel
    for intended, actual, joints in [([0.1, 0], [0, 0], [0.2, 0]),  # hand does not move
                                     ([0.1, 0], [0, 0], [0, 0]),  # nothing moves
                                     ([0, 0], [0.1, 0], [0.2, 0]),  # no intended movement
                                     ([0, 0], [0, 0], [0, 0])]:
        w = _weights_for(intended, actual, joints)
        assert np.isfinite(w).all() and w[1] == 0.0


@pytest.mark.parametrize("name, kw", [("arm5", {}),
                                      ("icub", dict(radius=0.1, targets_per_epoch=30, steps=10))])
def test_degenerate_weights_occur_only_with_repeated_targets(name, kw):
    """The degenerate cases of sample_weights never arise in the default runs (measured: 0 of
    405,000 samples over 50 epochs of arm5 and iCub, at the start and after 20,000 epochs); with
    repeated targets (targets=any) a still segment's samples move neither the hand nor the joints,
    have no intended step, and weigh 0."""
    body, exps = gbmodel.make_body(name), exponents(gbmodel.make_body(name).n)
    one, lo_hi = np.ones(body.m), body.target_box(1.0)
    for targets, still in (("distinct", False), ("any", True)):
        p = goal_babbling.Params(targets=targets, **kw)
        rng = np.random.default_rng(7)
        M = learner.init_inverse(body.home, *lo_hi, exps, 0.1, rng)
        idx, raw = goal_babbling.draw(p, body, 20, rng)
        found = False
        for e in range(20):
            path = learner.target_path(body.target_set(1.0), idx[e], p.steps)
            A, b = learner.scale_perturbations(raw[e], *lo_hi, p.radius)
            xstar, x, q = learner.rollout(M, body, one, exps, path, A, b)
            w = learner.sample_weights(xstar, x, q)
            nxs, nx, nq = (np.linalg.norm(np.diff(a, axis=-2), axis=-1) for a in (xstar, x, q))
            none = (nxs <= learner.NO_MOVEMENT) | (nx == 0) | (nq == 0)
            assert (w[..., 1:][none] == 0).all() and np.isfinite(w).all()
            found |= bool(none.any())
        assert found == still, targets


def test_disturbance_bound_is_exact():
    rng = np.random.default_rng(4)
    for name, radius in [("arm5", 0.2), ("icub", 0.1)]:
        body = gbmodel.make_body(name)
        for size in (0.5, 1.0):
            lo, hi = body.target_box(size)
            A, b = learner.scale_perturbations(
                rng.uniform(-1, 1, size=(50, body.m, body.n + 1)), lo, hi, radius)
            inside = lo + (hi - lo) * rng.uniform(size=(2000, body.n))
            pts = np.concatenate([body.target_set(size), inside])
            e = np.abs(pts @ A.transpose(0, 2, 1) + b[:, None, :])  # (V, points, m)
            assert e.max() <= radius * (1 + 1e-12)
            # the bound is attained on the target grid (its corners are targets)
            np.testing.assert_allclose(e[:, :len(body.targets)].max(axis=1), radius)


def test_initial_estimate_stays_near_home():
    rng = np.random.default_rng(5)
    for name in BODY_NAMES:
        body = gbmodel.make_body(name)
        exps = exponents(body.n)
        lo, hi = body.target_box(0.5)
        M = learner.init_inverse(body.home, lo, hi, exps, 0.1, rng)
        inside = lo + (hi - lo) * rng.uniform(size=(5000, body.n))
        dev = np.abs(gbmodel.predict(M, inside, exps) - body.home)
        assert dev.max() <= 0.1 and dev.max() > 0.01


def test_target_path_follows_eq9():
    targets = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 2.0]])
    path = learner.target_path(targets, np.array([0, 1, 2]), 4)
    assert path.shape == (8, 2)
    np.testing.assert_allclose(path[:5], [[0, 0], [0.25, 0], [0.5, 0], [0.75, 0], [1, 0]])
    np.testing.assert_allclose(path[-1], [1.0, 1.5])


def test_epoch_reaches_with_the_grown_body():
    """One reference epoch on arm5 grown non-proportionally: every reached position is the hand
    of the grown body at the posture taken, the home example leads each variation with weight 1,
    and the step changes M."""
    body, exps, rng = gbmodel.make_body("arm5"), exponents(2), np.random.default_rng(6)
    size = 0.7
    scale = factors(body, size, "nonproportional")
    M = learner.init_inverse(body.home, *body.target_box(size), exps, 0.1, rng)
    idx, raw = goal_babbling.draw(goal_babbling.Params(), body, 1, rng)
    M_new, (xstar, x, q, w) = learner.epoch(M, body, size, scale, exps, idx[0], raw[0], 0.2, 7,
                                            1.0)
    assert x.shape == (20, 15 * 7 + 1, 2) and q.shape == (20, 15 * 7 + 1, 5)
    np.testing.assert_allclose(x, body.forward(q, factors(body, size, "nonproportional")),
                               atol=1e-15)
    np.testing.assert_array_equal(w[:, 0], 1.0)
    assert not np.allclose(M_new, M)


def test_eval_epochs():
    e = eval_epochs(100_000)
    assert e[0] == 1 and e[-1] == 100_000 and (np.diff(e) > 0).all()
    assert 85 <= len(e) <= 110  # about 20 per decade: a few hundred rows at most
    assert eval_epochs(37)[-1] == 37 and eval_epochs(1).tolist() == [1]


def test_validate_names_the_bad_value():
    for kwargs, name in [(dict(body={"name": "arm7"}), "body.name"),
                         (dict(growth={"pattern": "sideways"}), "growth.pattern"),
                         (dict(growth={"period": -1}), "growth.period"),
                         (dict(growth={"period": 2.5}), "growth.period"),
                         (dict(epochs=0), "learner.epochs"),
                         (dict(learner={"name": "goal_babbling", "radius": -0.1}),
                          "learner.radius"),
                         (dict(learner={"name": "goal_babbling", "learning_rate": 0.0}),
                          "learner.learning_rate"),
                         (dict(snapshots=(0,)), "snapshots")]:
        with pytest.raises(ValueError, match=f"^{name}="):
            TrialSpec(**kwargs).validate()
    with pytest.raises(SpecError) as err:
        TrialSpec(learner={"name": "goal_babbling", "radius": -0.1}).validate()
    assert str(err.value) == "learner.radius=-0.1: must be >= 0"
    assert err.value.key == "learner.radius"


# ---- whole trials -----------------------------------------------------------------------------
REFERENCE = {"name": "goal_babbling", "fast": False}
RATES = {"arm2": 0.000518}  # conf/body_learner/arm2_goal_babbling.yaml; arm5 takes the default


def _spec(name="arm5", epochs=120, snapshots=(), **growth):
    learner = {**REFERENCE, **({"learning_rate": RATES[name]} if name in RATES else {})}
    return TrialSpec(body={"name": name}, growth=growth, learner=learner, epochs=epochs,
                     snapshots=snapshots)


def test_determinism():
    spec = _spec(epochs=120, period=50, snapshots=(7,))
    a = run_trial(spec, np.random.default_rng(11))
    b = run_trial(spec, np.random.default_rng(11))
    c = run_trial(spec, np.random.default_rng(12))
    np.testing.assert_array_equal(a.abs_error, b.abs_error)
    np.testing.assert_array_equal(a.M, b.M)
    np.testing.assert_array_equal(a.snapshots[7], b.snapshots[7])
    assert not np.array_equal(a.abs_error, c.abs_error)
    # snapshots cut the blocks of epochs but change no number
    d = run_trial(_spec(epochs=120, period=50), np.random.default_rng(11))
    np.testing.assert_array_equal(a.abs_error, d.abs_error)


def test_curve_columns():
    spec = _spec(epochs=300, period=100)
    r = run_trial(spec, np.random.default_rng(0))
    np.testing.assert_array_equal(r.epoch, eval_epochs(300))
    np.testing.assert_allclose(r.size, spec.make_growth().sizes(r.epoch))
    np.testing.assert_allclose(r.rel_error, r.abs_error / r.size)
    assert r.size[0] == 0.5 and r.size[-1] == 1.0
    # the last point of the curve is the evaluation of the final model
    body, params = spec.make_body(), spec.make_learner()[1]
    scale = factors(body, 1.0, "proportional")
    assert r.abs_error[-1] == evaluate(goal_babbling, r.M, params, body, 1.0, scale)


@pytest.mark.parametrize("name, epochs, start_max, end_max", [
    # measured (seed 0, the plain step at 1 / W, reference path): arm2 0.53 m -> 0.010 m,
    # arm5 0.44 m -> 0.075 m
    ("arm2", 300, 0.6, 0.02),
    ("arm5", 300, 0.6, 0.12),
])
def test_learning_reduces_the_error(name, epochs, start_max, end_max):
    spec = _spec(name, epochs=epochs, start_size=1.0, end_size=1.0)
    r = run_trial(spec, np.random.default_rng(0))
    assert r.abs_error[0] > 0.3 and r.abs_error[0] < start_max
    assert r.abs_error[-1] < end_max, r.abs_error[-1]
    assert r.abs_error[-1] < 0.3 * r.abs_error[0]


def _sums():
    """Arrays whose correctly rounded sums are hard: ties across partials, cancellation, every
    exponent, subnormals, zeros of both signs, and random ones of each kind."""
    rng = np.random.default_rng(20101207)
    yield from (np.array(x, dtype=np.float64) for x in (
        [], [-0.0], [0.0, -0.0], [1e-16, 1.0, 1e16], [1.0, 2.0 ** -53, 2.0 ** -106],
        [0.1] * 10, [1.0, -1.0, 1e-300], [5e-324, 5e-324], [1e308, -1e308, 1.0],
        [1.0, 2.0 ** -53], [1.0 + 2.0 ** -52, 2.0 ** -53], [1.0, 2.0 ** -53, -2.0 ** -200],
        [-1.0, -2.0 ** -53, 2.0 ** -1074], [2.0 ** -1022, -2.0 ** -1074], [1e300, 1e284, -1e300]))
    for _ in range(4000):
        k = int(rng.integers(0, 60))
        yield from (rng.random(k), np.ldexp(rng.random(k), rng.integers(-1074, 1000, k)),
                    np.ldexp(rng.choice([1.0, -1.0, 3.0, 0.5], k), rng.integers(-60, 60, k)),
                    np.concatenate([rng.random(k), -rng.random(k)]),
                    np.ldexp(rng.integers(-2 ** 53, 2 ** 53, k).astype(float),
                             rng.integers(-1100, 960, k)))


def test_the_compiled_sum_is_math_fsum_to_the_bit():
    """evaluation's sums (simd.fsum) give math.fsum's bits; a non-finite value or an
    intermediate overflow is left to math.fsum, which raises or answers as before."""
    import math

    from gbmodel.evaluation import error
    from gbmodel.simd import fsum

    for x in _sums():
        total, ok = fsum(x)
        assert ok and np.float64(total).tobytes() == np.float64(math.fsum(x.tolist())).tobytes(), x
    for x in ([np.inf, 1.0], [np.nan], [1e308, 1e308]):
        assert not fsum(np.array(x))[1]
    assert error(np.array([np.inf, 1.0])) == math.inf
    with pytest.raises(OverflowError):
        error(np.array([1e308, 1e308]))
    d = np.random.default_rng(7).random(4032)
    assert error(d, "rms") == math.sqrt(math.fsum((d * d).tolist()) / d.size)


def test_the_kernels_work_arrays_start_on_cache_lines():
    """simd.aligned: zeros on a 64-byte boundary (numba's arrays start on 32 bytes, where each
    16-lane vector of a row would span two cache lines), for rows of any length."""
    from gbmodel.learners.goal_babbling.rollout import _work
    from gbmodel.simd import LANES, aligned

    for rows, cols in [(1, 16), (3, 256), (5, 2144), (20, 112)]:
        a = aligned(rows, cols)
        assert a.shape == (rows, cols) and a.dtype == np.float32 and not a.any()
        assert a.ctypes.data % 64 == 0 and a.flags.c_contiguous
    work = _work(5, 2, 10, 20, 105)
    vectors = [a for a in work if a.dtype == np.float32 and a.shape[-1] % LANES == 0]
    assert len(vectors) >= 9 and all(a.ctypes.data % 64 == 0 for a in vectors)
