"""learner.solver=lstsq (goal_babbling/solve.py): M solved from eq. 6's weighted normal equations
over a ring of the last `window` epochs' Gram sums, on the numpy path and in the kernel.

Tolerances: the kernel accumulates the Gram sums in float32 lanes from its float32 rollout, so
they agree with the float64 reference's to 1e-4 relative to each row's largest entry (measured
<= 9e-5 on the iCub, <= 6e-6 on the arms); the solved inverse, compared where it is used (its
commands at the targets), to 2e-4 (measured <= 6e-5 in the first epoch, ~2e-6 after).
"""
import numpy as np
import pytest

import gbmodel
from gbmodel.features import exponents, features
from gbmodel.growth import factors
from gbmodel.spec import SpecError
from gbmodel.learners import goal_babbling as gb
from gbmodel.learners.goal_babbling import reference, solve
from pipeline.config import compose
from pipeline.plan import plan

from conftest import run_cli

ICUB = dict(radius=0.1, targets_per_epoch=30, steps=10)
BODIES = [("arm2", {}), ("arm5", {}), ("icub", ICUB), ("icub_urdf", ICUB)]  # DH and URDF


def one_epoch(S, params, body, d, size=1.0, fast=True):
    p = gb.Params(**{**params.__dict__, "fast": fast})
    scale = np.ones((1, body.m))
    return gb.train(S, p, body, np.full(1, size), scale, d, np.arange(1, 2))


@pytest.mark.parametrize("name, kw", BODIES)
def test_kernel_solve_matches_reference(name, kw):
    """Epoch by epoch from the reference's state: the same ring slot, the same commands."""
    body = gbmodel.make_body(name)
    params = gb.Params(**kw, solver="lstsq", window=3)
    rng = np.random.default_rng(3)
    S = gb.init(params, body, 1.0, rng)
    p = S.M.shape[1]
    assert isinstance(S, solve.Solved) and S.ring.shape == (3, p + body.m, p)
    for e in range(5):  # past the window: slots are overwritten
        d = gb.draw(params, body, 1, rng)
        ref, fst = one_epoch(S, params, body, d, fast=False), one_epoch(S, params, body, d)
        assert ref.epochs == fst.epochs == e + 1
        slot = e % 3
        scale = np.abs(ref.ring[slot]).max(axis=1, keepdims=True)
        assert np.abs(fst.ring[slot] - ref.ring[slot]).max(axis=None) > 0  # float32 vs float64
        np.testing.assert_array_less(np.abs(fst.ring[slot] - ref.ring[slot]) / scale, 1e-4)
        g = lambda s: gb.predict(s, params, body, body.targets)  # noqa: E731
        np.testing.assert_allclose(g(fst), g(ref), atol=2e-4)
        assert not np.allclose(ref.M, S.M), "the solve must change M"
        S = ref


def test_solve_is_the_weighted_least_squares_of_the_window():
    """With no ridge, M minimises sum w |M Phi(x) - q|^2 over the samples of the last `window`
    epochs exactly (numpy's lstsq on the stacked sqrt(w)-scaled rows), the older ones forgotten."""
    body = gbmodel.make_body("arm5")
    params = gb.Params(solver="lstsq", window=2, ridge=0.0, fast=False)
    exps = exponents(body.n, params.degree)
    rng = np.random.default_rng(0)
    S = gb.init(params, body, 1.0, rng)
    rows = []
    for e in range(3):
        idx, raw = gb.draw(params, body, 1, rng)
        _, x, q, w = reference.samples(S.M, body, 1.0, np.ones(body.m), exps, idx[0], raw[0],
                                       params.radius, params.steps)
        rows.append((x.reshape(-1, body.n), q.reshape(-1, body.m), w.reshape(-1)))
        S = solve.solve(S, solve.grams(x, q, w, exps), params.ridge)
    x, q, w = (np.concatenate(a) for a in zip(*rows[1:]))  # the last two epochs
    assert w[0] == 1.0  # the home example, weight 1
    sw = np.sqrt(w)[:, None]
    expected = np.linalg.lstsq(sw * features(x, exps), sw * q, rcond=None)[0].T
    g = lambda M: reference.predict(M, body.targets, exps)  # noqa: E731
    np.testing.assert_allclose(g(S.M), g(expected), atol=1e-9)


def test_ridge_pulls_towards_the_current_model():
    """A huge ridge keeps M; a feature that never varies keeps its column of M."""
    body = gbmodel.make_body("arm5")
    rng = np.random.default_rng(1)
    M0 = rng.normal(size=(body.m, 10))
    total = rng.normal(size=(10 + body.m, 10))
    total[:10] = total[:10] @ total[:10].T
    A, B = solve.system(M0, total, 1e12)
    np.testing.assert_allclose(np.linalg.solve(A, B).T, M0, atol=1e-9)
    total[3, :] = total[:, 3] = 0
    A, B = solve.system(M0, total, 0.0)
    np.testing.assert_allclose(np.linalg.solve(A, B).T[:, 3], M0[:, 3], atol=1e-12)


def test_anchor_pulls_towards_the_initial_model_over_the_targets():
    """A huge anchor gives M0's commands at the targets (not its coefficients: P weighs the
    features as the targets use them); no anchor leaves the ridge's system as it is."""
    body = gbmodel.make_body("icub")
    exps = exponents(body.n, 3)
    rng = np.random.default_rng(5)
    M, M0 = rng.normal(size=(body.m, 20)), rng.normal(size=(body.m, 20))
    X = rng.normal(size=(20, 20))
    total = np.concatenate([X @ X.T, rng.normal(size=(body.m, 20))])
    total[0, 0] = 300.0  # the window's sum of weights
    P = solve.target_gram(body.target_set(0.5), exps)
    A, B = solve.system(M, total, 1e-3, P, M0, 1e9)
    g = lambda M: reference.predict(M, body.target_set(0.5), exps)  # noqa: E731
    np.testing.assert_allclose(g(np.linalg.solve(A, B).T), g(M0), atol=1e-3)
    A0, B0 = solve.system(M, total, 1e-3, P, M0, 0.0)
    A1, B1 = solve.system(M, total, 1e-3)
    assert np.array_equal(A0, A1) and np.array_equal(B0, B1)


def test_limit_pulls_the_commands_at_the_targets_within_the_joint_limits():
    """A huge limit term gives the cubic closest, over the targets, to the commands the body
    executes under the current M (clipped at its limits: not M0's, not past a limit); no limit
    term leaves the system as it is."""
    body = gbmodel.make_body("icub")
    exps = exponents(body.n, 3)
    rng = np.random.default_rng(6)
    M, M0 = 3 * rng.normal(size=(body.m, 20)), rng.normal(size=(body.m, 20))
    X = rng.normal(size=(20, 20))
    total = np.concatenate([X @ X.T, rng.normal(size=(body.m, 20))])
    total[0, 0] = 300.0
    targets = body.target_set(0.5)
    g = lambda M: reference.predict(M, targets, exps)  # noqa: E731
    assert (np.abs(g(M)) > 1).mean() > 0.3  # many commands past a limit
    P = solve.target_gram(targets, exps)
    PC = solve.limit_gram(targets, exps, M, clip=True)
    A, B = solve.system(M, total, 1e-3, P, M0, 0.0, PC, 1e9)
    phi = features(targets, exps)
    closest = np.linalg.lstsq(phi, np.clip(g(M), -1, 1), rcond=None)[0].T
    np.testing.assert_allclose(g(np.linalg.solve(A, B).T), g(closest), atol=1e-3)
    assert np.abs(g(closest)).max() < 1.3
    A0, B0 = solve.system(M, total, 1e-3, P, M0, 0.0, PC, 0.0)
    A1, B1 = solve.system(M, total, 1e-3, P, M0, 0.0)
    assert np.array_equal(A0, A1) and np.array_equal(B0, B1)


def test_a_half_size_start_does_not_get_stuck_at_the_joint_limits():
    """Fig. 7's TG100 on a seed of the 2,000-epoch study (docs/bodies.md, "The exact solver"):
    without the limit term its inverse commands joints past their limits at 17-31 % of the
    targets by epoch 2,000, where no variation moves the hand (the samples weigh nothing) and
    the error climbs to 27 mm; with it the trial ends with the others (about 2 mm)."""
    trials = plan(compose(["experiment=fig7", "learner.solver=lstsq", "learner.epochs=2000",
                           "trials.count=1", "conditions.periods=[100]",
                           "conditions.references=[]"]))
    assert [t["growth_label"] for t in trials] == ["TG100"]
    spec = gbmodel.TrialSpec.from_dict(trials[0]["spec"])
    seed = np.random.SeedSequence(entropy=2010, spawn_key=[2943757460, 4])
    r = gbmodel.run_trial(spec, np.random.default_rng(seed))
    assert r.abs_error[-1] < 0.004, r.abs_error[-1]
    body = spec.make_body()
    _, params = spec.make_learner()
    q = gb.predict(r.M, params, body, body.target_set(r.size[-1]))
    assert (np.abs(q) > 1).any(axis=1).mean() < 0.1


def test_the_anchor_stays_without_joint_limits_and_decays_with_them():
    arm5, icub = gbmodel.make_body("arm5"), gbmodel.make_body("icub")
    assert solve.anchor_at(0.01, 100.0, 5000, arm5) == 0.01
    assert solve.anchor_at(0.01, 100.0, 1, icub) == 0.01
    assert solve.anchor_at(0.01, 100.0, 101, icub) == pytest.approx(0.005)


def test_arm2_learns_with_the_default_settings():
    """The one-output arm: before the anchor, the exact solve from the first epochs' samples
    (clustered at home) extrapolated over the targets and never recovered (356 mm held out
    after 1,000 epochs at the default ridge); now within 1.5 % of its 1 m reach."""
    spec = gbmodel.TrialSpec(body={"name": "arm2"}, epochs=1000,
                             learner={"name": "goal_babbling", "solver": "lstsq"})
    r = gbmodel.run_trial(spec, np.random.default_rng(0))
    assert r.heldout_abs_error[-1] < 0.015, r.heldout_abs_error[-1]


def test_a_constant_body_does_not_drift():
    """Fig. 5's constant half-size arm (three 3.3 cm segments among two of 20 cm): joints that
    barely move the hand and have no limits wound up (postures of 3-20 rad) and the error rose
    from 11 to 18-34 mm between epochs 1,000 and 10,000; the anchor holds them."""
    spec = gbmodel.TrialSpec(body={"name": "arm5"}, epochs=10_000,
                             growth={"pattern": "nonproportional", "start_size": 0.5,
                                     "end_size": 0.5, "period": 0},
                             learner={"name": "goal_babbling", "solver": "lstsq"})
    r = gbmodel.run_trial(spec, np.random.default_rng(1))
    early = r.abs_error[(r.epoch >= 500) & (r.epoch <= 1500)].mean()
    late = r.abs_error[r.epoch >= 5000].max()  # before the anchor: 1.6-3x early by 10,000
    assert late < 1.3 * early, (late, early)
    assert np.abs(r.M).max() < 100


def test_stale_kernel_caches_are_removed(tmp_path):
    """numba checks a kernel's cache against its own file only: a change of any file of the
    folder (a callee's) removes the folder's caches once."""
    from gbmodel.simd import fresh_cache
    (tmp_path / "a.py").write_text("x = 1\n")
    cache = tmp_path / "__pycache__"
    assert fresh_cache(tmp_path)  # no stamp yet
    (cache / "a.f-1.py311.nbi").write_text("index")
    assert not fresh_cache(tmp_path) and (cache / "a.f-1.py311.nbi").exists()
    (tmp_path / "b.py").write_text("y = 2\n")
    assert fresh_cache(tmp_path) and not (cache / "a.f-1.py311.nbi").exists()


def test_every_folder_of_cached_kernels_removes_its_stale_caches():
    """A folder with cached kernels (njit cache=True) outside simd.py, whose kernels hold what
    they call from simd.py or a sibling, calls fresh_cache on itself when imported: else an edit
    of simd.py leaves its kernels running the code of before (numba checks the kernel's own file
    only)."""
    import re
    from pathlib import Path
    root = Path(__file__).resolve().parents[2]
    cached = re.compile(r"@njit\([^)]*\bcache=True")
    folders = {f.parent for pkg in ("gbmodel", "pipeline") for f in (root / pkg).rglob("*.py")
               if cached.search(f.read_text()) and f.name != "simd.py"}
    assert {root / "gbmodel/learners/goal_babbling", root / "gbmodel/learners/online_goal_babbling",
            root / "pipeline/tools"} <= folders
    call = re.compile(r"^fresh_cache\(Path\(__file__\)\.parent", re.M)
    missing = [str(d.relative_to(root)) for d in sorted(folders)
               if not any(call.search(f.read_text()) for f in d.glob("*.py"))]
    assert missing == []


def test_cholesky_solve_matches_numpy():
    rng = np.random.default_rng(2)
    X = rng.normal(size=(20, 20))
    A, B = X @ X.T + np.eye(20), rng.normal(size=(20, 7))
    out = np.empty_like(B)
    solve.cholesky_solve(A, B, np.zeros_like(A), out)
    np.testing.assert_allclose(out, np.linalg.solve(A, B), rtol=1e-10, atol=1e-10)


@pytest.mark.parametrize("fast", [True, False])
def test_chunks_and_growth_do_not_change_the_result(fast):
    """The ring lives in the state: two blocks of epochs give the bytes of one (a growing body,
    so the epochs differ), on both paths."""
    body = gbmodel.make_body("arm5")
    params = gb.Params(solver="lstsq", window=4, fast=fast)
    sizes = np.linspace(0.6, 1.0, 9)
    scales = np.stack([factors(body, s, "proportional") for s in sizes])
    rng = np.random.default_rng(4)
    S = gb.init(params, body, sizes[0], rng)
    d = gb.draw(params, body, 9, rng)
    whole = gb.train(S, params, body, sizes, scales, d, np.arange(1, 10))
    part = gb.train(S, params, body, sizes[:5], scales[:5], tuple(a[:5] for a in d),
                    np.arange(1, 6))
    part = gb.train(part, params, body, sizes[5:], scales[5:], tuple(a[5:] for a in d),
                    np.arange(6, 10))
    assert whole.epochs == part.epochs == 9
    assert whole.M.tobytes() == part.M.tobytes() and whole.ring.tobytes() == part.ring.tobytes()


@pytest.mark.parametrize("name, kw", [("arm5", {}), ("icub_urdf", ICUB)])
def test_lstsq_learns_a_trial(name, kw):
    """A short trial on a DH and a URDF body: well below the initial error, finite on both
    paths, and the progress goal selection carries the solver's state."""
    for extra in ({}, {"goal_selection": "progress"}):
        spec = gbmodel.TrialSpec(body={"name": name}, epochs=60, learner={
            "name": "goal_babbling", "solver": "lstsq", **kw, **extra})
        r = gbmodel.run_trial(spec, np.random.default_rng(0))
        assert r.abs_error[-1] < 0.2 * r.abs_error[0], r.abs_error
        assert r.M.shape == (gbmodel.make_body(name).m, 10 if name == "arm5" else 20)


@pytest.mark.parametrize("field, value, shown", [
    ("solver", "foo", "learner.solver='foo'"), ("window", 0, "learner.window=0"),
    ("ridge", -1.0, "learner.ridge=-1.0"), ("anchor", -1.0, "learner.anchor=-1.0"),
    ("anchor_epochs", 0.0, "learner.anchor_epochs=0.0"), ("limit_pull", -1.0, "learner.limit_pull=-1.0"),
])
def test_bad_values_are_refused(field, value, shown):
    with pytest.raises(SpecError, match=shown.replace("(", r"\(")):
        gb.Params(**{field: value}).validate()


def test_lstsq_needs_batch_updates():
    with pytest.raises(SpecError, match="learner.updates='online'"):
        gb.Params(solver="lstsq", updates="online").validate()


@pytest.mark.parametrize("arg, shown", [
    ("learner.solver=foo", "learner.solver='foo'"), ("learner.window=0", "learner.window=0"),
    ("learner.ridge=-1", "learner.ridge=-1"),
])
def test_bad_values_exit_2_with_one_line(tmp_path, arg, shown):
    r = run_cli("pipeline.simulate", "experiment=fig4", "profile=smoke", arg,
                f"paths.root={tmp_path}")
    lines = r.stderr.strip().splitlines()
    assert r.returncode == 2 and len(lines) == 1, r.stderr
    assert lines[0].startswith("error: ") and shown in lines[0], r.stderr


def test_solver_enters_the_trial_key_only_when_not_the_default():
    default = plan(compose(["experiment=fig4", "profile=smoke"]))[0]
    assert not {"solver", "window", "ridge", "anchor", "anchor_epochs", "limit_pull"} & set(
        default["spec"]["learner"])
    lstsq = plan(compose(["experiment=fig4", "profile=smoke", "learner.solver=lstsq"]))[0]
    assert lstsq["spec"]["learner"]["solver"] == "lstsq"
    assert "window" not in lstsq["spec"]["learner"] and lstsq["key"] != default["key"]
    wide = plan(compose(["experiment=fig4", "profile=smoke", "learner.solver=lstsq",
                         "learner.window=20"]))[0]
    assert wide["spec"]["learner"]["window"] == 20 and wide["key"] != lstsq["key"]
