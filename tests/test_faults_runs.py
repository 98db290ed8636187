"""Runs that meet each other or a cache they cannot write: two sweeps of one figure started in the
same second keep their own groups, a cache where everything is cached is read without writing,
Hydra's own settings are never swept, and what the code fingerprint covers is pinned."""
import os
import subprocess
import sys

from pipeline import cache
from pipeline.config import REPO_ROOT
from conftest import figure_trials, tiny_overrides


# `python -m pipeline.simulate ARGS` with Hydra's `now` resolver reading a frozen clock: every
# sweep starts in the same second
_FROZEN = """
import runpy, sys, datetime, hydra.core.utils
class Clock:
    now = staticmethod(lambda: datetime.datetime(2026, 1, 2, 3, 4, 5))
hydra.core.utils.datetime = Clock
sys.argv = ["pipeline.simulate", *sys.argv[1:]]
runpy.run_module("pipeline.simulate", run_name="__main__", alter_sys=True)
"""


def _sweep(root, *overrides):
    env = dict(os.environ, PYTHONPATH=str(REPO_ROOT))
    r = subprocess.run([sys.executable, "-c", _FROZEN, "-m",
                        *tiny_overrides(root, "growth=proportional", *overrides)],
                       capture_output=True, text=True, cwd="/", env=env, timeout=300)
    assert r.returncode == 0, r.stderr


def test_two_sweeps_of_one_figure_in_one_second_keep_their_own_groups(tmp_path):
    _sweep(tmp_path, "growth.period=10,100")
    _sweep(tmp_path, "growth.period=20,200")
    cache_dir = tmp_path / "outputs/smoke/cache"
    trials, problems = figure_trials(cache_dir, "custom")
    # the later sweep makes the figure alone: its two conditions, not the four of both sweeps
    assert sorted({t["condition"] for t in trials}) == ["TG20", "TG200"] and problems == []
    groups = [p for p in (cache_dir / cache.PLANS / "custom").iterdir() if p.is_dir()]
    assert len(groups) == 2
    assert sorted(len(list(g.glob("*.json"))) for g in groups) == [2, 2]  # two jobs each
    logs = sorted((tmp_path / "outputs/smoke/logs").glob("simulate-multirun/*"))
    assert len(logs) == 2  # each sweep's multirun.yaml in its own folder
