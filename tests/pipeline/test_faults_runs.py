"""Runs that meet each other or a cache they cannot write: two sweeps of one figure started in the
same second keep their own groups, a cache where everything is cached is read without writing,
Hydra's own settings are never swept, and what the code fingerprint covers is pinned."""
import os
import subprocess
import sys
from pathlib import Path

import pytest

from pipeline import cache, cli, io
from pipeline.config import REPO_ROOT
from pipeline.fingerprint import source_fingerprint
from conftest import figure_trials, files_of, run_cli, tiny_overrides


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
    _sweep(tmp_path, "growth.period=10,20")  # within the run's 30 epochs
    _sweep(tmp_path, "growth.period=15,25")
    cache_dir = tmp_path / "outputs/smoke/cache"
    trials, problems = figure_trials(cache_dir, "custom")
    # the later sweep makes the figure alone: its two conditions, not the four of both sweeps
    assert sorted({t["condition"] for t in trials}) == ["TG15", "TG25"] and problems == []
    groups = [p for p in (cache_dir / cache.PLANS / "custom").iterdir() if p.is_dir()]
    assert len(groups) == 2
    assert sorted(len(list(g.glob("*.json"))) for g in groups) == [2, 2]  # two jobs each
    logs = sorted((tmp_path / "outputs/smoke/logs").glob("simulate-multirun/*"))
    assert len(logs) == 2  # each sweep's multirun.yaml in its own folder


# ---- Hydra's own settings are never swept -----------------------------------------------------
@pytest.mark.parametrize("sweep", [
    "+hydra.callbacks.x._target_=shutil.copyfile,os.remove",
    "hydra/launcher=nosuch,basic",
    "hydra/launcher=basic,joblib",
    "hydra.launcher.n_jobs=0,1",
    "hydra/job_logging=default,stdout",
    "hydra.searchpath=[file:///tmp],[file:///etc]",
])
@pytest.mark.parametrize("multirun", [["-m"], []])
def test_a_sweep_over_hydras_own_settings_is_one_line(tmp_path, sweep, multirun):
    out = cli.check([*multirun, sweep, f"paths.root={tmp_path}"])
    assert out is not None and out.startswith(sweep) and "one value per command" in out, out
    assert "\n" not in out and not any(tmp_path.iterdir())


def test_a_hydra_sweep_on_the_command_line_exits_2_before_hydra_starts(tmp_path):
    r = run_cli("pipeline.simulate", "-m", *tiny_overrides(
        tmp_path, "+hydra.callbacks.x._target_=shutil.copyfile,os.remove"))
    assert r.returncode == 2 and r.stderr.count("\n") == 1, r.stderr
    assert r.stderr.startswith("error: +hydra.callbacks.x._target_=shutil.copyfile,os.remove: ")
    assert not any(tmp_path.iterdir())


# ---- a read-only cache where everything is cached ----------------------------------------------
F4 = ("experiment=fig4", "figure=f4", "report.explain=false")
# `unshare -m`: a mount namespace of its own, where the cache is bound read-only (EROFS: root
# ignores permission bits, not a read-only mount)
_READ_ONLY = 'mount --bind "$1" "$1" && mount -o remount,bind,ro "$1" && shift && exec "$@"'


def _read_only_run(cache_dir, module, *args):
    env = dict(os.environ, PYTHONPATH=str(REPO_ROOT))
    return subprocess.run(["unshare", "-m", "sh", "-c", _READ_ONLY, "sh", str(cache_dir),
                           sys.executable, "-m", module, *args], capture_output=True, text=True,
                          cwd="/", env=env, timeout=300)


def _can_mount_read_only(tmp_path) -> bool:
    probe = tmp_path / "probe"
    probe.mkdir()
    r = subprocess.run(["unshare", "-m", "sh", "-c", _READ_ONLY + " || exit 3", "sh", str(probe),
                        "touch", str(probe / "x")], capture_output=True, text=True)
    return r.returncode == 1 and "Read-only" in r.stderr


def test_a_read_only_cache_with_everything_cached_is_read(tmp_path):
    if not _can_mount_read_only(tmp_path):
        pytest.skip("no read-only bind mount here (unshare -m and mount need CAP_SYS_ADMIN)")
    args = tiny_overrides(tmp_path, *F4)
    assert run_cli("pipeline.simulate", *args).returncode == 0
    cache_dir = tmp_path / "outputs/smoke/cache"
    kk = next((cache_dir / cache.TRIALS).iterdir())
    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"],
                          capture_output=True, text=True).stdout.strip()
    leftover = kk / f".x.json~{io._HOST}~{dead}~0.tmp"  # what a killed run of this host leaves
    leftover.write_text("")
    before = files_of(cache_dir)
    for module in ("pipeline.aggregate", "pipeline.simulate", "pipeline.report"):
        r = _read_only_run(cache_dir, module, *args)
        assert r.returncode == 0, (module, r.stderr)
        assert module != "pipeline.simulate" or "6 cached, 0 run" in r.stderr, r.stderr
    assert (tmp_path / "outputs/smoke/aggregate/f4/summary.parquet").exists()
    assert files_of(cache_dir) == before and leftover.exists()  # nothing written there
    # a trial that is not cached needs the cache: one line, before anything runs
    r = _read_only_run(cache_dir, "pipeline.simulate", *args, "trials.count=2")
    assert r.returncode == 2 and r.stderr.count("\n") == 1, r.stderr
    assert f"{cache_dir}/claims: read-only file system" in r.stderr


# ---- what the code fingerprint covers: whole files, on purpose ---------------------------------
def _evaluation():
    import gbmodel

    return "gbmodel/evaluation.py", (Path(gbmodel.__file__).parent / "evaluation.py").read_text()


def test_an_added_function_no_code_calls_changes_the_fingerprint_on_purpose():
    """The fingerprint hashes a file's whole syntax tree, not what the kernels reach: a function
    no code names can still change results (a numba @register_model or @overload, a registry's
    decorator, a redefinition of a name), so a spurious recompute is accepted, a missed one not."""
    label, text = _evaluation()
    base = source_fingerprint([(label, text)])
    unused = '\n\ndef unused_helper(x):\n    """Called by nothing."""\n    return x + 1\n'
    assert source_fingerprint([(label, text + unused)]) != base
    # what cannot change a result changes nothing: comments, docstrings, blank lines
    assert source_fingerprint([(label, text + "\n\n# a comment\n")]) == base
    assert source_fingerprint([(label, text.replace('"""', '"""Edited. ', 1))]) == base


def test_a_function_no_code_names_can_change_what_a_kernel_computes():
    """Why reachability is not enough: adding `f` changes `g`'s result without any call of f
    (the decorator registers it), so following calls from the kernels would miss it."""
    before = "TABLE = {}\n\ndef g(x):\n    return TABLE.get('scale', lambda v: v)(x)\n"
    added = ("\n\ndef put(fn):\n    TABLE['scale'] = fn\n    return fn\n\n"
             "@put\ndef f(v):\n    return 2 * v\n")
    results = []
    for text in (before, before + added):
        scope: dict = {}
        exec(compile(text, "<module>", "exec"), scope)
        results.append(scope["g"](3))
    assert results == [3, 6]
    assert source_fingerprint([("m.py", before)]) != source_fingerprint([("m.py", before + added)])


def test_a_root_that_does_not_exist_yet_is_made(tmp_path):
    root = tmp_path / "new" / "root"
    r = run_cli("pipeline.simulate", *tiny_overrides(root, *F4))
    assert r.returncode == 0, r.stderr
    assert (root / "outputs/smoke/cache/plans/f4/current.json").exists()
