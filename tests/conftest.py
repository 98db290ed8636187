"""Shared fixtures: configs composed the way the command line composes them, shrunk to seconds.

`compose_tiny(tmp_path, ...)` is the smoke profile made smaller still (few epochs, one trial,
one worker) and rooted in a temporary folder, so a test exercises the real config and code path
and writes nothing into the repository.
"""
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from pipeline.config import REPO_ROOT, compose

TINY = ("profile=smoke", "learner.epochs=30", "trials.count=1", "workers=1")
# what a plan record holds about the run that wrote it (when, which process): not its content
PLAN_RUN_FIELDS = ("created_ns", "pid")


def tiny_overrides(root: Path, *overrides: str) -> list[str]:
    return [*TINY, f"paths.root={root}", *overrides]


@pytest.fixture
def compose_tiny():
    def _compose(root, *overrides):
        return compose(tiny_overrides(root, *overrides))
    return _compose


def run_cli(module: str, *args: str, timeout: int = 300) -> subprocess.CompletedProcess:
    """`python -m module args` from a foreign working directory (the code must not rely on it)."""
    env = dict(os.environ, PYTHONPATH=str(REPO_ROOT))
    return subprocess.run([sys.executable, "-m", module, *args], capture_output=True, text=True,
                          cwd="/", env=env, timeout=timeout)


def files_of(folder: Path) -> dict[str, bytes]:
    """Relative path -> bytes of every file under folder, lock files left out. A plan record
    (cache/<figure>/plans/*.json) is compared by its content: the time and process id of the run
    that wrote it are dropped (its name already hashes the rest)."""
    out = {}
    for p in sorted(Path(folder).rglob("*")):
        if not p.is_file() or p.suffix == ".lock":
            continue
        data = p.read_bytes()
        if "plans" in p.relative_to(folder).parts and p.suffix == ".json":
            record = json.loads(data)
            for k in PLAN_RUN_FIELDS:
                record.pop(k, None)
            data = json.dumps(record, sort_keys=True).encode()
        out[p.relative_to(folder).as_posix()] = data
    return out


def figure_trials(cache_dir, figure: str) -> tuple[list[dict], list[str]]:
    """(trials as (condition label, trial index, key) dicts, problems) of a figure's current
    plan, as aggregate reads it."""
    from pipeline.aggregate import figure_conditions

    conds, _, problems = figure_conditions(cache_dir, figure)
    return [dict(condition=c["label"], trial=t["trial"], key=t["key"])
            for c in conds for t in c["trials"]], problems
