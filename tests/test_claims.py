"""The measures behind the report's verdicts, on synthetic curves with known answers."""
import numpy as np
import pandas as pd
import pytest

from pipeline import report
from pipeline.studies import claims
from pipeline.measures import growth_peak

EPOCHS = np.array([1, 2, 5, 10, 11, 20, 50, 100])


def test_growth_peak_is_the_largest_rise_above_the_running_minimum():
    curve = pd.DataFrame(dict(epoch=EPOCHS, abs_error_mean=[5, 4, 3, 6, 5, 2, 2.5, 1]))
    assert growth_peak(curve) == (10, 6.0, 3.0)
    falling = pd.DataFrame(dict(epoch=EPOCHS, abs_error_mean=np.linspace(5, 1, len(EPOCHS))))
    assert growth_peak(falling)[2] == 0.0


def _figure(grown):
    """Curves and summary of a figure: references falling from 0.4 and 0.2 m, and a body grown
    over 10 epochs whose absolute error is `grown` (relative error: the same over its size)."""
    short = np.linspace(0.2, 0.01, len(EPOCHS))
    long_ = np.linspace(0.4, 0.02, len(EPOCHS))
    size = np.clip(0.5 + 0.05 * (EPOCHS - 1), 0.5, 1.0)
    rows = []
    for name, err, s in [("TG10", grown, size), ("const0.5", short, 0.5), ("const1.0", long_, 1.0)]:
        rows += [dict(condition=name, epoch=e, abs_error_mean=a, rel_error_mean=a / si)
                 for e, a, si in zip(EPOCHS, err, np.broadcast_to(s, EPOCHS.shape))]
    curves = pd.DataFrame(rows)
    during = curves[(curves.condition == "TG10") & (curves.epoch <= 11)]
    ep, peak, rise = growth_peak(during)
    base = dict(paper_final_abs_error=0.02, n_bootstrap_failures=0, n_run_failures=0, n_trials=5)
    summary = pd.DataFrame([
        dict(condition="TG10", growth="proportional", growth_period=10, end_size=1.0,
             final_abs_error_mean=grown[-1], peak_abs_error_growth=peak,
             rise_abs_error_growth=rise, peak_epoch_growth=ep, **base),
        dict(condition="const0.5", growth="none", growth_period=0, end_size=0.5,
             final_abs_error_mean=short[-1], **base),
        dict(condition="const1.0", growth="none", growth_period=0, end_size=1.0,
             final_abs_error_mean=long_[-1], **base),
    ])
    return curves, summary


def _verdicts(grown):
    rows = claims.growth_claims("figX", *_figure(np.asarray(grown, float)))
    return {r["claim"].split(",")[0].split(" (")[0]: r["verdict"] for r in rows}


def test_a_body_that_rises_during_growth_and_then_learns_reproduces_the_claims():
    # rises from 0.2 to 0.5 m while growing (epochs 1-11), then falls to the long reference's end
    v = _verdicts([0.2, 0.3, 0.4, 0.5, 0.45, 0.2, 0.1, 0.02])
    assert v["the absolute error rises temporarily during growth for T_G in {10"] == "reproduced"
    assert v["the absolute error rises above both constant-size references during growth"] \
        == "reproduced"
    assert v["final error about 20.0 mm"].startswith("not reproduced: const0.5")
    assert v["bootstrapping succeeds in every trial"] == "reproduced"


def test_a_body_that_never_rises_fails_the_rise_claims():
    v = _verdicts(np.linspace(0.2, 0.02, len(EPOCHS)))
    assert v["the absolute error rises temporarily during growth for T_G in {10"] \
        == "not reproduced: T_G=10"
    assert v["the absolute error rises above both constant-size references during growth"] \
        == "not reproduced: T_G=10"


def test_a_rebound_after_growth_is_degeneration():
    v = _verdicts([0.2, 0.3, 0.4, 0.5, 0.45, 0.05, 0.2, 0.02])
    assert v["no degeneration: the error keeps decreasing after growth"].startswith(
        "not reproduced")


def test_the_discussion_is_shown_only_beside_the_numbers_it_was_written_for(tmp_path,
                                                                            monkeypatch):
    """findings.md is included when findings_numbers.csv matches the run (the same rows and
    verdicts, numbers within report.TOLERANCE), and left out otherwise, or when nothing was
    stamped."""
    text = "## Why\n\nBecause 17.5 mm.\n"
    (tmp_path / "findings.md").write_text(text)
    monkeypatch.setattr(report, "FINDINGS", tmp_path / "findings.md")
    monkeypatch.setattr(report, "FINDINGS_NUMBERS", tmp_path / "findings_numbers.csv")
    curves, summary = _figure(np.array([0.2, 0.3, 0.4, 0.5, 0.45, 0.2, 0.1, 0.02]))
    summary["figure"] = "figX"
    summary["final_rel_error_mean"] = summary["final_abs_error_mean"] / summary["end_size"]
    rows = claims.growth_claims("figX", curves, summary)
    assert "left out" in report.findings(summary, rows)  # nothing stamped yet
    report.stamp_findings(summary, rows)
    assert report.findings(summary, rows) == text
    other = summary.copy()
    other.loc[0, "final_abs_error_mean"] *= 1 + 1e-4  # another run
    assert "left out" in report.findings(other, rows)
    assert "left out" in report.findings(summary.iloc[:2], rows)  # a condition fewer
    flipped = [dict(r, verdict="reproduced") for r in rows]
    assert flipped != rows and "left out" in report.findings(summary, flipped)


@pytest.mark.parametrize("spread, verdict", [(0.06, "reproduced"), (0.5, "not reproduced")])
def test_fig2_stages_start_near_home(spread, verdict):
    import gbmodel

    body = gbmodel.make_body("arm2")
    exps = gbmodel.exponents(1)
    start = np.zeros((2, len(exps)))
    start[0, 0] = spread  # g(x) = home + (spread, 0) everywhere
    final = np.zeros((2, len(exps)))
    final[0, 1] = np.pi / 2  # q1 = pi/2 * x: reaches heights +-1 m exactly, and 0 at home
    spec = dict(body=dict(name="arm2"), growth=dict(pattern="proportional", end_size=1.0),
                learner=dict(name="goal_babbling", degree=3))
    rows = claims.stage_claims("fig2", spec, [("(a)", start), ("(b)", final)])
    assert rows[0]["verdict"].startswith(verdict)
