"""The baselines study's per-trial judgements (pipeline/studies/baselines.py) on constructed
aggregates: P(one learner beats another) and its interval, comparisons only where both learners
ran, the void-after-growth test on the memory that keeps everything (it can fail and pass), the
smoothness sentences, and the section's Markdown."""
import numpy as np
import pandas as pd
import pytest

from pipeline.studies import baselines as bl


def _aggs(body, cells, jump=0.01):
    """cells: {(learner, budget, schedule, growth): [final held-out mm per trial]} -> one study's
    aggregate (summary, per-trial curves of two epochs, models with each trial's largest jump)."""
    summary, trials, models = [], [], {}
    for i, ((learner, budget, schedule, growth), errs) in enumerate(cells.items()):
        cond = f"c{i}"
        e = np.asarray(errs, float) * 1e-3
        j = jump(learner) if callable(jump) else jump
        summary.append(dict(body=body, variant=f"{learner}, {budget}, {schedule}", growth=growth,
                            growth_period=0 if growth == "none" else 500, condition=cond,
                            final_samples=int(1e6), n_trials=len(e), n_diverged=0,
                            final_abs_error_mean=e.mean(), final_heldout_abs_error_mean=e.mean(),
                            final_heldout_abs_error_std=e.std(ddof=1) if len(e) > 1 else np.nan,
                            final_rel_error_mean=e.mean(), largest_jump_mean=j))
        for k, v in enumerate(e):
            for epoch in (0, 10):  # only the last epoch counts
                trials.append(dict(condition=cond, trial=k, epoch=epoch, samples=epoch * 1000,
                                   heldout_abs_error=v if epoch else 1.0))
        models[cond] = {"trials": {str(k): {"largest_jump": j} for k in range(len(e))}}
    return {"summary": pd.DataFrame(summary), "curves": pd.DataFrame(),
            "trials": pd.DataFrame(trials), "models": {"conditions": models}}


LOW, HIGH = [1.0, 1.1, 1.2, 1.3, 1.4], [2.0, 2.1, 2.2, 2.3, 2.4]


def test_fully_separated_samples_give_p_one_and_an_interval_above_one_half():
    p, lo, hi = bl.p_beats(LOW, HIGH)
    assert (p, hi) == (1.0, 1.0) and 0.5 < lo < 1.0
    assert bl.p_beats(HIGH, LOW) == pytest.approx((0.0, 0.0, 1 - lo))  # the mirror image


def test_identical_distributions_give_an_interval_covering_one_half():
    p, lo, hi = bl.p_beats(LOW, LOW)  # every pair of equal values ties: half each
    assert p == 0.5 and lo < 0.5 < hi
    rng = np.random.default_rng(0)
    a, b = rng.normal(size=5), rng.normal(size=5)
    p, lo, hi = bl.p_beats(a, b)
    assert lo < p < hi and lo < 0.5 < hi


def test_p_is_the_mann_whitney_statistic_over_all_pairs():
    a, b = [1.0, 3.0, 5.0], [2.0, 3.0, 6.0, 7.0]
    # pairs a < b: 1 < all 4, 3 < 6, 7 and ties 3 (half), 5 < 6, 7: 4 + 2.5 + 2 = 8.5 of 12
    assert bl.p_beats(a, b)[0] == pytest.approx(8.5 / 12)
    assert np.isnan(bl.p_beats([], b)).all()


def test_interval_is_newcombes_score_interval():
    """At its ends (x - P)^2 = z^2 V(x), Hanley and McNeil's variance with N = (n + m) / 2."""
    a, b = [1.0, 2.0, 4.0, 5.0, 7.0], [3.0, 6.0, 8.0, 9.0, 10.0]
    p, lo, hi = bl.p_beats(a, b)
    n = m = 5
    k, z2 = (n + m) / 2 - 1, 1.959963984540054 ** 2
    for x in (lo, hi):
        v = x * (1 - x) / (n * m) * (1 + k * (1 - x) / (2 - x) + k * x / (1 + x))
        assert (x - p) ** 2 == pytest.approx(z2 * v)
    assert lo < p < hi


def _same_solver_cells():
    return {(bl.GB_LSTSQ, "1M", "linear", "none"): LOW,
            (bl.GB_LSTSQ, "1M", "linear", "proportional"): LOW,
            (bl.MB, "1M", "linear", "none"): HIGH,
            (bl.MB, "1M", "linear", "proportional"): LOW,
            (bl.MB_WIDE, "1M", "linear", "none"): [9.0] * 5,
            (bl.GB_LSTSQ, "4M", "linear", "none"): LOW,  # no motor babbling at 4M
            (bl.MB, "8M", "linear", "none"): HIGH,  # no Goal Babbling (least squares) at 8M
            (bl.GB, "8M", "linear", "none"): LOW}


def test_same_solver_compares_only_where_both_ran():
    ss = bl.same_solver(bl.per_trial({"baselines_arm5": _aggs("arm5", _same_solver_cells())}))
    assert set(ss.budget) == {"1M"}
    got = {(r.rival, r.growth): r.verdict for r in ss.itertuples()}
    assert got == {(bl.MB, "no growth"): f"{bl.GB_LSTSQ} lower",
                   (bl.MB, "linear"): "no difference measured",
                   (bl.MB_WIDE, "no growth"): f"{bl.GB_LSTSQ} lower"}
    row = ss[(ss.rival == bl.MB) & (ss.growth == "no growth")].iloc[0]
    assert (row.gb_median_mm, row.rival_median_mm) == pytest.approx((1.2, 2.2))
    assert (row.gb_trials, row.rival_trials, row.p) == (5, 5, 1.0)


def test_motor_babbling_lower_is_said_when_it_is():
    cells = {(bl.GB_LSTSQ, "1M", "linear", "none"): HIGH, (bl.MB, "1M", "linear", "none"): LOW}
    ss = bl.same_solver(bl.per_trial({"baselines_icub": _aggs("icub", cells)}))
    assert list(ss.verdict) == [f"{bl.MB} lower"] and ss.p.iloc[0] == 0.0


def _memory_cells(grown_all):
    return {(bl.MEMORY_ALL, "1M", "linear", "none"): LOW,
            (bl.MEMORY_ALL, "1M", "linear", "proportional"): grown_all,
            (bl.MEMORY_ALL, "1M", "infant", "proportional"): grown_all,
            (bl.MEMORY, "1M", "linear", "none"): LOW,
            (bl.MEMORY, "1M", "linear", "proportional"): LOW,
            (bl.MEMORY, "1M", "infant", "proportional"): [x * 3 for x in LOW]}


def _void(grown_all):
    pt = bl.per_trial({"baselines_arm5": _aggs("arm5", _memory_cells(grown_all))})
    return bl.void_after_growth(pt)


def test_void_after_growth_can_pass():
    rows = _void([x * 3 for x in LOW])  # 3x worse after growing, no overlap
    test = [r for r in rows if r["argument"] == bl.VOID]
    assert [r["answer"] for r in test] == ["yes", "yes"]
    assert "linear: median 3.6 mm against 1.2 mm without growth (3.00x" in test[0]["measured"]


def test_void_after_growth_can_fail():
    # 1.2x, below the factor 1.5
    assert [r["answer"] for r in _void([x * 1.2 for x in LOW])
            if r["argument"] == bl.VOID] == ["no", "no"]
    # 1.83x in the medians but overlapping trials: the interval decides
    assert [r["answer"][:13] for r in _void([1.0, 1.1, 2.2, 2.3, 2.4])
            if r["argument"] == bl.VOID] == ["inconclusive:"] * 2


def test_windowed_memory_is_the_control_not_the_test():
    rows = [r for r in _void(HIGH) if r["argument"] == bl.CONTROL]
    assert [r["answer"][:3] for r in rows] == ["yes", "no:"]  # infant: 3x, the control degrades
    assert "only examples drawn after growth ended" in bl.CONTROL
    assert "first half drawn on the growing, smaller body" in bl.VOID


def test_smoothness_sentence_per_learner_from_the_numbers():
    cells = {(bl.GB, "1M", "linear", "none"): LOW, (bl.MEMORY, "1M", "linear", "none"): LOW}
    aggs = {"baselines_arm5": _aggs("arm5", cells,
                                    jump=lambda k: 3.56 if k == bl.MEMORY else 0.015)}
    lines = bl.smoothness(bl.table(aggs))
    assert len(lines) == 2
    gb, memory = lines
    assert gb.startswith(f"- {bl.GB} (") and "at most 0.015" in gb and "continuous" in gb
    assert memory.startswith(f"- {bl.MEMORY} (") and "up to 3.56" in memory
    assert "whip between solutions" in memory


def test_section_renders_every_part():
    cells = {**_same_solver_cells(), **_memory_cells([x * 3 for x in LOW])}
    aggs = {"baselines_arm5": _aggs("arm5", cells)}
    t, pt = bl.table(aggs), bl.per_trial(aggs)
    md = bl.markdown(t, bl.claims(t, pt), pt)
    assert bl.GB_LSTSQ in md and "| arm5 | 1M | no growth | motor babbling | 1.2 | 2.2 |" in md
    assert "1.00 [0.64, 1.00]" in md
    assert "Smoothness of the final inverse" in md and bl.VOID.split(":")[0] in md
    assert "| 4M | no growth | motor babbling" not in md and "| 8M | no growth | motor" not in md
    assert f"{bl.GB_LSTSQ} ends lower in 1, motor babbling in 0" in md


def test_three_trials_each_are_decided_only_without_overlap():
    assert bl.p_beats([1.0, 2.0, 3.0], [4.0, 5.0, 6.0])[1] > 0.5
    assert bl.p_beats([1.0, 2.0, 3.0], [3.0, 4.0, 5.0])[1] < 0.5  # one tie


def test_figure_draws_least_squares_goal_babbling_in_its_own_style():
    cells = {(bl.GB, "1M", "linear", "none"): LOW, (bl.GB_LSTSQ, "1M", "linear", "none"): LOW}
    agg = _aggs("arm5", cells)
    agg["curves"] = pd.DataFrame([dict(condition=c, samples=s, heldout_abs_error_mean=0.01)
                                  for c in ("c0", "c1") for s in (10, 100)])
    fig = bl.figure({"baselines_arm5": agg}, "t")
    styles = {ln.get_label(): (ln.get_linestyle(), ln.get_color())
              for ax in fig.axes for ln in ax.get_lines()}
    assert styles[bl.GB_LSTSQ][0] == "--" and styles[bl.GB][0] == "-"
    assert tuple(styles[bl.GB_LSTSQ][1]) != tuple(styles[bl.GB][1])
