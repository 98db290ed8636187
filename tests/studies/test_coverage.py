"""Coverage on fresh samples, per measure: the model, the calibrated level, and the committed
table that docs/scorecard.md shows."""
import numpy as np
import pandas as pd
import pytest

from pipeline.config import REPO_ROOT
from pipeline.studies import coverage


def test_a_normal_measure_is_covered_at_95_and_a_skewed_one_is_not():
    rng = np.random.default_rng(0)
    normal = rng.standard_normal(20)
    cov = coverage.fresh(normal, 5, 4000, seed=1)
    assert 0.90 <= cov[0.95] <= 0.97
    skewed = np.r_[np.full(19, 0.1) + 0.01 * rng.standard_normal(19), 1.0]  # one outlier
    cov = coverage.fresh(skewed, 20, 4000, seed=1)
    assert cov[0.95] < coverage.MIN_COVERAGE  # the t interval misses: the outlier decides
    level, c = coverage.calibrated(cov)
    assert level is None or (level > 0.95 and c >= coverage.MIN_COVERAGE)


def test_the_same_values_give_the_same_row():
    v = np.linspace(0, 1, 20) ** 3
    assert coverage.row("f", "c", "w", "k", v, 5) == coverage.row("f", "c", "w", "k", v, 5)


def test_the_committed_table_is_drawn_from_the_committed_reports_per_trial_values():
    """coverage.csv is the generator's output on outputs/report (checked on a sample of its
    rows: the whole table takes ~15 s)."""
    committed = coverage.read_table()
    assert set(committed["trials"]) == set(coverage.COUNTS)
    values = coverage.per_trial_values(REPO_ROOT / "outputs" / "report")
    have = {(r["figure"], r["claim"], r["where"]) for r in values.to_dict("records")
            if len(r["values"]) >= coverage.FIT}
    assert have == set(zip(committed["figure"], committed["claim"], committed["where"]))
    sample = committed.iloc[::37]
    by = {(r["figure"], r["claim"], r["where"]): r for r in values.to_dict("records")}
    for r in sample.to_dict("records"):
        v = by[(r["figure"], r["claim"], r["where"])]
        again = coverage.row(r["figure"], r["claim"], r["where"], v["kind"], v["values"],
                             int(r["trials"]), int(r["draws"]))
        assert again["t95"] == pytest.approx(r["t95"], abs=1e-4)
        assert (np.isnan(again["level"]) and np.isnan(r["level"])) or \
            again["level"] == pytest.approx(r["level"])


def test_docs_show_the_committed_table():
    """docs/scorecard.md shows coverage.csv as the named value coverage.table (rendered from
    values.csv, tests/studies/test_values.py); a table of another run would change it."""
    from pipeline.studies import values

    table = coverage.markdown(coverage.read_table())
    assert values.read(REPO_ROOT / "outputs" / "report" / values.FILE)["coverage.table"] == table
    assert table in (REPO_ROOT / "docs" / "scorecard.md").read_text()
    assert "{{ coverage.table }}" in (REPO_ROOT / "docs" / "templates" / "docs" / "scorecard.md").read_text()
    assert coverage.markdown(coverage.read_table().assign(t95=0.5)) != table

