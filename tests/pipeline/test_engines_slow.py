"""The cluster engines end to end at smoke scale: the same cache files as a local run.

Each test runs `simulate` in this process on a composed config (6 trials of fig4, 200 epochs)
through an engine and compares every file under cache/trials/ (locks left out) byte for byte
with a local run. Needs the extras: pip install -e '.[ray,slurm]'.
"""
import os
import sys
from pathlib import Path

import pytest

from conftest import cfg_of, trial_files
from pipeline import cache, engines
from pipeline.engines import submitit_jobs
from pipeline.simulate import simulate

pytestmark = pytest.mark.slow


def with_options(monkeypatch, fn=None, **extra):
    """engines.run as simulate calls it, plus what the schema cannot carry yet (extra, unless
    given), and with another trial function (fn)."""
    original = engines.run

    def run(*args, **kw):
        for k, v in extra.items():
            kw.setdefault(k, v)
        if fn is not None:
            kw["fn"] = fn
        return original(*args, **kw)

    monkeypatch.setattr(engines, "run", run)


def test_ray_local_instance_matches_local_run(tmp_path, local_files):
    pytest.importorskip("ray")
    summary = simulate(cfg_of(tmp_path, "engine=ray", "workers=2"))
    assert summary.ran == 6 and not summary.failed, summary.lines()
    assert trial_files(tmp_path) == local_files
    import ray
    assert not ray.is_initialized()  # the run's own instance is shut down


def test_submitit_local_matches_local_run(tmp_path, local_files, monkeypatch):
    pytest.importorskip("submitit")
    cfg = cfg_of(tmp_path, "engine=submitit_local", "workers=2")
    summary = simulate(cfg)
    assert summary.ran == 6 and not summary.failed, summary.lines()
    assert trial_files(tmp_path) == local_files
    jobs = Path(cfg.paths.out) / "logs" / "submitit"  # where simulate puts submitit's job files
    assert len(list(jobs.glob("*/*_result.pkl"))) == 2  # two shard jobs


class KillOnce:
    """run_one, except that the worker running trial `key` dies the first time (marker file)."""

    def __init__(self, key: str, marker: Path):
        self.key, self.marker = key, str(marker)

    def __call__(self, trial):
        from pipeline.execute import run_one

        if trial["key"] == self.key and not os.path.exists(self.marker):
            open(self.marker, "w").close()
            os._exit(1)
        return run_one(trial)


def test_ray_worker_killed_is_recorded_failed_and_rerun_completes(tmp_path, local_files,
                                                                  monkeypatch):
    pytest.importorskip("ray")
    import ray.cloudpickle

    from pipeline.plan import plan

    ray.cloudpickle.register_pickle_by_value(sys.modules[__name__])  # tests/ is not on the
    cfg = cfg_of(tmp_path, "engine=ray", "workers=2")              # workers' sys.path
    trial = plan(cfg)[2]
    victim = trial["key"]
    with_options(monkeypatch, fn=KillOnce(victim, tmp_path / "killed"))
    first = simulate(cfg)
    assert list(first.failed) == [victim] and first.ran == 6
    print(first.failed[victim])
    assert "WorkerCrashedError" in first.failed[victim] and "\n" not in first.failed[victim]
    assert cache.failure_path(cfg.paths.cache, trial).exists()
    assert not any(p.exists() for p in cache.trial_paths(cfg.paths.cache, trial))
    again = simulate(cfg)  # the same command again
    assert again.ran == 1 and again.cached == 5 and not again.failed
    assert trial_files(tmp_path) == local_files


def test_a_failed_submitit_job_returns_its_shard_as_failed_trials(tmp_path):
    pytest.importorskip("submitit")
    import cloudpickle

    from pipeline.plan import plan

    cloudpickle.register_pickle_by_value(sys.modules[__name__])
    todo = plan(cfg_of(tmp_path, "trials.count=1", "conditions.periods=[10]",
                       "conditions.references=[0.5,0.7,1.0]"))
    parts = submitit_jobs.shards(todo, 2)
    victim = parts[1][0]["key"]
    out = list(engines.run(dict(name="submitit_local"), todo, 2,
                           fn=KillOnce(victim, tmp_path / "killed"), logs=tmp_path / "submitit"))
    assert all(t["key"] == r["key"] for t, r in out)
    got = {r["key"]: r for _, r in out}
    assert sorted(got) == sorted(t["key"] for t in todo)
    lost = {t["key"] for t in parts[1]}
    assert {k for k, r in got.items() if r["status"] == "failed"} == lost
    assert all(r["status"] == "ok" for k, r in got.items() if k not in lost)
    print(got[victim]["error"])
    assert "\n" not in got[victim]["error"] and got[victim]["error"].startswith("job ")
