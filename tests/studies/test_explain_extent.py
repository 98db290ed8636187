"""The target set's extent (explain_extent_*): the exponent, the ratios on the same seeds and the
texts follow synthetic aggregates whose answer is known; a run without them has no row."""
import numpy as np
import pandas as pd
import pytest

from pipeline.studies import explain, explain_extent

COLUMNS = ("abs_error", "path_abs_error", "uniform_abs_error")


def _agg(k: float, factors=(1.0, 0.5, 1.5), n=5, paper=0.006):
    """Per trial a base error (its seed's), times the extent factor ** k at the last epoch."""
    base = 0.007 * (1 + 0.3 * np.random.default_rng(0).random(n))
    rows, summ = [], []
    for f in factors:
        name = f"x{f:g} | const1.0"
        summ.append(dict(condition=name, variant=f"x{f:g}" + (" (conf/body/icub.yaml)"
                                                              if f == 1 else "")))
        rows += [dict(condition=name, trial=t, epoch=e, **{c: b * f ** k * (2 if e < 100 else 1)
                                                           for c in COLUMNS})
                 for t, b in enumerate(base) for e in (10, 100)]
    return dict(trials=pd.DataFrame(rows), summary=pd.DataFrame(summ),
                models={"paper": {"final_abs_error": paper}})


def test_errors_in_proportion_to_the_extent_give_k_one_and_half_at_half_the_extent():
    e = explain_extent.extent(_agg(1.0))
    assert [v["factor"] for v in e["variants"]] == [0.5, 1.0, 1.5]
    assert all(k == pytest.approx(1) for k in e["k"].values())
    half = e["variants"][0]["grid"]
    assert half["ratio"]["value"] == pytest.approx(0.5) and half["ratio"]["low"] == \
        pytest.approx(0.5)
    assert half["value"] == pytest.approx(0.5 * e["variants"][1]["grid"]["value"])
    row = explain.rows({"explain_extent_icub": _agg(1.0)})[0]
    assert row["figure"] == "fig7" and row["experiment"].startswith(
        "target-set extent (explain_extent_icub): the body's grid at x0.5, x1, x1.5")
    assert "grid: x0.5 " in row["measured"] and "(0.50 [0.50, 0.50] of x1)" in row["measured"]
    assert "scales about in proportion with the extent (k = 1.00)" in row["measured"]
    claim = explain_extent.claim("explain_extent_icub", "fig7", e)
    assert claim.startswith("Fig. 7's 6 mm") and "changes by 3.00 x on the grid" in claim


def test_the_texts_follow_the_exponent():
    flat = explain_extent.extent(_agg(0.0, factors=(1.0, 0.5, 1.25), paper=0.02))
    assert flat["k"]["grid"] == pytest.approx(0, abs=1e-12)
    assert flat["variants"][0]["path targets"]["ratio"]["value"] == pytest.approx(1)
    text = explain_extent.measured(flat)
    assert "does not change with the extent (k = 0.00)" in text and "proportion" not in text
    assert "power k = 2.00" in explain_extent.measured(explain_extent.extent(_agg(2.0)))
    named = {}
    assert explain.rows({"explain_extent_arm5": _agg(0.0, (1.0, 0.5, 1.25), paper=0.02)},
                        named)[0]["figure"] == "fig4"
    assert named["explanations.fig4.extent.path.k"] == 0.0
    assert named["explanations.fig4.extent.path.ratio_x0.5"] == 1.0
    assert explain_extent.claim("x", "fig4", flat).startswith("Fig. 4's 2 cm")
    # lowest between the smallest and the largest extent: no exponent, the sentence says so
    bowl = explain_extent.extent(_agg(0.0, factors=(1.0, 0.5, 1.25), paper=0.02))
    for v, y in zip(bowl["variants"], (20.0, 11.0, 21.0)):
        v["path targets"]["value"] = y
    assert explain_extent.lowest(bowl, "path targets") == 1.0
    assert "not as a scale" in explain_extent.claim("x", "fig4", bowl)


def test_a_run_without_them_or_without_x1_has_no_row_and_a_bad_label_is_one_line():
    assert explain.rows({}) == [] and explain_extent.extent(_agg(1.0, (0.5, 1.5))) is None
    one = explain_extent.extent(_agg(1.0, n=1))  # one trial: no interval, still a row
    assert np.isnan(one["variants"][0]["grid"]["low"])
    with pytest.raises(ValueError, match="must start with x<factor>"):
        explain_extent.factor("half size")


def test_the_extent_experiments_end_to_end(tmp_path):
    from pipeline import aggregate, report, simulate
    from pipeline.config import compose
    over = ["learner.epochs=20", "trials.count=2", "workers=1", f"paths.root={tmp_path}"]
    for exp in ("explain_extent_icub", "explain_extent_arm5"):
        simulate.simulate(compose([f"experiment={exp}", *over]))
    aggregate.aggregate(compose(over))
    report.report(compose(over))
    rows = pd.read_csv(tmp_path / "outputs" / "latest" / "explanations.csv")
    assert sorted(rows["figure"]) == ["fig4", "fig7"]
    assert rows["experiment"].str.startswith("target-set extent (explain_extent_").all()
