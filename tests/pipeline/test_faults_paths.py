"""Nothing outside the root, and every stage heals what a kill leaves: planted links refused,
keys and records from disk checked before they become paths, leftover temporary links, sets and
files of dead processes of this host removed (another host's kept), never taken for figures."""
import os
import subprocess
import sys

import pytest

from pipeline import aggregate, cache, io, report, simulate
from pipeline.config import compose

TINY = ["experiment=fig4", "figure=f4", "profile=smoke", "learner.epochs=30", "trials.count=1",
        "workers=1"]


@pytest.fixture(autouse=True)
def _unconfined():
    yield
    io.confine(None)


def _cfg(root, *more):
    return compose([*TINY, f"paths.root={root}", *more])


def _dead_pid() -> int:
    p = subprocess.Popen([sys.executable, "-c", "pass"])
    p.wait()
    return p.pid


@pytest.fixture(scope="module")
def made(tmp_path_factory):
    """f4 simulated and aggregated once; tests copy it."""
    root = tmp_path_factory.mktemp("made")
    cfg = _cfg(root)
    simulate.simulate(cfg)
    assert aggregate.aggregate(cfg) == []
    return root


def _copy(made, tmp_path):
    import shutil
    shutil.copytree(made, tmp_path / "r", symlinks=True)
    return tmp_path / "r"


def test_a_switching_link_left_by_a_kill_is_no_figure_and_is_healed(made, tmp_path):
    root = _copy(made, tmp_path)
    cfg = _cfg(root)
    agg = root / "outputs/smoke/aggregate"
    left = agg / f".f4~{io._HOST}~{_dead_pid()}~6.tmp"
    os.symlink(os.readlink(agg / "f4"), left)
    theirs = agg / f".f4~otherhost~{_dead_pid()}~6.tmp"
    os.symlink(os.readlink(agg / "f4"), theirs)
    assert report.aggregated(agg) == ["f4"]  # the report never takes it for a figure
    leaked = agg / ".f4.sets" / f"set~{io._HOST}~{_dead_pid()}~3"
    leaked.mkdir()
    io.confine(root)
    with io.new_set(agg / "f4") as fresh:
        (fresh / "x").write_text("x")
    assert not left.is_symlink() and not leaked.exists()
    assert theirs.is_symlink()  # another host's: its process may be running


def test_report_temp_files_of_dead_processes_are_removed_others_kept(tmp_path):
    out = tmp_path / "latest"
    dead, alive = _dead_pid(), os.getppid()
    mine = tmp_path / f"..latest.inputs.json~{io._HOST}~{dead}~0.tmp"
    old_dir = tmp_path / f".latest.new~{io._HOST}~{dead}~1.tmp"
    running = tmp_path / f".latest.new~{io._HOST}~{alive}~1.tmp"
    other = tmp_path / f".latest.new~otherhost~{dead}~1.tmp"
    mine.write_text("{")
    for d in (old_dir, running, other):
        d.mkdir()
    with io.new_dir(out) as tmp:
        (tmp / "report.md").write_text("x")
    assert not mine.exists() and not old_dir.exists()
    assert running.exists() and other.exists()
    assert (out / "report.md").read_text() == "x"


def test_two_reports_finishing_at_once_both_succeed(tmp_path, monkeypatch):
    out = tmp_path / "latest"
    real = os.rename
    raced = []

    def rename(src, dst):
        if str(dst) == str(out) and not raced:  # another report puts its set in first
            raced.append(1)
            (out).mkdir(exist_ok=True)
            (out / "theirs.md").write_text("theirs")
        return real(src, dst)

    monkeypatch.setattr(os, "rename", rename)
    with io.new_dir(out) as tmp:
        (tmp / "report.md").write_text("ours")
    assert raced and sorted(p.name for p in out.iterdir()) == ["report.md"]


def test_a_report_reading_during_a_switch_retries_once(made, tmp_path, monkeypatch):
    root = _copy(made, tmp_path)
    agg = root / "outputs/smoke/aggregate"
    real, calls = io.set_of, []

    def gone_first(link):
        calls.append(link)
        return tmp_path / "removed-set" if len(calls) == 1 else real(link)

    monkeypatch.setattr(io, "set_of", gone_first)
    aggs = report.load_aggregates(agg)
    assert list(aggs) == ["f4"] and len(calls) == 2


@pytest.mark.parametrize("planted", ["trials", "plans", "sets"])
def test_links_planted_inside_the_outputs_are_refused(tmp_path, planted):
    root, elsewhere = tmp_path / "r", tmp_path / "elsewhere"
    elsewhere.mkdir()
    cfg = _cfg(root)
    io.confine(root)
    if planted == "sets":
        simulate.simulate(cfg)
        (root / "outputs/smoke/aggregate").mkdir(parents=True)
        os.symlink(elsewhere, root / "outputs/smoke/aggregate/.f4.sets")
        (elsewhere / "set~h~1~0").mkdir()
        with pytest.raises(io.UnsafeName, match="a link"):
            aggregate.aggregate(cfg)
        assert (elsewhere / "set~h~1~0").exists()
        return
    from pipeline.plan import plan
    key = plan(cfg)[0]["key"]
    where = {"trials": root / "outputs/smoke/cache/trials" / key[:2],
             "plans": root / "outputs/smoke/cache/plans/f4"}[planted]
    where.parent.mkdir(parents=True)
    os.symlink(elsewhere, where)
    with pytest.raises(io.UnsafeName, match="leads outside paths.root"):
        simulate.simulate(cfg)
    assert not any(elsewhere.iterdir())


def test_the_command_line_refuses_a_planted_link_in_one_line(tmp_path):
    from conftest import run_cli
    root, elsewhere = tmp_path / "r", tmp_path / "elsewhere"
    elsewhere.mkdir()
    (root / "outputs/smoke/cache").mkdir(parents=True)
    os.symlink(elsewhere, root / "outputs/smoke/cache/plans")
    r = run_cli("pipeline.simulate", *TINY, f"paths.root={root}")
    assert r.returncode == 2 and r.stderr.strip().splitlines()[-1].startswith("error: "), r.stderr
    assert "leads outside paths.root" in r.stderr and not any(elsewhere.iterdir())


@pytest.mark.parametrize("damage, says", [
    ("key", "conditions are malformed"),
    ("spec", "conditions are malformed"),
    ("outside", "conditions are malformed"),
    ("group", "which is not there"),
])
def test_malformed_plan_records_are_one_line(made, tmp_path, damage, says):
    root = _copy(made, tmp_path)
    plans = root / "outputs/smoke/cache/plans/f4"
    if damage == "group":
        io.write_json(plans / "current.json", dict(group="run-0000000000000000"))
    else:
        (path,) = (plans / cache.read_current(plans)).glob("*.json")
        record = io.read_json(path)
        cond = record["conditions"][0]
        if damage == "key":
            del cond["trials"][0]["key"]
        elif damage == "spec":
            cond["spec"] = {}
        else:
            cond["trials"][0]["key"] = "../../../../etc/passwd"
        io.write_json(path, record)
    with pytest.raises(io.DamagedFile, match=says):
        cache.figure_conditions(root / "outputs/smoke/cache", "f4")


def test_a_damaged_current_pointer_is_replaced_by_simulate(made, tmp_path):
    root = _copy(made, tmp_path)
    (root / "outputs/smoke/cache/plans/f4/current.json").write_text("{")
    s = simulate.simulate(_cfg(root))
    assert s.cached == s.total
    assert cache.read_current(root / "outputs/smoke/cache/plans/f4")


def test_a_curves_file_holding_another_table_is_damaged(made, tmp_path):
    root = _copy(made, tmp_path)
    d = io.set_of(root / "outputs/smoke/aggregate/f4")
    os.chmod(d, 0o755)
    (d / "curves.parquet").unlink()
    import shutil
    shutil.copy(d / "summary.parquet", d / "curves.parquet")
    with pytest.raises(io.DamagedFile, match="curves.parquet: damaged, lacks the columns"):
        report.load_aggregates(root / "outputs/smoke/aggregate")
