"""Growth as data (gbmodel.growth): the table schedule and per-segment relative growth rates."""
import subprocess
import sys

import numpy as np
import pytest
import yaml

import gbmodel
from gbmodel import Growth, SpecError
from gbmodel.growth import rate_factors
from pipeline.config import CONF_DIR

EPOCHS = np.arange(1, 1302)


@pytest.mark.parametrize("start, end, period, t_end", [(0.5, 1.0, 1000, 1.0), (0.5, 1.0, 1000, 12),
                                                       (0.3, 0.9, 7, 1000.0), (1.0, 0.6, 333, 5)])
def test_two_row_table_is_the_linear_schedule_to_the_bit(start, end, period, t_end):
    lin = Growth(period=period, start_size=start, end_size=end).sizes(EPOCHS)
    tab = Growth(period=period, start_size=start, end_size=end, schedule="table",
                 table=[[0, start], [t_end, end]]).sizes(EPOCHS)
    assert tab.tobytes() == lin.tobytes()


def test_table_interpolates_linearly_in_time_and_holds_after_the_last_row():
    g = Growth(period=120, schedule="table", table=[[0, 0.5], [6, 0.9], [12, 1.0]])
    s = g.sizes(EPOCHS)
    assert s[0] == 0.5 and s[60] == pytest.approx(0.9) and s[120] == 1.0
    assert s[30] == pytest.approx(0.7) and s[90] == pytest.approx(0.95)
    assert (s[120:] == 1.0).all()
    # the time unit does not matter: months or days give the same sizes
    days = Growth(period=120, schedule="table", table=[[0, 0.5], [182.5, 0.9], [365, 1.0]])
    np.testing.assert_allclose(days.sizes(EPOCHS), s, rtol=0, atol=1e-15)


def test_per_segment_table_gives_each_segment_its_row_at_every_epoch():
    body = gbmodel.make_body("arm5")
    rows = [[0, 0.4, 0.5, 0.5, 0.6, 0.5], [10, 0.9, 0.7, 0.8, 0.8, 0.9], [20, 1, 1, 1, 1, 1]]
    g = Growth(period=100, schedule="table", table=rows, start_size=0.5,
               end_size=1.0).validate(body)
    sizes = g.sizes(EPOCHS, body)
    scales = g.scales(body, sizes)
    f = np.asarray(rows)[:, 1:]
    np.testing.assert_allclose(scales[[0, 50, 100]], f, atol=1e-12)
    # between rows, linear in time (epoch 26 is a quarter of the way from row 0 to row 1)
    np.testing.assert_allclose(scales[25], f[0] + 0.5 * (f[1] - f[0]), atol=1e-12)
    np.testing.assert_allclose(scales[12], f[0] + 0.24 * (f[1] - f[0]), atol=1e-12)
    # the body size is the total length relative to the full one
    seg = body.segment_lengths
    np.testing.assert_allclose(scales @ seg, sizes * seg.sum(), atol=1e-12)
    with pytest.raises(ValueError, match="needs the body"):
        g.sizes(EPOCHS)


@pytest.mark.parametrize("table, match", [
    ([[0, 0.5], [6, 0.9], [5, 1.0]], "rise strictly"),
    ([[0, 0.5], [6, -0.9], [12, 1.0]], "> 0"),
    ([[0, 0.5, 1], [12, 1.0, 1]], r"\[t, size\] or \[t, f_1, ..., f_5\]"),
    ([[0, 0.5]], "at least two rows"),
    ([[0, 0.5], [12, float("nan")]], "finite"),
    ([[0, 0.6], [12, 1.0]], "set growth.start_size=0.6"),
    ([[0, 0.5, 0.5, 0.5, 0.5, 0.5], [5, 0.9, 0.9, 0.9, 0.9, 0.9], [9, 0.5, 1, 1, 1, 1]],
     "must rise, or fall, strictly"),
])
def test_bad_tables_are_one_line_spec_errors(table, match):
    with pytest.raises(SpecError, match=match) as err:
        Growth(period=10, schedule="table", table=table).validate(gbmodel.make_body("arm5"))
    assert "\n" not in str(err.value)


def test_a_table_needs_its_schedule_and_the_schedule_its_table():
    body = gbmodel.make_body("arm5")
    with pytest.raises(SpecError, match="only schedule=table"):
        Growth(period=10, table=[[0, 0.5], [1, 1.0]]).validate(body)
    with pytest.raises(SpecError, match="needs growth.table"):
        Growth(period=10, schedule="table").validate(body)


def test_who_infant_table_is_the_who_medians():
    conf = yaml.safe_load((CONF_DIR / "schedule" / "who_infant.yaml").read_text())
    cm = [49.9, 54.7, 58.4, 61.4, 63.9, 65.9, 67.6, 69.2, 70.6, 72.0, 73.3, 74.5, 75.7]
    assert [r[0] for r in conf["table"]] == list(range(13))
    assert [r[1] for r in conf["table"]] == [round(c / 75.7, 4) for c in cm]
    g = Growth(period=120, **{k: conf[k] for k in ("schedule", "table", "start_size", "end_size")})
    g.validate(gbmodel.make_body("arm5"))
    s = g.sizes(EPOCHS)
    assert s[0] == 0.6592 and s[120] == 1.0 and (np.diff(s[:121]) > 0).all()


@pytest.mark.parametrize("name", ["arm5", "icub"])
def test_rates_hold_their_ratio_over_the_whole_growth(name):
    body = gbmodel.make_body(name)
    r = np.linspace(2.0, 1.0, body.m)
    g = Growth(pattern="per_segment", period=200, rates=list(r)).validate(body)
    sizes = g.sizes(EPOCHS)
    f = g.scales(body, sizes)
    df = np.diff(f[:201], axis=0)
    grow = body.segment_lengths > 0
    # every segment's rate over its first's is r_i / r_0 at every epoch
    np.testing.assert_allclose(df[:, grow] / df[:, :1], np.broadcast_to(r[grow] / r[0], df[:, grow].shape),
                               rtol=1e-9)
    np.testing.assert_allclose(f[200:], 1.0, atol=1e-15)  # every segment ends at the full body
    seg = body.segment_lengths
    np.testing.assert_allclose(f @ seg, sizes * seg.sum(), rtol=1e-12)  # total length S x full


def test_twice_as_fast_is_one_line_and_means_it():
    body = gbmodel.make_body("arm5")
    f = rate_factors(body.segment_lengths, [2, 2, 1, 1, 1], np.linspace(0.5, 1.0, 11))
    up, fore = np.diff(f[:, 0]), np.diff(f[:, 3])
    np.testing.assert_allclose(up / fore, 2.0, rtol=1e-12)


@pytest.mark.parametrize("rates, match", [([9, 2, 1, 1, 1], "segment 1 would start"),
                                          ([1, 1, 1], "needs 5 rates"),
                                          ([0, 0, 0, 0, 0], "not all zero"),
                                          ([1, -1, 1, 1, 1], ">= 0")])
def test_bad_rates_are_refused(rates, match):
    with pytest.raises(SpecError, match=match):
        Growth(pattern="per_segment", period=10, rates=rates).validate(gbmodel.make_body("arm5"))
    with pytest.raises(SpecError, match="only growth=per_segment"):
        Growth(period=10, rates=[1] * 5).validate(gbmodel.make_body("arm5"))


def test_bad_table_on_the_command_line_is_one_line_exit_2(tmp_path):
    out = subprocess.run(
        [sys.executable, "-m", "pipeline.simulate", "schedule=table",
         "growth.table=[[0,0.5],[6,0.9],[5,1.0]]", "figure=t_bad", f"paths.root={tmp_path}"],
        capture_output=True, text=True, timeout=120)
    assert out.returncode == 2
    assert out.stderr.strip().count("\n") == 0 and "rise strictly" in out.stderr


def test_table_and_rates_run_a_trial():
    for growth in (dict(schedule="table", period=3, start_size=0.5, end_size=1.0,
                        table=[[0, 0.5, 0.5, 0.5, 0.5, 0.5], [1, 1, 1, 1, 1, 1]]),
                   dict(pattern="per_segment", period=3, rates=[2, 2, 1, 1, 1])):
        spec = gbmodel.TrialSpec(growth=growth, epochs=5).validate()
        res = gbmodel.run_trial(spec, np.random.default_rng(0))
        assert res.size[-1] == 1.0 and np.isfinite(res.abs_error).all()
