"""The calibration from a replicate set (pipeline/studies/replicate.py), on synthetic data whose
answer is known, and once end to end on a smoke run of fig4 and its replicate."""
import numpy as np
import pandas as pd
import pytest
from scipy import stats

from pipeline.studies import coverage, replicate, scorecard
from pipeline.studies.claims import Measure

EMPTY = pd.DataFrame(columns=coverage.COLUMNS)  # no coverage table: fresh samples decide


def _shares(n1: int, n2: int, draws: int = 2000, seed: int = 0) -> tuple[float, float]:
    """(prediction interval, plain t interval of the first set): the share of `draws` pairs of
    normal samples whose 95 % interval from the first covers the replicate's mean."""
    rng = np.random.default_rng(seed)
    pred = plain = 0
    for _ in range(draws):
        a, b = rng.normal(3.0, 2.0, n1), rng.normal(3.0, 2.0, n2)
        _, lo, hi = replicate.prediction(a, n2, 0.95)
        pred += lo <= b.mean() <= hi
        _, lo, hi = scorecard.interval(a, 0.95)
        plain += lo <= b.mean() <= hi
    return pred / draws, plain / draws


def test_the_prediction_interval_covers_a_replicate_mean_at_its_level_the_t_interval_does_not():
    pred, plain = _shares(20, 20)
    assert 0.935 <= pred <= 0.965  # 2000 draws: the binomial sd is 0.005
    # the first set's own t interval ignores the replicate's noise: ~83 % (2 Phi(1.96 / sqrt 2) - 1)
    assert 0.80 <= plain <= 0.86
    pred, _ = _shares(20, 5, seed=1)  # a smaller replicate: wider, still at its level
    assert 0.935 <= pred <= 0.965


def test_the_prediction_interval_is_the_t_interval_widened_by_the_replicates_noise():
    v = np.array([1.0, 2.0, 4.0, 3.0, 5.0])
    m, lo, hi = replicate.prediction(v, 10, 0.99)
    _, tlo, thi = scorecard.interval(v, 0.99)
    assert m == 3.0
    assert np.isclose((hi - lo) / (thi - tlo), np.sqrt(1 + 5 / 10))
    assert np.isnan(replicate.prediction([1.0], 5, 0.95)[1])


def test_the_expected_range_is_the_exact_binomials_and_a_low_share_fails():
    assert replicate.expected_range([0.95] * 60) == tuple(
        int(x) for x in stats.binom.interval(0.95, 60, 0.95))
    lo, hi = replicate.expected_range([0.95] * 30 + [0.99] * 30)
    assert (lo, hi) >= replicate.expected_range([0.95] * 60) and hi == 60
    low = stats.binom.interval(0.95, 60, 0.95)[0]
    table = pd.DataFrame(dict(
        figure=["f"] * 60 + ["g"] * 60, claim=["a"] * 60 + ["b"] * 60, where="w",
        deciding=False, level=0.95,
        covered=[i >= 60 - low + 1 for i in range(60)] + [i >= 60 - low for i in range(60)]))
    s = replicate.summary(table).set_index("claim")
    assert s.loc["a", "covered"] == low - 1 and s.loc["a", "fails"]
    assert s.loc["b", "covered"] == low and not s.loc["b", "fails"]
    assert replicate.failing(table) == {("f", "a")}
    assert replicate.failing(table, scale="smoke") == set()  # no verdict at a reduced scale


def _final(where: str, values) -> Measure:
    """A final-error measure where the primary reading measures it (the path targets)."""
    return Measure("figX", "final", where, np.asarray(values, float), unit="x", kind="final",
                   points="path")


def test_a_shifted_replicate_is_not_covered_and_its_cell_fails():
    rng = np.random.default_rng(3)
    first = [_final("only", rng.normal(1.0, 0.1, 20))]
    same = [_final("only", rng.normal(1.0, 0.1, 20))]
    shifted = [_final("only", rng.normal(2.0, 0.1, 20))]
    ok = pd.DataFrame(replicate.rows("figX", first, same, table=EMPTY))
    bad = pd.DataFrame(replicate.rows("figX", first, shifted, table=EMPTY))
    assert list(ok["covered"]) == [True] and list(bad["covered"]) == [False]
    r = bad.iloc[0]
    assert (r["claim"], r["where"], r["n1"], r["n2"], bool(r["deciding"])) == (
        "final", "only", 20, 20, True)
    assert np.isclose(r["mean"], first[0].values.mean())
    assert replicate.failing(ok) == set() and replicate.failing(bad) == {("figX", "final")}


def test_only_counted_primary_measures_paired_by_their_key_are_judged():
    rng = np.random.default_rng(4)
    first = [_final("a", rng.normal(1, 0.1, 20)), _final("b", rng.normal(1, 0.1, 20)),
             Measure("figX", "bootstrap", "0 of 40 trials failed", np.array([0, 40]),
                     unit="rate", exact=True)]
    second = [_final("a", rng.normal(1, 0.1, 20)),  # no "b": nothing to pair it with
              Measure("figX", "bootstrap", "0 of 40 trials failed", np.array([0, 40]),
                      unit="rate", exact=True)]
    other = _final("a", rng.normal(5, 0.1, 20))
    other.points = "grid"  # another evaluation point: another key, not paired with "a"
    got = replicate.rows("figX", first, second + [other], table=EMPTY)
    assert [(r["claim"], r["where"]) for r in got] == [("final", "a")]  # one primary reading
    assert got[0]["covered"]


@pytest.mark.slow
def test_a_smoke_run_of_fig4_and_its_replicate_writes_the_calibration(tmp_path):
    """fig4 and replicate_fig4 at smoke scale (~50 s): calibration.csv, the section saying it is
    no verdict, and the replicate's measures in measures.parquet."""
    from conftest import run_cli

    for stage in ("simulate", "aggregate", "report"):  # as make smoke runs them
        r = run_cli(f"pipeline.{stage}", "experiments=[fig4,replicate_fig4]", "profile=smoke",
                    f"paths.root={tmp_path}", timeout=600)
        assert r.returncode == 0, r.stderr[-2000:]
    out = tmp_path / "outputs" / "smoke" / "latest"
    cal = pd.read_csv(out / "calibration.csv")
    assert set(cal["figure"]) == {"fig4"} and (cal["n2"] == 2).all() and len(cal) > 10
    assert {"final", "rise"} <= set(cal["claim"])
    text = (out / "report.md").read_text()
    assert "## Calibration" in text and "not a verdict at that scale" in text
    t = pd.read_parquet(out / "measures.parquet")
    rep = t[t["study"] == "replicate"]
    assert len(rep) and set(rep["figure"]) == {"fig4"}
    assert len(rep) == len(t[t["study"] == "figures"])  # the same conditions, trials, measures


def _ctx(tmp_path, groups: dict):
    from types import SimpleNamespace

    from pipeline.studies.sections import Context

    return Context(SimpleNamespace(report=SimpleNamespace(scale="")), tmp_path, "t", groups)


def test_a_report_without_a_replicate_set_has_no_section_and_one_without_its_figure_says_so(
        tmp_path):
    fig4 = {"summary": pd.DataFrame(), "models": {}}
    assert replicate.section(_ctx(tmp_path, {"figures": {"fig4": fig4}})) == []
    assert replicate.frames(_ctx(tmp_path, {"figures": {"fig4": fig4}})) == []
    alone = replicate.section(_ctx(tmp_path, {"replicate": {"replicate_fig4": fig4}}))
    assert "replicate_fig4 (of fig4)" in "\n".join(alone) and "nothing to calibrate" in alone[2]
    assert not (tmp_path / "calibration.csv").exists()
