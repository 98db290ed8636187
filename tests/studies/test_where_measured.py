"""Where the error is measured (issue 58): the readings of the final error and the rise on the
grid, the path targets and uniform points, the last decade's mean, each cell's margin, and the
headline's counts under the criteria as first fixed and the reading selected after the data; on
synthetic curves with known answers."""
import numpy as np
import pandas as pd
import pytest

from pipeline.studies import claims, measures_table
from pipeline.studies import scorecard as sc
from tests.studies.coverage_tables import covered

EPOCHS = np.array([1, 2, 5, 10, 11, 20, 50, 100])
RISING = np.array([0.2, 0.3, 0.4, 0.5, 0.45, 0.2, 0.1, 0.02])


def _figure(path_scale=0.5, uniform_scale=0.8, n=4, seed=5):
    """A figure whose path-target error is `path_scale` and uniform-point error `uniform_scale`
    times its grid error, every epoch; the paper's value 20 mm."""
    rng = np.random.default_rng(seed)
    rows, summ = [], []
    conds = [("TG10", RISING, 1.0, "proportional", 10),
             ("const0.5", np.linspace(0.2, 0.01, len(EPOCHS)), 0.5, "none", 0),
             ("const1.0", np.linspace(0.4, 0.02, len(EPOCHS)), 1.0, "none", 0)]
    for name, err, size, growth, period in conds:
        for t in range(n):
            e = err * (1 + 0.01 * rng.standard_normal(len(EPOCHS)))
            rows += [dict(condition=name, trial=t, epoch=ep, abs_error=a, rel_error=a / size,
                          path_abs_error=path_scale * a, uniform_abs_error=uniform_scale * a)
                     for ep, a in zip(EPOCHS, e)]
        summ.append(dict(condition=name, growth=growth, growth_period=period, end_size=size,
                         paper_final_abs_error=0.02, n_bootstrap_failures=0, n_run_failures=0,
                         n_diverged=0, n_trials=n))
    return pd.DataFrame(rows), pd.DataFrame(summ)


def _results(**kw):
    trials, summary = _figure(**kw)
    return sc.results({"figX": dict(trials=trials, summary=summary)}, table=covered(0.95))


def _final(results, reading, where="const1.0"):
    return next(r for r in results if r["claim"] == "final" and r["where"] == where
                and r["reading"] == reading)


def test_each_reading_judges_the_error_where_it_says_it_is_measured():
    t = _results()
    grid = _final(t, "metres, full size two-sided")["value"]
    assert grid == pytest.approx(0.02 / 0.02, rel=0.03)  # const1.0 ends at 20 mm on the grid
    assert _final(t, "")["value"] == pytest.approx(0.5 * grid)  # the primary: path targets
    assert _final(t, "uniform points, full size two-sided")["value"] == pytest.approx(0.8 * grid)
    # the rise is the same relative measure wherever the curve is scaled by a constant
    rises = {r["reading"]: r["value"] for r in t if r["claim"] == "rise"}
    assert rises[""] == pytest.approx(rises["per trial"]) == pytest.approx(rises["uniform points"])
    # a measure serves only the readings of its points: one final test per reading and condition
    keys = [(r["reading"], r["where"]) for r in t if r["claim"] == "final"]
    assert len(keys) == len(set(keys))


def test_the_last_decade_is_the_mean_over_the_last_decade_of_epochs_not_the_endpoint():
    t = _results()
    last = _final(t, "last decade, path targets")["value"]
    end = _final(t, "")["value"]
    decade = EPOCHS >= EPOCHS[-1] / 10  # epochs 10 ... 100
    expected = 0.5 * np.linspace(0.4, 0.02, len(EPOCHS))[decade].mean() / 0.02
    assert last == pytest.approx(expected, rel=0.03) and last > 5 * end


def test_a_register_with_an_unknown_place_of_measurement_is_refused(tmp_path):
    text = claims.REGISTER.read_text().replace("points: uniform}", "points: centre}", 1)
    (tmp_path / "r.yaml").write_text(text)
    with pytest.raises(ValueError, match="points"):
        claims.read_register(tmp_path / "r.yaml")
    assert set(claims.PARAMS["points"]) == set(claims.POINTS)


@pytest.mark.parametrize("interval, bounds, verdict, expected", [
    ((0.84, 0.88), (1 / 1.5, 1.5), sc.REPRODUCED, (1 / 1.5, 0.84)),  # the nearer bound moves in
    ((0.06, 0.08), (0.1, np.inf), sc.NOT, (0.1, 0.08)),  # down onto the interval's top
    ((1.6, 1.9), (1 / 1.5, 1.5), sc.NOT, (1.5, 1.6)),
    ((0.07, 0.14), (0.1, np.inf), sc.INCONCLUSIVE, (0.1, 0.07)),  # past the nearer end: decided
    ((np.nan, np.nan), (0.1, np.inf), sc.INCONCLUSIVE, (np.nan, np.nan)),
])
def test_the_margin_is_where_the_bound_would_have_to_move_to_change_the_verdict(
        interval, bounds, verdict, expected):
    assert sc.verdict(*interval, *bounds) == verdict
    got = sc.flip(*interval, *bounds, verdict)
    np.testing.assert_allclose(got, expected)
    if np.isfinite(got[1]):  # moved there (and a hair beyond), the verdict changes
        lo, hi = bounds
        nudge = 1e-9 * np.sign(got[1] - got[0])
        moved = (got[1] + nudge, hi) if got[0] == lo else (lo, got[1] + nudge)
        assert sc.verdict(*interval, *moved) != verdict


def test_every_counted_cell_shows_its_margin():
    cards = sc.cells(_results())
    text = sc.cell_text(cards.set_index("claim").loc["final"].to_dict())
    assert "margin: its bound" in text and "would change it" in text


def test_the_headline_says_what_the_criteria_as_first_fixed_give_and_which_have_none():
    t = _results(path_scale=1.6)  # path targets 1.6x the grid: the primary fails at full size
    first, none = sc.first_cells(t)
    firsts = {c.id: r.id for c in claims.CLAIMS for r in c.readings if r.first}
    assert set(first["claim"]) <= set(firsts) and "final" in set(first["claim"])
    assert "rise_none" in none and "stages" in none
    primary = sc.cells(t).set_index("claim")
    assert primary.loc["final", "verdict"] == sc.NOT  # 1.6x on the path targets
    # as first fixed: the grid, every condition two-sided: the half-size arm's 0.5x fails it
    got = first.set_index("claim").loc["final"]
    assert (got["verdict"], got["where"]) == (sc.NOT, "const0.5")
    assert got["value"] == pytest.approx(0.5, rel=0.03)
    text = sc.first_headline(t)
    assert text.startswith("The criteria as first fixed, before the first run's data")
    assert "rise_none" in text


def test_the_recommended_reading_is_labelled_selected_after_the_data():
    cards = pd.DataFrame(sc.all_cells(_results())).assign(figure="fig4", reading="eta = 0.1 / W")
    text = sc.recommended_headline(cards, [dict(figure="fig4", reading="eta = 0.1 / W")])
    assert "**selected after the data**" in text


def test_measures_keep_where_they_were_measured_through_the_table(tmp_path):
    trials, summary = _figure()
    ms = claims.measures("figX", trials, summary)
    assert {(m.points, m.span) for m in ms if m.claim == "final"} == {
        (p, s) for p in claims.POINTS for s in ("end", claims.LAST_DECADE)}
    path = measures_table.write(tmp_path / "m.parquet", [measures_table.frame(ms, "figures")])
    back = measures_table.measures(measures_table.read(path))[("figures", "", "figX")]
    assert sorted((m.claim, m.where, m.points, m.span) for m in back) == sorted(
        (m.claim, m.where, m.points, m.span) for m in ms)
    old = pd.read_parquet(path).drop(columns=["points", "span"])  # a table from before
    old.to_parquet(tmp_path / "old.parquet")
    assert set(measures_table.read(tmp_path / "old.parquet")["points"]) == {"grid"}


def test_the_committed_models_give_the_committed_path_target_errors():
    """Rescoring the committed Fig. 7 models (20 trials) on the path targets and the uniform
    points, with no retraining, gives the report's own final errors there (summary.csv)."""
    from gbmodel import evaluation
    from pipeline import models
    from pipeline.config import REPO_ROOT

    report = REPO_ROOT / "outputs" / "report"
    summary = pd.read_csv(report / "summary.csv").set_index(["figure", "condition"])
    m = models.load(report / "models" / "fig7_20trials.json")["const1.0"]
    body, size = m.body, m.size
    sets = dict(path=evaluation.path_targets(body, m.spec.learner["steps"], size),
                uniform=evaluation.heldout_points(body, size)[-evaluation.HELDOUT_UNIFORM:])
    for name, xs in sets.items():
        again = np.mean([np.linalg.norm(m.reach(xs, t) - xs, axis=-1).mean() for t in m.M])
        want = summary.loc[("fig7_20trials", "const1.0"), f"final_{name}_abs_error_mean"]
        assert again == pytest.approx(want, rel=1e-5), name
