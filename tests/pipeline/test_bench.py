"""`make bench` runs end to end (one repeat, no parallel timing) and the fast path is faster."""
import json
from pathlib import Path

import pytest

from pipeline.tools import bench
from pipeline.config import compose


def test_bench_writes_medians_and_the_fast_path_wins(tmp_path):
    cfg = compose(["bench.repeats=1", "bench.parallel=false", f"paths.root={tmp_path}"])
    result = bench.bench(cfg)
    saved = json.loads((Path(cfg.paths.bench) / "bench.json").read_text())
    assert saved == json.loads(json.dumps(result))
    for body in ("arm5", "icub"):
        row = saved[body]
        assert 0 < row["fast_us_per_trial_epoch"] < row["reference_us_per_trial_epoch"]
        assert row["speedup"] > 5
        # online Goal Babbling, timed in the same run against the batch epoch
        assert row["online_over_batch"] == (row["online_us_per_trial_epoch"]
                                            / row["fast_us_per_trial_epoch"])
        assert 0 < row["online_draw_us_per_epoch"] < row["online_us_per_trial_epoch"]
        # the lstsq solver's epoch against the gradient epoch
        assert row["lstsq_over_gradient"] == (row["lstsq_us_per_trial_epoch"]
                                              / row["fast_us_per_trial_epoch"])
        # Goal Babbling with updates=online against the batch epoch
        assert row["updates_online_over_batch"] == (row["updates_online_us_per_trial_epoch"]
                                                    / row["fast_us_per_trial_epoch"])
        # beside each: the CPU-time ratio of the interleaved pairs (one repeat: its one pair)
        for name, (a, b) in bench.RATIOS.items():
            assert row[f"{name}_cpu"] == pytest.approx(row[f"{a}_cpu_us_per_trial_epoch"]
                                                       / row[f"{b}_cpu_us_per_trial_epoch"])



def test_cpu_ratios_are_the_median_of_the_pairs():
    """Each repeat's pair (run back to back) gives one ratio; the CPU ratio is their median, not
    the ratio of medians, and it does not follow the wall clock."""
    times = {"fast": [(1.0, 1.0), (3.0, 2.0), (1.0, 1.0)],
             "lstsq": [(1.5, 1.4), (3.0, 2.8), (1.1, 1.4)]}  # the second repeat waited for a core
    assert bench.paired_ratio(times, "lstsq", "fast") == 1.4
    assert bench.paired_ratio(times, "lstsq", "fast", clock=0) == 1.1
    assert set(bench.RATIOS) == {"speedup", "online_over_batch", "lstsq_over_gradient",
                                 "updates_online_over_batch"}
