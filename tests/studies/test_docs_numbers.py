"""Numbers in the docs that come from a table: each is the table's, regenerated or compared."""
import pandas as pd

from pipeline.config import REPO_ROOT
from pipeline.studies import coverage, scorecard


def test_the_coverage_table_in_the_docs_is_coverage_csv():
    text = (REPO_ROOT / "docs" / "scorecard.md").read_text()
    shown = text[text.index(coverage.BEGIN):text.index(coverage.END) + len(coverage.END)]
    assert shown == coverage.markdown(pd.read_csv(scorecard.COVERAGE))


def test_the_scorecard_decides_exactly_where_the_measured_coverage_allows():
    t = pd.read_csv(scorecard.COVERAGE)
    assert {"final", "rebound", "excess", "ratio"} <= set(t["kind"])
    for r in t.itertuples():  # "not reproduced" only where the coverage reaches MIN_COVERAGE
        assert scorecard.established(r.kind, int(r.trials), t) == (r.coverage >= scorecard.MIN_COVERAGE)
    assert not scorecard.established("rebound", 2, t)  # below the smallest count measured


def test_the_coverage_command_refuses_a_figure_that_is_not_there(tmp_path, capsys):
    assert coverage.main([str(tmp_path), "fig4"]) == 2
    assert capsys.readouterr().err.startswith("error: fig4: not aggregated")


def test_coverage_of_the_t_interval_on_independent_trials_is_near_95_percent():
    from test_claims import RISING, _figure

    trials, summary = _figure(RISING, periods=(10, 100), n=20, noise=0.1, seed=11)
    per_kind, per_measure = coverage.coverage({"figX": dict(trials=trials, summary=summary)},
                                              counts=(5,), draws=60)
    assert set(per_kind["trials"]) == {5}
    assert ((per_kind["coverage"] > 0.8) & (per_kind["coverage"] <= 1.0)).all(), per_kind
    assert set(per_measure["claim"]) >= {"final", "rise", "after"}
