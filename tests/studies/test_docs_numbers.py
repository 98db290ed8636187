"""The scorecard's calibration from the committed coverage table, and the coverage command (the
docs' numbers are named values: tests/studies/test_values.py)."""
import pandas as pd

from pipeline.studies import coverage, scorecard
from pipeline.tools import coverage as coverage_tool


def test_the_scorecard_decides_exactly_where_the_measured_coverage_allows():
    """A measure on fewer than coverage.FIT trials takes its level from the committed table:
    "not calibrated" where the table has none, the table's level where it has one."""
    import numpy as np

    from pipeline.studies.claims import Test

    t = coverage.read_table()
    assert t["level"].isna().any() and t["level"].notna().any()
    for r in t[t["trials"] < coverage.FIT].iloc[::23].itertuples():
        test = Test(r.figure, r.claim if r.claim in scorecard.BY_ID else "final", r.where,
                    np.linspace(1, 2, int(r.trials)), measure=r.claim)
        level, _ = coverage.calibration(test, int(r.trials), t)
        rows = t[(t["claim"] == r.claim) & (t["where"] == r.where) & (t["trials"] == r.trials)
                 & t["figure"].str.startswith(r.figure)]
        want = None if rows["level"].isna().any() else float(rows["level"].max())
        assert level == want


def test_the_coverage_command_refuses_a_folder_without_measures(tmp_path, capsys):
    assert coverage_tool.main([str(tmp_path)]) == 2
    assert capsys.readouterr().err.startswith("error: ")


def test_coverage_of_the_t_interval_on_independent_trials_is_near_95_percent():
    from test_claims import RISING, _figure

    from pipeline.studies import claims

    trials, summary = _figure(RISING, periods=(10, 100), n=20, noise=0.1, seed=11)
    ms = [m for m in claims.measures("figX", trials, summary) if not m.exact]
    values = pd.DataFrame([dict(figure=m.figure, claim=m.claim, where=m.where, kind=m.kind,
                                values=m.values) for m in ms])
    t = coverage.table(values, counts=(5,), draws=400)
    assert set(t["trials"]) == {5}
    assert ((t["t95"] > 0.8) & (t["t95"] <= 1.0)).all(), t
    assert set(t["claim"]) >= {"final", "rise", "after"}
