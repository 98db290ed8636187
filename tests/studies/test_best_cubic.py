"""capacity.best_cubic: the capacity of a cubic inverse, fitted with the analytic Jacobian
(exact in M, the kinematics' derivative carried through the chain: capacity.hand_jacobian, checked
here against central differences), gives the fit of scipy's finite differences over M (what it
used before), with the forward kinematics called only for the residuals. The learned models are
the committed report's."""
import json
import os
import subprocess
import sys
from types import SimpleNamespace

import numpy as np
import pytest
from scipy.optimize import least_squares

from gbmodel.bodies import Body, make_body
from gbmodel.growth import factors
from pipeline.config import REPO_ROOT
from pipeline.studies import capacity
from pipeline.studies.figures import final_body

MODELS = REPO_ROOT / "outputs" / "report" / "models"
TOLERANCE_MM = 1e-3  # on the mean and the worst error of the fit (the report prints 0.01 mm)


def _model(figure, condition, trial):
    conds = json.loads((MODELS / f"{figure}.json").read_text())["conditions"]
    c = conds[condition] if condition else next(iter(conds.values()))
    return c["spec"], c["trials"][trial]["M"]


def _difference_fit(spec, M0):
    """best_cubic as it was: scipy's 2-point differences over every entry of M."""
    body, size, pattern, predict = final_body(spec)
    xs, f, M0 = body.target_set(size), factors(body, size, pattern), np.asarray(M0, float)
    fit = least_squares(lambda flat: (body.forward(predict(flat.reshape(M0.shape), xs), f)
                                      - xs).ravel(), M0.ravel(), method="trf",
                        max_nfev=200 * M0.size)
    d = np.linalg.norm(body.forward(predict(fit.x.reshape(M0.shape), xs), f) - xs, axis=-1)
    return 1e3 * d.mean(), 1e3 * d.max()


def _counted(monkeypatch):
    calls = []
    forward = Body.forward
    monkeypatch.setattr(Body, "forward", lambda self, q, f=None: calls.append(1) or
                        forward(self, q, f))
    return calls


@pytest.mark.parametrize("trial", ["0", "1", "2"])
def test_the_arm2_fit_is_that_of_finite_differences_over_m(trial, monkeypatch):
    spec, M = _model("fig2", None, trial)
    calls = _counted(monkeypatch)
    mean, worst = _difference_fit(spec, M)
    before = len(calls)
    c = capacity.best_cubic(spec, M)
    assert abs(c["best_mean_mm"] - mean) < TOLERANCE_MM
    assert abs(c["best_worst_mm"] - worst) < TOLERANCE_MM
    assert len(calls) - before < 0.8 * before, (before, len(calls) - before)


def test_the_icub_fit_is_that_of_finite_differences_over_m_calling_forward_for_residuals_only(
        monkeypatch):
    """fig7 const1.0 trial 0 (10 x 20 parameters): the 2-point fit (_difference_fit) ends at a
    mean of 0.499082 mm and a worst of 2.056121 mm (2.056123 with two BLAS threads) after 8,264
    forward calls, 6 to 24 s CPU; test_the_icub_fit_against_finite_differences runs it."""
    spec, M = _model("fig7", "const1.0", "0")
    calls = _counted(monkeypatch)
    c = capacity.best_cubic(spec, M)
    assert abs(c["best_mean_mm"] - 0.499082) < TOLERANCE_MM
    assert abs(c["best_worst_mm"] - 2.056121) < TOLERANCE_MM
    assert len(calls) < 8264 / 40  # residuals only: no forward call for the Jacobian
    assert f"{c['best_mean_mm']:.2f} {c['best_worst_mm']:.1f}" == "0.50 2.1"  # as reported


def _differences(body, f, q, h=1e-6):
    """d forward / d q (N, n, m) by central differences, one joint at a time."""
    cols = []
    for j in range(body.m):
        e = np.zeros(body.m)
        e[j] = h
        cols.append((body.forward(q + e, f) - body.forward(q - e, f)) / (2 * h))
    return np.stack(cols, axis=-1)


@pytest.mark.parametrize("name, saturate", [("arm2", True), ("icub", True), ("icub", False),
                                            ("icub_urdf", True)])
def test_the_hand_jacobian_is_that_of_central_differences(name, saturate):
    """DH chains (the 2-DOF arm in radians, the iCub's normalised commands with and without
    clipping) and a general chain (the iCub's URDF), grown unevenly; commands beyond +-1 on
    a saturating body are clipped, so their column is zero."""
    body = make_body(name, saturate=saturate)
    q = np.random.default_rng(3).uniform(-1.3, 1.3, (40, body.m))
    q[np.abs(np.abs(q) - 1) < 1e-4] = 0.5  # no difference across the clip's kink
    f = np.linspace(0.6, 1.0, body.m)
    J = capacity.hand_jacobian(body, f, q)
    assert J.shape == (40, body.n, body.m)
    np.testing.assert_allclose(J, _differences(body, f, q), rtol=0, atol=1e-8)
    clipped = (np.abs(q) > 1) & (body.normalized and saturate)
    assert clipped.any() == (name != "arm2" and saturate)
    assert np.all(J.transpose(0, 2, 1)[clipped] == 0)
    assert np.abs(J).max() > 0.01


def test_a_body_in_the_loop_is_differenced_in_one_forward_call():
    """A Python forward function (body.loop) has no chain to carry the derivative through:
    central differences over the commands, every displaced posture in one call."""
    arm = make_body("arm5")
    calls = []
    loop = SimpleNamespace(loop=object(), m=arm.m,
                           forward=lambda q, f=None: calls.append(q.shape) or arm.forward(q, f))
    q = np.random.default_rng(4).uniform(-1, 1, (25, arm.m))
    f = np.linspace(0.7, 1.0, arm.m)
    J = capacity.hand_jacobian(loop, f, q)
    assert calls == [(2 * arm.m * 25, arm.m)]
    np.testing.assert_allclose(J, capacity.hand_jacobian(arm, f, q), rtol=0, atol=1e-8)


@pytest.mark.slow
@pytest.mark.parametrize("trial", ["0", "1", "2"])
def test_the_icub_fit_against_finite_differences(trial):
    spec, M = _model("fig7", "const1.0", trial)
    mean, worst = _difference_fit(spec, M)
    c = capacity.best_cubic(spec, M)
    assert abs(c["best_mean_mm"] - mean) < TOLERANCE_MM
    assert abs(c["best_worst_mm"] - worst) < TOLERANCE_MM


def test_a_learner_whose_inverse_is_not_linear_in_m_falls_back_to_differences():
    xs = np.linspace(-1, 1, 7)[:, None]
    assert capacity._linear_features(lambda M, x: np.tanh(x @ M.T), np.ones((2, 1)), xs) is None
    assert capacity._linear_features(lambda M, x: x @ M.T + 1, np.ones((2, 1)), xs) is None
    Phi = capacity._linear_features(lambda M, x: np.hstack([x, x ** 2]) @ M.T, np.ones((2, 2)), xs)
    assert np.array_equal(Phi, np.hstack([xs, xs ** 2]))


REPORT_ENV = """
import os, sys
sys.orig_argv = [sys.executable, *sys.argv[1].split()]
sys.argv = sys.orig_argv[2:] if sys.orig_argv[1] == "-m" else sys.orig_argv[1:]
import pipeline
print(os.environ.get("OPENBLAS_NUM_THREADS"))
"""


@pytest.mark.parametrize("command, threads", [("-m pipeline.report", "1"),
                                              ("-m pipeline report", "1"),
                                              ("/usr/bin/gbgrowth report", "1"),
                                              ("-m pipeline.simulate", None),
                                              ("/usr/bin/gbgrowth simulate", None)])
def test_the_report_stage_runs_blas_on_one_thread(command, threads):
    """The report's least squares is small: a second BLAS thread only spins (35x the CPU of an
    SVD of 192 x 200 on a loaded two-core machine); the other stages keep their setting."""
    env = {k: v for k, v in os.environ.items() if k != "OPENBLAS_NUM_THREADS"}
    r = subprocess.run([sys.executable, "-c", REPORT_ENV, command], capture_output=True,
                       text=True, env=dict(env, PYTHONPATH=str(REPO_ROOT)), cwd=REPO_ROOT,
                       timeout=120)
    assert r.returncode == 0, r.stderr
    assert r.stdout.split()[-1] == str(threads)
