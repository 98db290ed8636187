"""The cluster engines' plain parts, without Ray or a cluster: sharding, backend choice, errors.

The engines themselves run end to end in test_backends_slow.py (-m slow).
"""
import importlib.util
import random

import pytest

from conftest import run_cli, tiny_overrides
from pipeline import backends, execute
from pipeline.config import ConfigError, compose
from pipeline.plan import cost, plan


def fake(n, seed=0):
    rng = random.Random(seed)
    return [dict(key=f"k{i}", c=rng.choice([1, 1, 2, 5, 10, 100]) * rng.random()) for i in range(n)]


def fake_cost(t):
    return t["c"]


@pytest.mark.parametrize("n_trials,n", [(1, 1), (1, 4), (7, 3), (50, 4), (50, 50), (50, 80),
                                        (271, 16)])
def test_shards_partition_todo_in_order_and_balance_cost(n_trials, n):
    todo = fake(n_trials, seed=n_trials * 100 + n)
    parts = backends.shards(todo, n, cost=fake_cost)
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
    assert [len(p) for p in backends.shards(todo, 4, cost=fake_cost)] == [3, 3, 2, 2]
    assert backends.shards([], 4, cost=fake_cost) == []
    for bad in (0, -1, 2.0, True):
        with pytest.raises(ValueError):
            backends.shards(todo, bad, cost=fake_cost)


def test_shards_hold_the_trials_a_local_run_computes(tmp_path):
    """The shards of a real plan (by pipeline.plan.cost) are its trials, each once, unchanged."""
    cfg = compose(tiny_overrides(tmp_path, "experiment=fig4", "trials.count=3",
                                 "conditions.periods=[10,100]"))
    trials = plan(cfg)
    todo = sorted(trials, key=cost, reverse=True)
    parts = backends.shards(todo, 4)
    assert sorted(t["key"] for p in parts for t in p) == sorted(t["key"] for t in trials)
    by_key = {t["key"]: t for t in trials}
    assert all(t == by_key[t["key"]] for p in parts for t in p)
    assert len(parts) == 4 and max(map(len, parts)) - min(map(len, parts)) <= 1  # equal costs


def test_unknown_backend_and_missing_package_are_one_line_config_errors(monkeypatch):
    with pytest.raises(ConfigError, match=r"^executor.backend='dask': choose one of local, ray, "
                                          r"slurm, submitit_local$"):
        backends.check("dask")
    with pytest.raises(ConfigError, match="choose one of"):
        next(backends.run("dask", [dict(key="k")], 2))
    real = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec",
                        lambda name, *a: None if name in ("ray", "submitit") else real(name, *a))
    for backend, extra in (("ray", "ray"), ("slurm", "slurm"), ("submitit_local", "slurm")):
        with pytest.raises(ConfigError, match=rf"pip install -e '\.\[{extra}\]'$") as err:
            backends.check(backend)
        assert "\n" not in str(err.value)
    backends.check("local")


def test_slurm_refuses_an_address_and_a_machine_without_sbatch(monkeypatch, tmp_path):
    pytest.importorskip("submitit")
    with pytest.raises(ConfigError, match="takes no address"):
        next(backends.run("slurm", [dict(key="k")], 2, address="head:6379"))
    monkeypatch.setattr(backends.shutil, "which", lambda name: None)
    with pytest.raises(ConfigError, match="sbatch not found"):
        next(backends.run("slurm", [dict(key="k")], 2, fn=len, logs=tmp_path))
    assert not any(tmp_path.iterdir())  # nothing submitted


def test_engine_configs_compose_and_name_their_backend():
    for name in ("local", "ray", "slurm", "submitit_local"):
        executor = compose([f"executor={name}"]).executor
        assert executor.backend == name and executor.address is None


def test_a_worker_with_other_code_fails_the_trial_instead_of_caching_it(tmp_path):
    trial = plan(compose(tiny_overrides(tmp_path)))[0]
    assert execute.run_one(trial)["status"] == "ok"
    out = execute.run_one(dict(trial, code="0" * 16))  # what every backend's workers run
    assert out["status"] == "failed" and out["key"] == trial["key"]
    assert "fingerprint" in out["error"] and "\n" not in out["error"]
    assert isinstance(out["seconds"], float)


def test_failed_result_has_what_simulate_records():
    out = backends.failed(dict(key="abc"), "WorkerCrashedError: The worker died.\n  details")
    assert out["status"] == "failed" and out["key"] == "abc" and out["seconds"] == 0.0
    assert out["error"] == "WorkerCrashedError: The worker died." and "details" in out["traceback"]


def test_unknown_backend_on_the_command_line_exits_2_with_one_line(tmp_path):
    r = run_cli("pipeline.simulate", *tiny_overrides(tmp_path, "executor.backend=dask"))
    assert r.returncode == 2, r.stderr
    lines = r.stderr.strip().splitlines()
    assert lines[-1] == ("error: executor.backend='dask': choose one of local, ray, slurm, "
                         "submitit_local"), r.stderr
    assert len(lines) == 1 and not any(tmp_path.iterdir()), "refused before anything is written"
