"""SIGTERM, SIGHUP and Ctrl-C stop a stage the same way: one line, exit 128 + the signal, and no
worker or resource-tracker process outlives the driver (found by pid in /proc)."""
import contextlib
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from pipeline.config import REPO_ROOT
from conftest import tiny_overrides

ENV = dict(os.environ, PYTHONPATH=str(REPO_ROOT))


def _children(pid: int) -> dict[int, str]:
    """pid -> command line of every process whose parent is `pid` (from /proc)."""
    out = {}
    for p in Path("/proc").iterdir():
        if not p.name.isdigit():
            continue
        try:
            ppid = int((p / "stat").read_text().rsplit(")", 1)[1].split()[1])
            if ppid == pid:
                out[int(p.name)] = (p / "cmdline").read_bytes().replace(b"\0", b" ").decode()
        except (OSError, IndexError, ValueError):
            continue
    return out


def _descendants(pid: int) -> dict[int, str]:
    """_children of `pid`, of theirs and so on (workers are the fork server's children)."""
    out, todo = {}, [pid]
    while todo:
        kids = _children(todo.pop())
        out.update(kids)
        todo += kids
    return out


def _workers(procs: dict[int, str]) -> int:
    """How many of `procs` are pool workers: spawned, or forks of the fork server."""
    return sum("spawn_main" in c or "forkserver" in c for c in procs.values()) - \
        any(_children(p) for p, c in procs.items() if "forkserver" in c)  # (the server)


def _running(pid: int) -> bool:
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except OSError:
        return False
    return state != "Z"


def _start(tmp_path, *extra):
    args = tiny_overrides(tmp_path, "learner.epochs=200000", "trials.count=2", "workers=2",
                          "growth=none", *extra)
    return subprocess.Popen([sys.executable, "-m", "pipeline.simulate", *args], cwd="/", env=ENV,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            start_new_session=True)


@pytest.mark.parametrize("sig, status", [(signal.SIGTERM, 143), (signal.SIGHUP, 129)])
def test_a_signal_to_the_driver_alone_stops_every_worker_and_the_tracker(tmp_path, sig, status):
    proc = _start(tmp_path)
    try:
        deadline, kids = time.monotonic() + 120, {}
        while time.monotonic() < deadline:  # two workers and the tracker, busy with the trials
            kids = _descendants(proc.pid)
            if _workers(kids) >= 2 and proc.poll() is None:
                break
            time.sleep(0.2)
        assert _workers(kids) >= 2, kids
        assert any("resource_tracker" in c for c in kids.values()), kids
        time.sleep(1.0)
        os.kill(proc.pid, sig)  # the driver alone, as `kill PID` or a scheduler does
        out, err = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
    assert proc.returncode == status, err
    assert err.strip().splitlines()[-1] == (f"stopped by {signal.Signals(sig).name}: finished "
                                            "work is cached; run the same command again to resume")
    assert "Traceback" not in err
    deadline = time.monotonic() + 20
    while any(map(_running, kids)) and time.monotonic() < deadline:
        time.sleep(0.2)
    assert not [kids[p] for p in kids if _running(p)]
    assert not list(Path(tmp_path).rglob(".*.tmp"))


def test_a_driver_killed_outright_takes_every_worker_with_it(tmp_path):
    """SIGKILL (no clean-up): the kernel ends the workers, and a fork server's, within seconds
    (each dies with its parent; the fork server with the driver), not after their trials."""
    proc = _start(tmp_path, "learner.epochs=30000000")  # minutes of work each
    try:
        deadline, kids = time.monotonic() + 120, {}
        while time.monotonic() < deadline:
            kids = _descendants(proc.pid)
            if _workers(kids) >= 2 and proc.poll() is None:
                break
            time.sleep(0.2)
        assert _workers(kids) >= 2, kids
        time.sleep(1.0)
        os.kill(proc.pid, signal.SIGKILL)
        proc.communicate(timeout=30)  # (its pipes stay open while a worker or the server runs)
        deadline = time.monotonic() + 20
        while any(map(_running, kids)) and time.monotonic() < deadline:
            time.sleep(0.2)
        assert not [kids[p] for p in kids if _running(p)]
    finally:
        with contextlib.suppress(ProcessLookupError):  # what is left of its group, if anything
            os.killpg(proc.pid, signal.SIGKILL)


def test_ctrl_c_to_the_whole_group_while_the_pool_starts_is_one_line(tmp_path):
    """A terminal's Ctrl-C reaches every process of the group, the fork server too while it
    loads the kernels: it ignores it (pipeline/preload.py), and the driver stops with one line."""
    proc = _start(tmp_path, "learner.epochs=30000000")
    try:
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline and not any(
                "forkserver" in c for c in _descendants(proc.pid).values()):
            time.sleep(0.02)
        os.killpg(proc.pid, signal.SIGINT)
        out, err = proc.communicate(timeout=60)
    finally:
        with contextlib.suppress(ProcessLookupError):
            os.killpg(proc.pid, signal.SIGKILL)
    assert proc.returncode == 130, err
    assert "Traceback" not in err and err.strip().splitlines()[-1].startswith("stopped by SIGINT")


def test_ctrl_c_in_the_first_second_is_one_line(tmp_path):
    proc = _start(tmp_path)
    time.sleep(0.6)  # in the middle of the imports
    proc.send_signal(signal.SIGINT)
    out, err = proc.communicate(timeout=60)
    assert proc.returncode == 130, err
    assert len(err.strip().splitlines()) == 1, err
    assert "Traceback" not in err and "SIGINT" in err


def test_a_signal_while_workers_start_is_raised_after_their_start():
    """stop.held (around a pool's submits): the signal is taken after the block, once, so no
    worker starts unknown to its pool (a fork server's would outlive the driver)."""
    from pipeline import stop

    order = []
    with stop.armed():
        with pytest.raises(stop.Stopped) as got:
            with stop.held():
                os.kill(os.getpid(), signal.SIGTERM)
                order.append("after the signal, in the block")
                os.kill(os.getpid(), signal.SIGINT)  # a second one while the first waits
                order.append("still in the block")
        assert got.value.signum == signal.SIGTERM
    assert order == ["after the signal, in the block", "still in the block"]
    with stop.armed(), pytest.raises(stop.Stopped):
        os.kill(os.getpid(), signal.SIGTERM)  # outside the block: at once
        time.sleep(1)
