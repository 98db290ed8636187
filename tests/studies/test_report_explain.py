"""The report stage only reads: the decisive experiments are experiments of the plan, and the
report draws from their aggregates without starting a trial."""
import numpy as np
import pytest

import gbmodel
from gbmodel.learners import goal_babbling as gb
from pipeline import aggregate, report, simulate
from pipeline.config import compose


def test_the_step_schedule_lowers_the_rate_after_its_epoch():
    p = gb.Params(rate_schedule="step", rate_step_epoch=3, rate_step_factor=0.1,
                  learning_rate=0.5).validate()
    assert np.allclose(p.rates([1, 2, 3, 4, 5]), [0.5, 0.5, 0.5, 0.05, 0.05])
    with pytest.raises(ValueError, match="rate_step_factor"):
        gb.Params(rate_schedule="step", rate_step_factor=0.0).validate()


def test_the_explanation_experiments_are_planned_like_any_other():
    from pipeline.plan import plan
    b = plan(compose(["experiment=explain_fig2_boundary"]))
    assert {t["spec"]["body"]["grid"]["hi"][0] if t["spec"]["body"].get("grid") else 1.0
            for t in b} == {1.0, 0.9, 0.8}
    c = plan(compose(["experiment=explain_fig7_continuation"]))
    assert {t["spec"]["learner"]["rate_schedule"] for t in c} == {"constant", "step"}
    assert {t["spec"]["epochs"] for t in c} == {101000}


def test_the_report_stage_starts_no_trial(tmp_path, monkeypatch):
    over = ["learner.epochs=20", "trials.count=2", "workers=1", f"paths.root={tmp_path}"]
    for exp in ("fig2", "explain_fig2_boundary", "explain_fig7_continuation"):
        simulate.simulate(compose([f"experiment={exp}", *over]))
    cfg = compose(over)
    aggregate.aggregate(cfg)

    def refuse(*a, **k):
        raise AssertionError("the report stage started a trial")
    monkeypatch.setattr(gbmodel, "run_trial", refuse)
    for learner in (gb,):
        monkeypatch.setattr(learner, "train", refuse)
    report.report(cfg)
    text = (tmp_path / "outputs" / "latest" / "report.md").read_text()
    assert "boundary (explain_fig2_boundary)" in text
    assert "continuation (explain_fig7_continuation)" in text
    # Fig. 2 at 20 epochs declares the paper's claims, but is not the paper's scale: it says so
    assert text.startswith("# Paper experiments at a custom scale (not the paper's): ")
    assert "Reproduction" not in text.splitlines()[0]
