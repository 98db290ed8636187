"""Shared fixtures: configs composed the way the command line composes them, shrunk to seconds.

`compose_tiny(tmp_path, ...)` is the smoke profile made smaller still (few epochs, one trial,
one worker) and rooted in a temporary folder, so a test exercises the real config and code path
and writes nothing into the repository.
"""
import dataclasses
import json
import os
import subprocess
import sys
import types
from pathlib import Path

import numpy as np
import pytest

import gbmodel
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


def run_cli(module: str, *args: str, timeout: int = 300, env: dict | None = None
            ) -> subprocess.CompletedProcess:
    """`python -m module args` from a foreign working directory (the code must not rely on it);
    env: more environment (a PYTHONPATH in it comes after the repository's)."""
    extra = dict(env or {})
    path = os.pathsep.join([str(REPO_ROOT), *filter(None, [extra.pop("PYTHONPATH", None)])])
    env = dict(os.environ, **extra, PYTHONPATH=path)
    return subprocess.run([sys.executable, "-m", module, *args], capture_output=True, text=True,
                          cwd="/", env=env, timeout=timeout)


def declare_plugin(folder: Path, group: str, name: str, module: str, source: str) -> None:
    """A distribution in `folder` (put it on the Python path) whose entry point `name` of
    `group` (gbgrowth.engines, gbgrowth.studies) is the module `module`, written from `source`:
    what `pip install` of a package of one's own leaves (pipeline.plugins)."""
    folder.mkdir(parents=True, exist_ok=True)
    (folder / f"{module}.py").write_text(source)
    info = folder / f"{module}-0.1.dist-info"
    info.mkdir(exist_ok=True)
    (info / "METADATA").write_text(f"Metadata-Version: 2.1\nName: {module}\nVersion: 0.1\n")
    (info / "entry_points.txt").write_text(f"[{group}]\n{name} = {module}\n")


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


# ---- the engines' runs (pipeline/test_engines_slow, pipeline/test_engines_cluster): fig4 at smoke scale --------
ENGINE_SMOKE = ("experiment=fig4", "profile=smoke", "learner.epochs=200", "trials.count=1")


def cfg_of(root: Path, *overrides: str):
    """fig4 at smoke scale, 6 trials of 200 epochs, rooted at `root`."""
    return compose([*ENGINE_SMOKE, f"paths.root={root}", *overrides])


def trial_files(root: Path) -> dict[str, bytes]:
    """Relative path -> bytes of the trials a run under `root` cached (cache/trials/: a curve and
    a sealed sidecar per trial), lock files left out: the files an engine must write byte for
    byte as a local run does. Plans and failed trials' records lie outside cache/trials/."""
    folder = root / "outputs/smoke/cache/trials"
    return {p.relative_to(folder).as_posix(): p.read_bytes() for p in sorted(folder.rglob("*"))
            if p.is_file() and p.suffix != ".lock" and p.name != ".lock"}


@pytest.fixture(scope="module")
def local_files(tmp_path_factory):
    """The trial files of that run on one local worker: what every engine must write."""
    from pipeline.simulate import simulate

    root = tmp_path_factory.mktemp("local")
    summary = simulate(cfg_of(root, "workers=1"))
    assert summary.ran == 6 and not summary.failed
    files = trial_files(root)
    assert len(files) == 12  # a curve and a sidecar per trial
    return files


def figure_trials(cache_dir, figure: str) -> tuple[list[dict], list[str]]:
    """(trials as (condition label, trial index, key) dicts, problems) of a figure's current
    plan, as aggregate reads it."""
    from pipeline.aggregate_set import figure_conditions

    conds, _, problems = figure_conditions(cache_dir, figure)
    return [dict(condition=c["label"], trial=t["trial"], key=t["key"])
            for c in conds for t in c["trials"]], problems


# ---- a learner that never learns (registered at run time by the architecture and trial tests) ---
@dataclasses.dataclass(frozen=True)
class StayParams:
    """A learner that never learns: it commands the home posture for every target."""

    reach: float = 0.0  # unused; a field, to show that the schema is generated from Params

    def validate(self) -> "StayParams":
        if isinstance(self.reach, bool) or not isinstance(self.reach, (int, float)) \
                or not self.reach >= 0:
            raise gbmodel.SpecError("learner.reach", self.reach, "must be >= 0")
        return self


def stay_home_module(name: str = "stay_home") -> types.ModuleType:
    m = types.ModuleType(name)
    m.Params = StayParams
    m.init = lambda params, body, size, rng: None
    m.draw = lambda params, body, B, rng: (np.zeros(B),)
    m.train = lambda state, params, body, sizes, scales, draws, epochs: state
    m.predict = lambda state, params, body, x: np.tile(body.home, (len(x), 1))
    m.model = lambda state: None
    m.samples_per_epoch = lambda params, body: 1
    return m
