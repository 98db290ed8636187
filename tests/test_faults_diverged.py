"""A condition all of whose trials diverged: aggregate names it, the report marks its cells and
the claims it touches as diverged and goes on (it crashed in the claims before)."""
from pathlib import Path

import pytest

from pipeline import aggregate, report, simulate
from pipeline.config import compose
from pipeline.studies import claims

# a learning rate 57 times the arm's: every trial of const1.0 diverges, some of the others
ARGS = ["experiment=fig4", "figure=f4", "learner.epochs=2000", "trials.count=2", "workers=1",
        "learner.learning_rate=0.05"]


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    cfg = compose([*ARGS, f"paths.root={tmp_path_factory.mktemp('div')}"])
    simulate.simulate(cfg)
    return cfg


def test_aggregate_names_the_diverged_condition_and_report_marks_it(run, capsys):
    assert aggregate.aggregate(run, explicit=True) == []
    assert "note: [f4] const1.0: every trial diverged or failed" in capsys.readouterr().err
    report.report(run, explicit=True)
    md = (Path(run.paths.report) / "report.md").read_text()
    row = next(ln for ln in md.splitlines() if ln.startswith("| f4 | const1.0 |"))
    assert row.count("| diverged |") >= 1, row
    verdicts = [ln for ln in md.splitlines() if "| diverged: const1.0 |" in ln]
    assert len(verdicts) == len(claims.REFERENCE_CLAIMS)


def test_claims_of_a_figure_without_a_reference_curve_do_not_crash(run):
    aggs = report.load_aggregates(Path(run.paths.aggregate))
    rows = claims.growth_claims("f4", aggs["f4"]["curves"], aggs["f4"]["summary"])
    assert claims.diverged_conditions(aggs["f4"]["summary"]) == ["const1.0"]
    final = next(r for r in rows if r["claim"].startswith("final error"))
    assert "const1.0 diverged" in final["verdict"]
