"""Growth schedules and patterns (gbmodel.growth): linear, infant, proximal-first."""
import hashlib
import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import gbmodel
from gbmodel import Growth, SpecError
from gbmodel.growth import INFANT_RATE, WHO_LENGTH_CM, _expm1, progress

EPOCHS = np.arange(1, 302)


def test_linear_schedule_unchanged():
    g = Growth(period=200, start_size=0.5, end_size=1.0)
    s = g.sizes(EPOCHS)
    np.testing.assert_allclose(s, 0.5 + 0.5 * np.clip((EPOCHS - 1) / 200, 0, 1), atol=1e-15)
    assert s[0] == 0.5 and s[200] == 1.0 and (s[200:] == 1.0).all()
    assert (Growth(period=0, end_size=0.7).sizes(EPOCHS) == 0.7).all()


def test_infant_rate_fits_the_who_curve():
    birth, year, two_years = WHO_LENGTH_CM
    half = (year - birth) / (two_years - birth)  # 0.694 of 0-24 months' growth in the first 12
    assert progress(0.5, "infant") == pytest.approx(half, abs=1e-12)
    assert INFANT_RATE == pytest.approx(1.6335, abs=1e-4)


def test_infant_rate_is_the_formula_written_out():
    birth, year, two_years = WHO_LENGTH_CM
    f = (year - birth) / (two_years - birth)
    assert abs(INFANT_RATE - 2.0 * math.log(f / (1.0 - f))) <= math.ulp(INFANT_RATE)


def test_expm1_from_plain_arithmetic_is_within_a_few_ulp():
    x = np.linspace(-2.0, 2.0, 40001)
    exact = np.array([math.expm1(v) for v in x])
    ulps = np.abs(_expm1(x) - exact) / np.array([math.ulp(v) for v in exact])
    assert ulps.max() <= 8
    assert _expm1(np.zeros(1))[0] == 0.0


# sha256 of progress(linspace(0, 1, 10001), "infant"): recorded on an Intel Xeon with AVX-512; the
# same bytes on any CPU, as only + - * / make them (numpy's expm1 gave other bytes without
# AVX-512, which moved least squares under the infant schedule between CPUs)
INFANT_BYTES = "01af9acccba7a4e407a984b39130e1f146a2e35ad39bb35f22dcf89ea1f9cbc0"
CHILD = ("import hashlib, numpy as np; from gbmodel.growth import progress; "
         "print(hashlib.sha256(progress(np.linspace(0, 1, 10001), 'infant').tobytes())"
         ".hexdigest())")


@pytest.mark.parametrize("disabled", ["", "AVX512_SPR AVX512_ICL X86_V4",
                                      "AVX512_SPR AVX512_ICL X86_V4 X86_V3"])
def test_infant_schedule_same_bytes_on_every_numpy_target(disabled):
    """numpy picks its loops by CPU (AVX-512, AVX2, the baseline); the schedule's bytes are the
    recorded ones under each (NPY_DISABLE_CPU_FEATURES; a target the CPU lacks is ignored)."""
    env = {**os.environ, "NPY_DISABLE_CPU_FEATURES": disabled,
           "PYTHONPATH": str(Path(__file__).resolve().parents[2])}
    out = subprocess.run([sys.executable, "-c", CHILD], capture_output=True, text=True,
                         env=env, timeout=120, check=True).stdout.strip()
    assert out == INFANT_BYTES


def test_infant_schedule_gives_the_recorded_bytes_here():
    here = hashlib.sha256(progress(np.linspace(0, 1, 10001), "infant").tobytes()).hexdigest()
    assert here == INFANT_BYTES


@pytest.mark.parametrize("start, end", [(0.5, 1.0), (1.0, 0.6)])
def test_infant_schedule_is_monotone_concave_and_hits_both_ends(start, end):
    g = Growth(period=200, start_size=start, end_size=end, schedule="infant")
    s = g.sizes(EPOCHS)
    assert s[0] == start and s[200] == pytest.approx(end, abs=1e-15)
    assert (s[200:] == s[200]).all()
    rise = np.sign(end - start) * np.diff(s[:201])
    assert (rise > 0).all(), "monotone during growth"
    assert (np.diff(rise) < 0).all(), "fast early, then slowing (concave)"
    lin = Growth(period=200, start_size=start, end_size=end).sizes(EPOCHS)
    assert (np.sign(end - start) * (s - lin)[1:200] > 0).all(), "ahead of linear growth"
    # the first half of the period brings 69 % of the growth (WHO: 0-12 of 0-24 months)
    assert (s[100] - start) / (end - start) == pytest.approx(0.694, abs=1e-3)


@pytest.mark.parametrize("name", ["arm2", "arm5", "icub"])
@pytest.mark.parametrize("schedule", ["linear", "infant"])
def test_proximal_first_keeps_the_total_length(name, schedule):
    body = gbmodel.make_body(name)
    seg = np.hypot(body.a, body.d)
    g = Growth(pattern="proximal_first", period=200, schedule=schedule).validate(body)
    sizes = g.sizes(EPOCHS)
    scales = g.scales(body, sizes)
    assert scales.shape == (len(EPOCHS), body.m)
    # the total length is proportional growth's at every epoch
    np.testing.assert_allclose(scales @ seg, sizes * seg.sum(), rtol=1e-12)
    # every segment starts at start_size and ends at end_size: the bodies of proportional growth
    proportional = Growth(period=200, schedule=schedule).scales(body, sizes)
    np.testing.assert_allclose(scales[0], proportional[0], atol=1e-15)
    np.testing.assert_allclose(scales[200:], proportional[200:], atol=1e-15)
    # during growth, along the chain (segments of non-zero length), proximal >= distal
    grown = scales[1:200][:, seg > 0]
    assert (np.diff(grown, axis=1) <= 1e-15).all()
    assert (grown[:, 0] > grown[:, -1]).all(), "the first segment strictly ahead of the last"
    assert (np.diff(scales[:201], axis=0) >= 0).all(), "every segment grows monotonically"


def test_proximal_first_on_arm5_by_numbers():
    body = gbmodel.make_body("arm5")
    g = Growth(pattern="proximal_first", period=10)
    np.testing.assert_allclose(g.scales(body, 0.75), [0.875, 0.8125, 0.75, 0.6875, 0.625])
    np.testing.assert_allclose(Growth(pattern="proximal_first", proximal_lead=0.0).scales(
        body, 0.75), 0.75)
    # the straight arm reaches its total length
    scale = g.scales(body, 0.6)
    assert body.forward(np.zeros(5), scale) == pytest.approx([0.6, 0.0])


def test_proximal_first_runs_in_a_trial():
    spec = gbmodel.TrialSpec(growth={"pattern": "proximal_first", "period": 20,
                                     "schedule": "infant"},
                             learner={"name": "goal_babbling", "fast": False}, epochs=30)
    r = gbmodel.run_trial(spec, np.random.default_rng(0))
    np.testing.assert_allclose(r.size, spec.make_growth().sizes(r.epoch))
    assert r.size[-1] == 1.0 and np.isfinite(r.abs_error).all()


def test_growth_validation_names_the_field():
    arm5 = gbmodel.make_body("arm5")
    for kwargs, key in [(dict(schedule="cubic"), "growth.schedule"),
                        (dict(pattern="distal_first"), "growth.pattern"),
                        (dict(proximal_lead=1.5), "growth.proximal_lead"),
                        (dict(proximal_lead=-0.1), "growth.proximal_lead"),
                        (dict(start_size=0.0), "growth.start_size"),
                        (dict(period=-3), "growth.period")]:
        with pytest.raises(SpecError, match=f"^{key}=") as err:
            Growth(**kwargs).validate(arm5)
        assert err.value.key == key


# ---- growth as data: every pattern is per-segment data for one mechanism ----------

def test_per_segment_leads_are_the_one_mechanism_behind_proximal_first():
    """proximal_first is per_segment with its computed leads, to the bit."""
    body = gbmodel.make_body("icub")
    pf = Growth(pattern="proximal_first", period=200, proximal_lead=0.6)
    _, leads = pf.segments(body)
    ps = Growth(pattern="per_segment", period=200, proximal_lead=0.6, leads=leads.tolist())
    sizes = pf.sizes(EPOCHS)
    np.testing.assert_array_equal(ps.validate(body).scales(body, sizes), pf.scales(body, sizes))


def test_stated_rates_grow_the_upper_arm_ahead():
    """"The upper arm grows faster than the forearm" at stated rates is a config."""
    body = gbmodel.make_body("arm5")
    g = Growth(pattern="per_segment", period=100, leads=[0.8, 0.4, 0.0, -0.4, -0.8])
    k = g.validate(body).scales(body, g.sizes(EPOCHS))
    np.testing.assert_allclose(k[50], [0.85, 0.8, 0.75, 0.7, 0.65])  # p = 1/2: 0.75 +- 0.5 c / 4
    assert k[0].tolist() == [0.5] * 5 and k[100].tolist() == [1.0] * 5
    assert (np.diff(k[:101], axis=0) >= 0).all()


def test_the_patterns_as_data():
    """Each named pattern is (grows, leads) per segment: no code of its own."""
    body = gbmodel.make_body("arm5")
    grows, leads = Growth(pattern="nonproportional").segments(body)
    assert grows.tolist() == [True, False, True, False, True] and not leads.any()
    grows, leads = Growth(pattern="proportional").segments(body)
    assert grows.all() and not leads.any()
    # the body's file says which segments grow
    body3 = gbmodel.make_body("arm5", grows=[True, True, False, False, False])
    k = Growth(pattern="nonproportional").scales(body3, 0.8)
    assert k[2:].tolist() == [1.0] * 3 and k[0] == k[1] == pytest.approx(0.5)


@pytest.mark.parametrize("kwargs", [dict(pattern="per_segment"),
                                    dict(pattern="per_segment", leads=[0.5] * 4),
                                    dict(pattern="per_segment", leads=[1.5, 0, 0, 0, 0]),
                                    dict(pattern="proportional", leads=[0.0] * 5)])
def test_leads_are_checked(kwargs):
    with pytest.raises(SpecError, match="^growth.leads="):
        Growth(**kwargs).validate(gbmodel.make_body("arm5"))


@pytest.mark.parametrize("growth", [
    dict(pattern="proportional"), dict(pattern="nonproportional"),
    dict(pattern="nonproportional", fixed_scale=0.5, start_size=0.5, end_size=0.6),
    dict(pattern="proximal_first"), dict(pattern="per_segment", leads=[0.5, 0.2, 0, -0.2, -0.5])])
def test_every_pattern_draws_its_postures(growth):
    """The posture figures (Fig. 3) take every pattern."""
    import matplotlib
    matplotlib.use("Agg")
    from pipeline.studies import figures
    spec = gbmodel.TrialSpec(growth={**growth, "period": 10}, epochs=5,
                             learner={"name": "goal_babbling", "fast": False, "degree": 3}).to_dict()
    M = gbmodel.run_trial(gbmodel.TrialSpec.from_dict(spec), np.random.default_rng(0)).M
    fig = figures.postures([("a", spec, M)], "test")
    body, size, g, _ = figures.final_body(spec)
    np.testing.assert_allclose(body.frame_points(body.home, g.scales(body, size))[-1, :2],
                               body.forward(body.home, g.scales(body, size)), atol=1e-15)
    assert fig.axes
