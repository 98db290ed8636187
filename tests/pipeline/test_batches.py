"""Short trials travel to a worker in batches, long ones alone; the results are the same."""
import importlib
import os
import sys

import pytest

from pipeline import execute
from pipeline.config import compose
from pipeline.plan import plan


def trials(tmp_path, *overrides):
    return plan(compose([f"paths.root={tmp_path}", "body=arm5", *overrides]))


def test_short_trials_are_batched_in_order_and_long_ones_alone(tmp_path):
    short = trials(tmp_path, "learner.epochs=10", "trials.count=500", "conditions.periods=[5]")
    long = trials(tmp_path, "learner.epochs=100000", "trials.count=2", "conditions.periods=[5]")
    todo = long + short
    cut = execute.batches(todo, 2)
    assert [t for b in cut for t in b] == todo  # every trial once, in order
    assert cut[0] == long[:1] and cut[1] == long[1:]  # each long trial alone
    assert all(1 <= len(b) <= execute.MAX_BATCH for b in cut)
    assert max(len(b) for b in cut) == execute.MAX_BATCH  # the short ones share tasks
    few = execute.batches(short[:32], 2)
    assert len(few) == execute.BATCH_SHARE * 2  # few trials: still spread over the workers


def test_batched_pool_gives_each_trial_its_own_result(tmp_path):
    todo = trials(tmp_path, "learner.epochs=3", "trials.count=12", "conditions.periods=[2]")
    got = list(execute.local(todo, 2))
    assert sorted(t["key"] for t, _ in got) == sorted(t["key"] for t in todo)
    assert all(r["key"] == t["key"] and r["status"] == "ok" for t, r in got)


def test_a_pool_warms_up_in_its_first_worker_and_the_driver_loads_no_kernel(tmp_path,
                                                                           monkeypatch):
    from pipeline import simulate

    calls = []
    monkeypatch.setattr(execute, "warm_up", lambda t: calls.append(len(t)))
    overrides = [f"paths.root={tmp_path}", "body=arm5", "learner.epochs=3",
                 "conditions.periods=[2]"]
    s = simulate.simulate(compose([*overrides, "trials.count=3", "workers=2"]))
    assert s.ran == 3 and not s.failed
    assert calls == ([] if execute.pooled(3, 2) else [3])  # the pool's first worker did it
    s = simulate.simulate(compose([*overrides, "trials.count=5", "workers=1"]))
    assert s.ran == 2 and not s.failed and calls[-1] == 2  # in this process: warmed up here


def test_the_warm_up_runs_one_tiny_trial_per_body_and_learner(tmp_path):
    todo = trials(tmp_path, "learner.epochs=30", "trials.count=3", "conditions.periods=[2,5]")
    todo[0] = dict(todo[0], resume={"epoch": 1000}, keep_state=True)
    warm = execute.warm_trials(todo)
    assert len(warm) == 1 and set(warm[0]) == {"key", "seed", "code", "spec"}
    assert warm[0]["spec"]["epochs"] == 2 and warm[0]["spec"]["growth"]["period"] == 0
    assert execute.run_one(warm[0])["status"] == "ok"


def _imported_here(trial: dict) -> dict:
    """A worker's answer: which process it is."""
    return dict(key=trial["key"], pid=os.getpid())


def test_a_worker_does_not_import_the_drivers_main_module(tmp_path, monkeypatch):
    """`python -m pipeline.simulate` is the driver's __main__: a spawned worker imported it
    (Hydra, OmegaConf, the config) before its first trial, and used none of it."""
    (tmp_path / "heavy_main.py").write_text(
        "import os, pathlib\n"
        f"with open({str(tmp_path / 'imported')!r}, 'a') as f:\n"
        "    f.write(f'{os.getpid()}\\n')\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.setitem(sys.modules, "__main__", importlib.import_module("heavy_main"))
    todo = [dict(key=f"{i:020x}", spec={}) for i in range(4)]
    got = list(execute.local(todo, 2, fn=_imported_here))
    assert sorted(t["key"] for t, _ in got) == [t["key"] for t in todo]
    workers = {r["pid"] for _, r in got} - {os.getpid()}
    assert workers or not execute.pooled(4, 2)
    assert (tmp_path / "imported").read_text().split() == [str(os.getpid())]  # here only
    assert sys.modules["__main__"].__name__ == "heavy_main"  # given back


def _threads_here(trial: dict) -> dict:
    """A worker's answer: its thread settings as it inherited them."""
    return dict(key=trial["key"], pid=os.getpid(),
                env={k: os.environ.get(k) for k in execute.THREAD_VARS})


def test_pool_workers_start_with_one_thread_each(monkeypatch):
    """The pool starts its workers in the submits, after the pool is made: the thread
    settings must be in the environment then (they were restored before: a worker ran with
    OPENBLAS_NUM_THREADS unset, a BLAS thread per CPU in each of two workers)."""
    for k in execute.THREAD_VARS:
        monkeypatch.delenv(k, raising=False)
    todo = [dict(key=f"{i:020x}", spec={}) for i in range(4)]
    got = list(execute.local(todo, 2, fn=_threads_here))
    if not execute.pooled(4, 2):
        pytest.skip("one CPU: the trials run in this process")
    workers = [r for _, r in got if r["pid"] != os.getpid()]
    assert workers and all(r["env"] == {k: "1" for k in execute.THREAD_VARS} for r in workers)
    assert all(k not in os.environ for k in execute.THREAD_VARS)  # the driver's as it was


def _trusted_here(trial: dict) -> dict:
    """A worker's answer: its fingerprint, and how many files it parsed for it."""
    from pipeline import fingerprint
    return dict(key=trial["key"], pid=os.getpid(), fp=fingerprint.code_fingerprint("goal_babbling"),
                parsed=fingerprint._facts.cache_info().currsize)


def test_pool_workers_are_handed_the_drivers_fingerprints():
    """A worker takes the driver's code fingerprints (fingerprint.known) for files with the same
    bytes: it parses its learner's files (their imports name the files), not the shared core."""
    from pipeline.fingerprint import code_fingerprint, learner_sources
    code_fingerprint("goal_babbling")
    todo = [dict(key=f"{i:020x}", spec={}) for i in range(4)]
    got = list(execute.local(todo, 2, fn=_trusted_here))
    if not execute.pooled(4, 2):
        pytest.skip("one CPU: the trials run in this process")
    workers = [r for _, r in got if r["pid"] != os.getpid()]
    own = len(learner_sources("goal_babbling"))  # parsed for their imports; the shared core not
    assert workers and all(r["fp"] == code_fingerprint("goal_babbling") and r["parsed"] == own
                           for r in workers)


def _warm_here(trial: dict) -> dict:
    """A worker's answer: whether the kernels were loaded before its first trial."""
    return dict(key=trial["key"], pid=os.getpid(),
                loaded="gbmodel.learners.goal_babbling.fast" in sys.modules)


def test_pool_workers_start_warm_and_their_server_stops_with_the_pool():
    """Each worker is a fork of one server that loaded the kernels (pipeline.preload): none
    loads them again; the server is stopped and waited for when the pool ends."""
    import multiprocessing.forkserver
    if "forkserver" not in multiprocessing.get_all_start_methods():
        pytest.skip("no fork server here: workers are spawned")
    todo = [dict(key=f"{i:020x}", spec={}) for i in range(4)]
    got = list(execute.local(todo, 2, fn=_warm_here))
    if not execute.pooled(4, 2):
        pytest.skip("one CPU: the trials run in this process")
    workers = [r for _, r in got if r["pid"] != os.getpid()]
    assert workers and all(r["loaded"] for r in workers)
    assert multiprocessing.forkserver._forkserver._forkserver_pid is None
