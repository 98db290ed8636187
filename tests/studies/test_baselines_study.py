"""The baselines study's table and verdicts (pipeline/studies/baselines.py) on constructed
summaries: the held-out error decides, intervals are Student's t, identical rows are explained."""
import numpy as np
import pandas as pd
import pytest

from pipeline.studies import baselines as bl


def _summary(body, rows):
    """rows: (learner, budget, schedule, growth, heldout mm, grid mm, std mm, period)."""
    out = []
    for i, (learner, budget, schedule, growth, held, grid, std, period) in enumerate(rows):
        out.append(dict(body=body, variant=f"{learner}, {budget}, {schedule}", growth=growth,
                        growth_period=period, condition=f"c{i}", final_samples=int(1e6),
                        n_trials=3, n_diverged=0, final_abs_error_mean=grid * 1e-3,
                        final_heldout_abs_error_mean=held * 1e-3,
                        final_heldout_abs_error_std=std * 1e-3, final_rel_error_mean=grid * 1e-3,
                        largest_jump_mean=0.01))
    return {"summary": pd.DataFrame(out), "curves": pd.DataFrame()}


def _rows():
    r = []
    for learner, (none, lin, inf) in {bl.GB: (20, 22, 21), bl.GB_LSTSQ: (15, 40, 16),
                                      bl.MB: (30, 25, 25),
                                      bl.MB_WIDE: (400, 410, 405),
                                      bl.MEMORY_ALL: (3, 1, 50), bl.MEMORY: (3, 9, 9)}.items():
        r += [(learner, "1M", "linear", "none", none, none / 10, 1.0, 0),
              (learner, "1M", "linear", "proportional", lin, lin / 10, 1.0, 500),
              (learner, "1M", "infant", "proportional", inf, inf / 10, 1.0, 500)]
    return r


def test_verdicts_use_the_heldout_error_not_the_grid():
    t = bl.table({"baselines_arm5": _summary("arm5", _rows())})
    row = t[(t.learner == bl.GB) & (t.growth == "no growth")].iloc[0]
    assert (row.heldout_mm, row.grid_mm) == pytest.approx((20.0, 2.0))
    lo, hi = bl.interval(20.0, 1.0, 3)  # t(0.975, 2) = 4.303
    assert (lo, hi) == pytest.approx((20 - 4.303 / 3 ** 0.5, 20 + 4.303 / 3 ** 0.5), abs=1e-3)
    claims = {c["argument"].split(":")[0]: c for c in bl.claims(t)}
    # motor babbling over the whole range 400 mm against Goal Babbling (least squares) 15 mm
    assert claims["motor babbling cannot resolve redundancy"]["answer"] == "yes"
    assert claims["Goal Babbling keeps its error"]["answer"] == "yes"
    assert claims[f"{bl.GB_LSTSQ} keeps its error"]["answer"] == "no"  # 40 mm > 1.5 x 15
    md = bl.markdown(t, bl.claims(t))
    assert "20.0 ± 1.0 [17.5, 22.5]" in md


def test_redundancy_is_judged_against_the_same_solver_only():
    """Without Goal Babbling (least squares) at a budget, motor babbling is not judged there,
    however it compares with gradient Goal Babbling."""
    rows = [r for r in _rows() if r[0] != bl.GB_LSTSQ]
    t = bl.table({"baselines_arm5": _summary("arm5", rows)})
    assert not [c for c in bl.claims(t) if c["argument"].startswith("motor babbling cannot")]


def test_identical_rows_are_explained_and_unexpected_ones_flagged():
    t = bl.table({"baselines_arm5": _summary("arm5", _rows())})
    notes = bl.identical_rows(t)
    assert any("motor babbling, 1M" in n and "last 10 epochs" in n for n in notes)
    assert any("example memory, 1M" in n and "not expected" in n for n in notes)
    assert not any(bl.GB + ", 1M" in n for n in notes)  # 22 and 21 mm differ


def test_progress_against_random_by_intervals():
    rows = _rows() + [(bl.GB_PROGRESS, "1M", "linear", "none", 20, 2, 1.0, 0),
                      (bl.GB_PROGRESS, "1M", "linear", "proportional", 10, 1, 1.0, 500),
                      (bl.GB_PROGRESS, "1M", "infant", "proportional", 40, 1, 1.0, 500)]
    t = bl.table({"baselines_arm5": _summary("arm5", rows)})
    claim = [c for c in bl.claims(t) if "by progress" in c["argument"]][0]
    assert claim["answer"] == ("no growth no difference measured, linear yes, infant no (worse)")
    assert np.isfinite(t.heldout_lo_mm).all()
