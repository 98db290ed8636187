"""A condition all of whose trials diverged: aggregate names it, the report marks its summary row
and every scorecard cell it touches as diverged and goes on (it crashed in the claims before)."""
from pathlib import Path

import pandas as pd
import pytest

from pipeline import aggregate, report, simulate
from pipeline.config import compose
from pipeline.studies import claims, scorecard

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
    out = Path(run.paths.report) / "f4"  # a named figure reports into its own folder
    md = (out / "report.md").read_text()
    row = next(ln for ln in md.splitlines() if ln.startswith("| f4 | const1.0 |"))
    assert row.count("| diverged |") >= 1, row
    table = pd.read_csv(out / "claims.csv")
    marked = table[table["verdict"] == claims.DIVERGED]
    assert {"final", "blend"} <= set(marked["claim"]), table[["claim", "verdict"]]
    assert (marked["worst"] == "const1.0").all()
    assert "diverged" in md.split("## Files")[0]


def test_the_claims_of_a_figure_without_a_reference_curve_are_marked_not_crashed(run):
    aggs = report.load_aggregates(Path(run.paths.aggregate))
    summary = aggs["f4"]["summary"]
    assert claims.diverged_conditions(summary) == ["const1.0"]
    tests = claims.judge(claims.measures("f4", aggs["f4"]["trials"], summary))
    dead = [t for t in tests if t.diverged]
    assert dead and all(t.where == "const1.0" for t in dead)
    assert not any(t.claim in ("above_refs", "above_start") for t in tests)  # no reference pair
    cards = scorecard.cells([scorecard.run_test(t) for t in tests])
    assert cards.set_index("claim").loc["final", "verdict"] == claims.DIVERGED
