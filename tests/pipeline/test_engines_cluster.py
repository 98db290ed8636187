"""The cluster engines against REAL engines: a one-host SLURM with accounting, a two-node Ray.

`make test-cluster` (or `pytest -m cluster`) installs what they need and runs these; where SLURM or
Ray cannot be installed they skip with the reason. Each run goes through pipeline.simulate at smoke
scale (6 trials of fig4, 200 epochs) and compares every cache file with a local run, byte for byte.
The engines are started by the fixtures (tests/cluster_engines.py) and stopped by process id.
"""
import os
import shutil
import signal
import sys
import tempfile
import threading
import time
from pathlib import Path

import pytest

from cluster_engines import Slurm, slurm_missing, stop_ray, two_node_ray, wait
from conftest import cfg_of, trial_files
from pipeline import engines
from pipeline.engines import ray as ray_engine, submitit_jobs
from pipeline.plan import cost, plan
from pipeline.simulate import simulate

pytestmark = pytest.mark.cluster

SLURM_FAST = ("engine=slurm", "engine.poll_s=1", "engine.lost_s=10", "engine.timeout_min=10")


class Slow:
    """run_one after `sleep` seconds, writing `<marks>/<key>.<pid>` when it starts (and the Ray
    node it runs on), so a test can kill a trial's job or node while it runs."""

    def __init__(self, marks: Path, sleep: float):
        self.marks, self.sleep = str(marks), sleep

    def __call__(self, trial):
        from pipeline.worker import run_one

        where = ""
        try:
            import ray
            if ray.is_initialized():
                where = ray.get_runtime_context().get_node_id()
        except ImportError:
            pass
        os.makedirs(self.marks, exist_ok=True)
        with open(os.path.join(self.marks, f"{trial['key']}.{os.getpid()}"), "w") as fh:
            fh.write(where)
        time.sleep(self.sleep)
        return run_one(trial)


def started(marks: Path) -> dict[str, list[str]]:
    out = {}
    for p in marks.glob("*.*") if marks.exists() else []:
        out.setdefault(p.name.split(".")[0], []).append(p.read_text())
    return out


def with_fn(monkeypatch, fn):
    """simulate, but its engine runs `fn` (pickled by value: tests/ is not on a job's path)."""
    import cloudpickle

    cloudpickle.register_pickle_by_value(sys.modules[__name__])
    try:
        import ray.cloudpickle
        ray.cloudpickle.register_pickle_by_value(sys.modules[__name__])
    except ImportError:
        pass
    original = engines.run
    monkeypatch.setattr(engines, "run", lambda *a, **kw: original(*a, **dict(kw, fn=fn)))


def in_thread(fn):
    box = {}
    th = threading.Thread(target=lambda: box.update(out=fn()), daemon=True)
    th.start()
    return th, box


def until(what, ok, timeout=120.0, every=0.2):
    """ok()'s first true value within `timeout` seconds, else a failed assertion."""
    return wait(what, ok, timeout, every, error=AssertionError)


# --- SLURM -------------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def slurm(tmp_path_factory):
    why = slurm_missing()
    if why:
        pytest.skip(why)
    pytest.importorskip("submitit", reason="the slurm extra: pip install -e '.[slurm]'")
    # not under pytest's tmp folder: MariaDB runs as user mysql, which cannot enter it (mode 700)
    folder = Path(tempfile.mkdtemp(prefix="gbgrowth-slurm-"))
    folder.chmod(0o755)
    cluster = Slurm(folder)
    before = os.environ.get("SLURM_CONF")
    try:
        cluster.start()
        print(f"one-host SLURM with accounting up in {cluster.started_s:.1f} s")
        os.environ["SLURM_CONF"] = cluster.env["SLURM_CONF"]
        yield cluster
    finally:
        cluster.stop()
        if not os.environ.get("GBGROWTH_KEEP_SLURM"):  # to read its logs after a failure
            shutil.rmtree(folder, ignore_errors=True)
        if before is None:
            os.environ.pop("SLURM_CONF", None)
        else:
            os.environ["SLURM_CONF"] = before


def shard_keys(cfg, n):
    todo = sorted(plan(cfg), key=cost, reverse=True)
    return [[t["key"] for t in part] for part in submitit_jobs.shards(todo, n)]


def test_slurm_run_matches_local_run(slurm, tmp_path, local_files):
    t0 = time.monotonic()
    summary = simulate(cfg_of(tmp_path, *SLURM_FAST, "workers=2"))
    print(f"6 trials in 2 SLURM jobs: {time.monotonic() - t0:.1f} s")
    assert summary.ran == 6 and not summary.failed, summary.lines()
    assert trial_files(tmp_path) == local_files


def test_slurm_lab_options_reach_the_jobs(slurm, tmp_path, local_files):
    """engine.extra (a free-form sbatch option) and gres-less defaults: the jobs run
    with the option in their script and compute the same trial files."""
    summary = simulate(cfg_of(tmp_path, *SLURM_FAST, "workers=2",
                              "+engine.extra.comment=gbgrowth-lab"))
    assert summary.ran == 6 and not summary.failed, summary.lines()
    assert trial_files(tmp_path) == local_files
    scripts = list(tmp_path.rglob("*_submission.sh"))
    assert scripts and all("#SBATCH --comment=gbgrowth-lab" in p.read_text() for p in scripts)


def test_slurm_jobs_cancelled_or_killed_lose_only_their_trials_without_accounting(
        slurm, tmp_path, local_files, monkeypatch):
    """scancel one shard's job, SIGKILL another's processes; sacct made to fail (a cluster
    without accounting: every state UNKNOWN, the case that hung the driver)."""
    bin_dir = tmp_path / "bin"
    bin_dir.mkdir()
    (bin_dir / "sacct").write_text("#!/bin/sh\necho 'sacct: accounting disabled' >&2\nexit 1\n")
    (bin_dir / "sacct").chmod(0o755)
    monkeypatch.setenv("PATH", f"{bin_dir}:{os.environ['PATH']}")
    cfg = cfg_of(tmp_path, *SLURM_FAST, "workers=3", "engine.shards=3")
    parts = shard_keys(cfg, 3)
    marks = tmp_path / "marks"
    with_fn(monkeypatch, Slow(marks, sleep=20))
    th, box = in_thread(lambda: simulate(cfg))
    until("two jobs running", lambda: sum(s == "RUNNING" for s in slurm.jobs().values()) >= 2)

    def running_trials():  # a trial of shard 0 and one of shard 1 started (their mark files)
        found = [next((m for m in marks.glob("*.*") if m.name.split(".")[0] in parts[i]), None)
                 for i in (0, 1)]
        return found if all(found) else None

    marked = until("a trial of shards 0 and 1 started", running_trials)
    job_of = {}  # the job running shard i: SLURM_ARRAY_TASK_ID i (map_array keeps the order)
    for j in slurm.jobs():
        job_of[int(j.split("_")[1])] = j
    t_kill = time.monotonic()
    slurm.run("scancel", job_of[0])
    os.kill(int(marked[1].name.split(".")[1]), signal.SIGKILL)  # the python running shard 1
    th.join(300)
    assert not th.is_alive(), "the driver waits for a lost job"
    seen_s = time.monotonic() - t_kill
    summary = box["out"]
    lost = set(parts[0]) | set(parts[1])
    assert set(summary.failed) == lost, summary.lines()
    assert summary.ran == 6
    text = "\n".join(summary.lines())
    for key in lost:  # the command says which
        assert f"FAILED {summary.labels[key]}: job " in text
    print(f"killed jobs seen lost and the run over {seen_s:.1f} s after the kill\n{text}")
    monkeypatch.undo()  # the plain trial function, and sacct back
    again = simulate(cfg)  # the same command again
    assert again.ran == len(lost) and not again.failed, again.lines()
    assert trial_files(tmp_path) == local_files


def test_slurm_killed_job_is_seen_within_seconds_with_accounting(slurm, tmp_path, monkeypatch):
    """SIGKILL a shard's python: sacct says FAILED after a few seconds, and the driver asks
    every poll_s (1 s here), not at submitit's back-off (up to 10 minutes). lost_s is long,
    so the job must be seen through accounting, not through its absence from squeue."""
    cfg = cfg_of(tmp_path, *SLURM_FAST, "engine.lost_s=300", "workers=1",
                 "trials.count=1", "conditions.periods=[10]", "conditions.references=[1.0]")
    marks = tmp_path / "marks"
    with_fn(monkeypatch, Slow(marks, sleep=60))
    th, box = in_thread(lambda: simulate(cfg))
    (mark,) = until("the trial started", lambda: list(marks.glob("*.*")), 120)
    t_kill = time.monotonic()
    os.kill(int(mark.name.split(".")[1]), signal.SIGKILL)
    th.join(120)
    seen_s = time.monotonic() - t_kill
    assert not th.is_alive()
    failed = box["out"].failed
    print(f"SIGKILLed job seen {seen_s:.1f} s later: {failed}")
    assert len(failed) == 2 and all("FAILED" in e for e in failed.values()) and seen_s < 15


def test_slurm_preempted_job_requeued_loses_only_its_trial_in_flight(
        slurm, tmp_path, local_files, monkeypatch):
    """`scontrol requeue` (SIGTERM, then the job is queued again) once a shard has finished one
    trial: nothing fails, the finished trial is not computed again."""
    cfg = cfg_of(tmp_path, *SLURM_FAST, "workers=1", "engine.shards=1")
    marks = tmp_path / "marks"
    with_fn(monkeypatch, Slow(marks, sleep=2))
    spool = Path(cfg.paths.out) / "logs" / "submitit" / "spool"
    th, box = in_thread(lambda: simulate(cfg))
    until("a trial spooled", lambda: spool.exists() and any(spool.glob("*.pkl")), 180)
    (job,) = slurm.jobs()
    first = {p.stem for p in spool.glob("*.pkl")}
    slurm.run("scontrol", "requeue", job)
    th.join(400)
    assert not th.is_alive()
    summary = box["out"]
    assert summary.ran == 6 and not summary.failed, summary.lines()
    runs = started(marks)
    assert all(len(runs[k]) == 1 for k in first), runs  # not computed again after the requeue
    assert sum(len(v) for v in runs.values()) <= 6 + 1  # at most the trial in flight twice
    restarts = slurm.run("sacct", "-n", "-X", "-j", job.split("_")[0], "-o", "Restarts",
                         check=False).stdout.split()
    print(f"requeued {job}: sacct Restarts {restarts}; computed {runs and len(runs)} trials")
    assert trial_files(tmp_path) == local_files


def test_slurm_short_time_limit_does_not_fail_a_healthy_shard(slurm, tmp_path, monkeypatch):
    """timeout_min=2 and a shard of ~65 s (two trials): with submitit's USR2@90 SLURM signals at
    0-30 s and the shard fails "timed-out and not checkpointable"."""
    cfg = cfg_of(tmp_path, *SLURM_FAST, "engine.timeout_min=2", "workers=1",
                 "trials.count=1", "conditions.periods=[10]", "conditions.references=[1.0]")
    with_fn(monkeypatch, Slow(tmp_path / "marks", sleep=25))
    t0 = time.monotonic()
    summary = simulate(cfg)
    print(f"one ~65 s shard under --time=2: {time.monotonic() - t0:.1f} s, {summary.lines()}")
    assert summary.ran == 2 and not summary.failed, summary.lines()


# --- Ray ---------------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def ray_cluster():
    pytest.importorskip("ray", reason="the ray extra: pip install -e '.[ray]'")
    t0 = time.monotonic()
    cluster = two_node_ray()
    print(f"Ray head + 2 worker nodes up in {time.monotonic() - t0:.1f} s")
    try:
        yield cluster
    finally:
        stop_ray(cluster)


def test_ray_two_nodes_match_local_run(ray_cluster, tmp_path, local_files):
    t0 = time.monotonic()
    summary = simulate(cfg_of(tmp_path, "engine=ray", f"engine.address={ray_cluster.address}",
                              "workers=2"))
    print(f"6 trials on two Ray nodes: {time.monotonic() - t0:.1f} s")
    assert summary.ran == 6 and not summary.failed, summary.lines()
    assert trial_files(tmp_path) == local_files


def test_ray_worker_node_removed_loses_only_its_trial(ray_cluster, tmp_path, local_files,
                                                     monkeypatch):
    cfg = cfg_of(tmp_path, "engine=ray", f"engine.address={ray_cluster.address}",
                 "workers=2")
    marks = tmp_path / "marks"
    with_fn(monkeypatch, Slow(marks, sleep=4))
    th, box = in_thread(lambda: simulate(cfg))
    until("a trial on each node", lambda: len({v[0] for v in started(marks).values()}) >= 2, 180)
    victim = next(n for n in ray_cluster.worker_nodes
                  if any(n.node_id in v for v in started(marks).values()))
    on_victim = {k for k, v in started(marks).items() if victim.node_id in v}
    t_kill = time.monotonic()
    ray_cluster.remove_node(victim, allow_graceful=False)
    th.join(300)
    assert not th.is_alive()
    summary = box["out"]
    print(f"node removed: run over {time.monotonic() - t_kill:.1f} s later\n"
          + "\n".join(summary.lines()))
    assert summary.failed and set(summary.failed) <= on_victim, (on_victim, summary.lines())
    assert all("NodeDiedError" in e or "died" in e.lower() for e in summary.failed.values())
    monkeypatch.undo()
    again = simulate(cfg)  # on the node that is left
    assert again.ran == len(summary.failed) and not again.failed
    assert trial_files(tmp_path) == local_files


def test_ray_trials_that_can_never_be_scheduled_fail_instead_of_waiting(ray_cluster, tmp_path,
                                                                        monkeypatch):
    """Every worker node removed (the head has no CPU): the trials left can never run; the
    driver fails them after RAY_LOST_S instead of waiting forever. Runs last: it empties the
    cluster."""
    monkeypatch.setattr(ray_engine, "RAY_POLL_S", 0.5)
    monkeypatch.setattr(ray_engine, "RAY_LOST_S", 2.0)
    cfg = cfg_of(tmp_path, "engine=ray", f"engine.address={ray_cluster.address}",
                 "workers=2")
    marks = tmp_path / "marks"
    with_fn(monkeypatch, Slow(marks, sleep=30))
    th, box = in_thread(lambda: simulate(cfg))
    until("a trial started", lambda: started(marks), 180)
    for node in list(ray_cluster.worker_nodes):
        ray_cluster.remove_node(node, allow_graceful=False)
    t_gone = time.monotonic()
    th.join(120)
    assert not th.is_alive(), "the driver waits for trials no node can run"
    summary = box["out"]
    print(f"no CPU left: run over {time.monotonic() - t_gone:.1f} s later; {summary.lines()[0]}")
    assert len(summary.failed) == 6
    assert sum("cannot be scheduled" in e for e in summary.failed.values()) >= 4
