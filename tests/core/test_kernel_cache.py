"""A damaged numba cache file is found, removed and compiled again, with one line saying so."""
import os
import shutil
import subprocess
import sys

import pytest

from pipeline import warm
from pipeline.config import REPO_ROOT


def _warm(copy):
    return subprocess.run([sys.executable, "-m", "pipeline.warm"], cwd=copy, capture_output=True,
                          text=True, timeout=600, env=dict(os.environ, PYTHONPATH=str(copy)))


def test_a_damaged_kernel_cache_is_removed_and_compiled_again(tmp_path):
    copy = tmp_path / "repo"
    for part in ("gbmodel", "pipeline", "conf"):  # mtimes kept: numba's cache stays valid
        shutil.copytree(REPO_ROOT / part, copy / part, copy_function=shutil.copy2)
    assert _warm(copy).returncode == 0  # the cache is complete (loaded, or compiled once)
    from gbmodel.learners.goal_babbling import rollout
    line = rollout._distances.py_func.__code__.co_firstlineno  # the index of today's code, not a
    index = next((copy / "gbmodel/learners/goal_babbling/__pycache__").glob(  # stale one's
        f"rollout._distances-{line}.*.nbi"))
    index.write_bytes(index.read_bytes()[:30])  # truncated, as by a full disk
    r = _warm(copy)
    assert r.returncode == 0, r.stderr
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(
        "numba's cache of a kernel was damaged (UnpicklingError"), r.stderr
    assert str(index) in lines[0]
    assert index.stat().st_size > 30  # written again
    again = _warm(copy)
    assert again.returncode == 0 and again.stderr == ""


def test_an_error_not_from_the_cache_is_raised_unchanged():
    calls = []

    def broken():
        calls.append(1)
        raise EOFError("not numba's")

    with pytest.raises(EOFError):
        warm.recovering(broken)
    assert calls == [1]
