"""The engines' plain parts, without Ray or a cluster: the registry and its config group, each
engine's own settings, sharding, errors; a toy engine added as one module runs a figure.

The cluster engines themselves run end to end in pipeline/test_engines_slow.py (-m slow).
"""
import dataclasses
import importlib.util
import random
import tempfile
from pathlib import Path
from types import SimpleNamespace

import pytest

from conftest import declare_plugin, run_cli, tiny_overrides
from pipeline import engines, execute, simulate
from pipeline.engines import submitit_jobs
from pipeline.config import REPO_ROOT, ConfigError, compose
from pipeline.plan import cost, plan


def fake(n, seed=0):
    rng = random.Random(seed)
    return [dict(key=f"k{i}", c=rng.choice([1, 1, 2, 5, 10, 100]) * rng.random()) for i in range(n)]


def fake_cost(t):
    return t["c"]


def test_cost_weighs_each_learners_path():
    """A trial's cost is its samples x joints x epochs times its learner's measured cost per
    sample and joint (its sample_cost, measured by pipeline.tools.bench costs): online Goal
    Babbling's 106 samples an epoch cost more than Goal Babbling's 2120, as they do in CPU time;
    every shipped learner states its weight."""
    from gbmodel import learners

    def one(*over):
        return cost(plan(compose(["body=arm5", "trials.count=1", "learner.epochs=100",
                                  *over]))[0])
    gb, online = one(), one("learner=online_goal_babbling")
    assert gb == 100 * 2120 * 5 and online == 100 * 106 * 5 * 35
    assert one("learner.fast=false") == 60 * gb
    assert one("learner.updates=online") == 2 * gb
    assert one("learner=online_goal_babbling", "learner.fast=false") > 100 * online
    assert all(hasattr(learners.get(name), "sample_cost") for name in learners.available())


@pytest.mark.parametrize("n_trials,n", [(1, 1), (1, 4), (7, 3), (50, 4), (50, 50), (50, 80),
                                        (271, 16)])
def test_shards_partition_todo_in_order_and_balance_cost(n_trials, n):
    todo = fake(n_trials, seed=n_trials * 100 + n)
    parts = submitit_jobs.shards(todo, n, cost=fake_cost)
    assert len(parts) == min(n, n_trials) and all(parts)
    keys = [t["key"] for p in parts for t in p]
    assert sorted(keys) == sorted(t["key"] for t in todo) and len(set(keys)) == len(keys)
    position = {t["key"]: i for i, t in enumerate(todo)}
    for p in parts:  # within a shard: the order of todo (longest first)
        assert [position[t["key"]] for t in p] == sorted(position[t["key"]] for t in p)
    loads = [sum(map(fake_cost, p)) for p in parts]
    assert loads == sorted(loads, reverse=True)
    assert max(loads) - min(loads) <= max(map(fake_cost, todo)) + 1e-9  # LPT's bound


def test_shards_of_equal_trials_are_even_and_empty_todo_has_none():
    todo = [dict(key=str(i), c=1.0) for i in range(10)]
    assert [len(p) for p in submitit_jobs.shards(todo, 4, cost=fake_cost)] == [3, 3, 2, 2]
    assert submitit_jobs.shards([], 4, cost=fake_cost) == []
    for bad in (0, -1, 2.0, True):
        with pytest.raises(ValueError):
            submitit_jobs.shards(todo, bad, cost=fake_cost)


def test_shards_hold_the_trials_a_local_run_computes(tmp_path):
    """The shards of a real plan (by pipeline.plan.cost) are its trials, each once, unchanged."""
    cfg = compose(tiny_overrides(tmp_path, "experiment=fig4", "trials.count=3",
                                 "conditions.periods=[10,100]"))
    trials = plan(cfg)
    todo = sorted(trials, key=cost, reverse=True)
    parts = submitit_jobs.shards(todo, 4, cost)
    assert sorted(t["key"] for p in parts for t in p) == sorted(t["key"] for t in trials)
    by_key = {t["key"]: t for t in trials}
    assert all(t == by_key[t["key"]] for p in parts for t in p)
    assert len(parts) == 4 and max(map(len, parts)) - min(map(len, parts)) <= 1  # equal costs


def test_unknown_engine_and_missing_package_are_one_line_config_errors(monkeypatch):
    with pytest.raises(ConfigError, match=r"^engine='dask': choose one of local, ray, "
                                          r"slurm, submitit_local$"):
        engines.check("dask")
    with pytest.raises(ConfigError, match="choose one of"):
        next(engines.run(dict(name="dask"), [dict(key="k")], 2))
    real = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec",
                        lambda name, *a: None if name in ("ray", "submitit") else real(name, *a))
    for name, extra in (("ray", "ray"), ("slurm", "slurm"), ("submitit_local", "slurm")):
        with pytest.raises(ConfigError, match=rf"^engine={name} needs the package \w+: "
                                              rf"pip install -e '\.\[{extra}\]'$") as err:
            engines.check(name)
        assert "\n" not in str(err.value)
    engines.check("local")


def test_slurm_refuses_another_engines_setting_and_a_machine_without_sbatch(monkeypatch, tmp_path):
    with pytest.raises(ConfigError, match=r"^engine=slurm: .*address"):
        next(engines.run(dict(name="slurm", address="head:6379"), [dict(key="k")], 2))
    pytest.importorskip("submitit")
    monkeypatch.setattr(submitit_jobs.shutil, "which", lambda name: None)
    with pytest.raises(ConfigError, match="sbatch not found"):
        next(engines.run(dict(name="slurm"), [dict(key="k")], 2, fn=len, logs=tmp_path))
    assert not any(tmp_path.iterdir())  # nothing submitted


def test_the_engine_group_is_generated_from_the_registered_engines():
    """engine=<name> for every engine module of pipeline/engines/, its settings those of its
    dataclass (typed: a wrong type or another engine's setting is refused); no YAML file."""
    assert set(engines.available()) >= {"local", "ray", "slurm", "submitit_local"}
    assert not (REPO_ROOT / "conf" / "engine").exists()
    for name in engines.available():
        conf = compose([f"engine={name}"]).engine
        fields = {f.name for f in dataclasses.fields(engines.get(name).settings)}
        assert conf.name == name and set(conf) == {"name", *fields}
    assert compose(["engine=ray", "engine.address=auto"]).engine.address == "auto"
    assert compose(["engine=slurm", "engine.timeout_min=5"]).engine.timeout_min == 5
    for bad in (["engine=slurm", "engine.timeout_min=soon"], ["engine=ray", "engine.partition=x"]):
        with pytest.raises(Exception, match="timeout_min|partition"):
            compose(bad)


def test_each_engine_gets_its_own_settings_only(tmp_path, compose_tiny, monkeypatch):
    """simulate hands the chosen engine its own settings (engine.<field>), never another
    engine's (before: every engine got executor.slurm, the SLURM options)."""
    got = []

    def spy(name):
        def run(todo, workers, fn, settings, logs, **given):  # (slurm's: its cost)
            got.append((name, settings, logs))
            yield from execute.local(todo, workers, fn)
        return run

    for name in ("ray", "slurm"):
        monkeypatch.setitem(engines._ENGINES, name, dataclasses.replace(
            engines.get(name), run=spy(name), package=None))
    summary = simulate.simulate(compose_tiny(tmp_path / "a", "engine=ray", "engine.address=auto"))
    assert summary.failed == {}
    summary = simulate.simulate(compose_tiny(tmp_path / "b", "engine=slurm", "engine.mem_gb=4",
                                             "+engine.extra.reservation=course"))
    assert summary.failed == {}
    (ray, ray_settings, _), (slurm, slurm_settings, logs) = got
    assert ray == "ray" and ray_settings == engines.get("ray").settings(address="auto")
    assert slurm == "slurm" and slurm_settings.mem_gb == 4.0
    assert slurm_settings.extra == {"reservation": "course"} and logs.name == "submitit"


TOY = """
import sys
from dataclasses import dataclass

from pipeline.engines import engine


@dataclass
class ToySettings:
    greeting: str = "hello"


@engine("toy", ToySettings)
def run(todo, workers, fn, settings, logs):
    for trial in todo:
        print(f"toy engine ({settings.greeting}): {trial['key']}", file=sys.stderr)
        yield trial, fn(trial)
"""


def test_a_toy_engine_in_one_module_runs_a_figure_with_no_other_edit(tmp_path):
    """An engine added as one module (here gbgrowth_engine_toy.py, which its distribution
    declares as an entry point of gbgrowth.engines; in the repository: pipeline/engines/toy.py)
    is engine=toy on the command line, its settings engine.<field>, and runs the trials; the
    unknown-engine line names it. A module that only bears the old prefix is never imported."""
    plugins = tmp_path / "plugins"
    declare_plugin(plugins, "gbgrowth.engines", "toy", "gbgrowth_engine_toy", TOY)
    (plugins / "gbgrowth_engine_stray.py").write_text("print('STRAY IMPORTED')\n")
    env = {"PYTHONPATH": str(plugins)}
    out = tmp_path / "run"
    r = run_cli("pipeline.simulate", *tiny_overrides(out, "engine=toy", "engine.greeting=hi",
                                                     "trials.count=2"), env=env)
    assert r.returncode == 0, r.stderr
    ran = [ln for ln in r.stderr.splitlines() if ln.startswith("toy engine (hi): ")]
    assert len(ran) == 2, r.stderr  # the tiny figure's trials, through the toy engine
    assert "2 trials: 0 cached, 2 run, 0 failed" in r.stderr, r.stderr
    r = run_cli("pipeline.simulate", *tiny_overrides(tmp_path / "x", "engine=dask"), env=env)
    assert r.returncode == 2 and "toy" in r.stderr.strip().splitlines()[-1], r.stderr
    assert "stray" not in r.stderr.strip().splitlines()[-1] and "STRAY" not in r.stdout


def test_a_worker_with_other_code_fails_the_trial_instead_of_caching_it(tmp_path):
    trial = plan(compose(tiny_overrides(tmp_path)))[0]
    assert execute.run_one(trial)["status"] == "ok"
    out = execute.run_one(dict(trial, code="0" * 16))  # what every engine's workers run
    assert out["status"] == "failed" and out["key"] == trial["key"]
    assert "fingerprint" in out["error"] and "\n" not in out["error"]
    assert isinstance(out["seconds"], float)


def test_failed_result_has_what_simulate_records():
    out = engines.failed(dict(key="abc"), "WorkerCrashedError: The worker died.\n  details")
    assert out["status"] == "failed" and out["key"] == "abc" and out["seconds"] == 0.0
    assert out["error"] == "WorkerCrashedError: The worker died." and "details" in out["traceback"]


def test_unknown_engine_and_the_old_group_on_the_command_line_exit_2_with_one_line(tmp_path):
    r = run_cli("pipeline.simulate", *tiny_overrides(tmp_path, "engine=dask"))
    assert r.returncode == 2, r.stderr
    lines = r.stderr.strip().splitlines()
    assert lines[-1] == ("error: engine=dask: unknown option; choose one of: local, ray, slurm, "
                         "submitit_local"), r.stderr
    assert len(lines) == 1 and not any(tmp_path.iterdir()), "refused before anything is written"
    for old, new in (("executor=slurm", "engine=slurm"), ("executor.backend=ray", "engine=ray"),
                     ("executor.slurm.partition=cpu", "engine.partition=cpu"),
                     ("+executor.slurm.extra.reservation=x", "+engine.extra.reservation=x")):
        r = run_cli("pipeline.simulate", *tiny_overrides(tmp_path, old))
        assert r.returncode == 2 and r.stderr.strip() == (
            f"error: {old}: the group executor is named engine now; write {new} "
            "(docs/engines.md)"), r.stderr
    assert not any(tmp_path.iterdir())


# --- waiting for submitit jobs (what the real SLURM cluster showed; tests/pipeline/test_engines_cluster.py)

class FakeWatcher:
    def __init__(self):
        self.calls = 0

    def update(self):
        self.calls += 1


class FakeJob:
    """A submitit job that never ends by itself (a job killed on a cluster without accounting:
    sacct fails, its state stays UNKNOWN, it leaves no result)."""
    watcher = None

    def __init__(self, job_id, results=None, folder=None):
        self.job_id, self.results, self.cancelled = job_id, results, False
        self.state = "UNKNOWN"
        folder = Path(folder or tempfile.mkdtemp())
        self.paths = SimpleNamespace(result_pickle=folder / f"{job_id}_result.pkl",
                                     stderr=folder / f"{job_id}.err")
        if results is not None:
            self.paths.result_pickle.touch()

    def done(self):
        return self.results is not None

    def result(self):
        return self.results

    def cancel(self, check=True):
        self.cancelled = True


def test_a_job_slurm_no_longer_lists_is_lost_after_lost_s_not_waited_for(tmp_path):
    import time

    FakeJob.watcher = FakeWatcher()
    dead, fine = FakeJob("7_0"), FakeJob("7_1", results=[dict(key="b", status="ok")])
    parts = [[dict(key="a")], [dict(key="b")]]
    t0 = time.monotonic()
    out = list(submitit_jobs.watch([dead, fine], parts, tmp_path, poll=0.05, lost_s=0.3,
                              queued=lambda: set(), refresh=FakeJob.watcher.update))
    assert time.monotonic() - t0 < 5
    got = {t["key"]: r for t, r in out}
    assert got["b"]["status"] == "ok" and got["a"]["status"] == "failed"
    assert got["a"]["error"].startswith("job 7_0 ended without a result") and dead.cancelled
    assert FakeJob.watcher.calls >= 2  # sacct once per poll_s, not submitit's back-off


def test_a_listed_job_is_waited_for_and_squeue_failing_loses_nothing(tmp_path):
    FakeJob.watcher = FakeWatcher()
    job = FakeJob("8_0")
    gen = submitit_jobs.watch([job], [[dict(key="a")]], tmp_path, poll=0.01, lost_s=0.0,
                         queued=lambda: {"8_0"})
    import threading
    box = []
    th = threading.Thread(target=lambda: box.append(next(gen)), daemon=True)
    th.start()
    th.join(0.5)
    assert th.is_alive() and not box  # still waiting: the job is queued or running
    submitit_jobs.spool(tmp_path, "a", dict(key="a", status="ok"))  # its shard finishes the trial
    th.join(5)
    assert box and box[0][1]["status"] == "ok"
    assert list(gen) == [] and not submitit_jobs.spool_path(tmp_path, "a").exists()  # handed over
    assert list(submitit_jobs.watch([FakeJob("9_0", results=[dict(key="c", status="ok")])],
                               [[dict(key="c")]], tmp_path, poll=0.01, lost_s=0.0,
                               queued=lambda: None))[0][1]["status"] == "ok"


def test_a_lost_job_hands_over_what_it_spooled(tmp_path):
    FakeJob.watcher = FakeWatcher()
    submitit_jobs.spool(tmp_path / "s", "a", dict(key="a", status="ok", seconds=1.0))
    job = FakeJob("3_0")
    out = list(submitit_jobs.watch([job], [[dict(key="a"), dict(key="b")]], tmp_path / "s",
                              poll=0.01, lost_s=0.0, queued=lambda: set()))
    assert {t["key"]: r["status"] for t, r in out} == {"a": "ok", "b": "failed"}


def test_a_job_that_ended_without_a_result_fails_after_the_grace_without_blocking(tmp_path,
                                                                                  monkeypatch):
    import time

    monkeypatch.setattr(submitit_jobs, "RESULT_GRACE_S", 0.3)
    dead = FakeJob("5_0", folder=tmp_path)
    dead.done, dead.state = (lambda: True), "FAILED"  # sacct says FAILED, no result file
    other = FakeJob("5_1", folder=tmp_path)
    gen = submitit_jobs.watch([dead, other], [[dict(key="a")], [dict(key="b")]], tmp_path / "s",
                         poll=0.05, lost_s=60, queued=lambda: {"5_0", "5_1"})
    submitit_jobs.spool(tmp_path / "s", "b", dict(key="b", status="ok"))
    t0 = time.monotonic()
    first = next(gen)  # the other job's trial is not held up by the failed one
    assert first[0]["key"] == "b" and time.monotonic() - t0 < 0.2
    trial, result = next(gen)
    assert trial["key"] == "a" and result["error"].startswith("job 5_0 FAILED without a result")
    assert 0.25 < time.monotonic() - t0 < 3


def test_a_requeued_shard_skips_the_trials_it_spooled(tmp_path):
    calls = []

    def fn(t):
        calls.append(t["key"])
        return dict(key=t["key"], status="ok" if t["key"] != "x" else "failed", seconds=0.0)

    shard = submitit_jobs.Shard(fn, str(tmp_path))
    trials = [dict(key="a"), dict(key="x"), dict(key="b")]
    assert [r["key"] for r in shard(trials)] == ["a", "x", "b"]
    assert shard(trials)[0]["status"] == "ok"  # the same job again after a requeue
    assert calls == ["a", "x", "b", "x"]  # a failed trial is not spooled: computed again
    pytest.importorskip("submitit")  # the requeue itself is submitit's (the slurm extra)
    again = shard.checkpoint(trials)  # on SIGUSR2: the same shard, requeued
    assert again.function is shard and again.args == (trials,)


def test_the_signal_delay_leaves_a_short_time_limit_room():
    opts = dataclasses.asdict(engines.get("slurm").settings(timeout_min=2))
    params = submitit_jobs.job_parameters(opts, 2, "slurm", "fig4")
    assert params["slurm_signal_delay_s"] == 12 and params["timeout_min"] == 2
    assert submitit_jobs.signal_delay(dict(opts, timeout_min=1440)) == 90  # submitit's default
    assert submitit_jobs.signal_delay(dict(opts, signal_delay_s=30)) == 30
    cfg = compose(["engine=slurm", "engine.signal_delay_s=30", "engine.lost_s=5"])
    assert cfg.engine.signal_delay_s == 30 and cfg.engine.lost_s == 5
    assert "slurm_signal_delay_s" not in submitit_jobs.job_parameters(opts, 2, "local", "fig4")


def test_a_failing_sacct_is_reported_once_not_every_poll():
    import logging

    f = submitit_jobs.OnceFilter("Bypassing sacct error")
    rec = lambda msg: logging.LogRecord("submitit", logging.WARNING, "", 0, msg, None, None)  # noqa: E731
    assert [f.filter(rec(m)) for m in ("Call #1 - Bypassing sacct error x", "other",
                                       "Call #2 - Bypassing sacct error x")] == [True, True, False]


def test_a_plugin_that_does_not_import_costs_no_other_command(tmp_path):
    """An engine's module (an entry point of gbgrowth.engines) that fails to import (a missing
    package) left every command a traceback, since every command imports the registry; now
    only engine=<name> is refused, in one line naming the module and its error."""
    plugins = tmp_path / "plugins"
    declare_plugin(plugins, "gbgrowth.engines", "broken", "gbgrowth_engine_broken",
                   "import a_package_not_installed_zz\n")
    env = {"PYTHONPATH": str(plugins)}
    r = run_cli("pipeline", "--version", env=env)
    assert r.returncode == 0 and r.stdout.startswith("gbgrowth "), r.stderr
    r = run_cli("pipeline.simulate", *tiny_overrides(tmp_path / "run", "engine=broken"), env=env)
    assert r.returncode == 2, r.stderr
    assert r.stderr.strip() == ("error: engine=broken: its module did not import "
                                "(gbgrowth_engine_broken: ModuleNotFoundError: No module named "
                                "'a_package_not_installed_zz')"), r.stderr
