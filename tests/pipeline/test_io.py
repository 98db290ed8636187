"""Writes stay under paths.root, temporary files are exclusive and judged by host and pid, limits
are checked before planning, and the building blocks of pipeline.io (output sets, seals, damaged
files, a full or read-only disk) each do what they promise: one line, never a traceback."""
import errno
import itertools
import json
import os
import subprocess
import sys
from pathlib import Path

import pyarrow as pa
import pytest

from pipeline import cli, execute, io
from pipeline.config import REPO_ROOT, ConfigError, check_stamp, compose
from conftest import files_of, run_cli, tiny_overrides

ENV = dict(os.environ, PYTHONPATH=str(REPO_ROOT))


# ---- paths.root, names that become paths ------------------------------------------------------
@pytest.mark.parametrize("root, shown", [
    ("paths.root=", "paths.root='': must be a folder"),
    ("paths.root=relative/x", "paths.root='relative/x': must be an absolute path"),
])
def test_an_empty_or_relative_root_is_refused(root, shown):
    assert cli.check(["profile=smoke", root]).startswith(shown)


def test_an_output_folder_outside_the_root_is_refused(tmp_path):
    problem = cli.check(tiny_overrides(tmp_path, f"paths.cache={tmp_path.parent}/elsewhere"))
    assert problem.startswith("paths.cache=") and "outside paths.root" in problem


def test_an_empty_root_on_the_command_line_exits_2_and_writes_nothing(tmp_path):
    r = subprocess.run([sys.executable, "-m", "pipeline.simulate", "profile=smoke",
                        "learner.epochs=30", "trials.count=1", "paths.root="],
                       cwd=tmp_path, env=ENV, capture_output=True, text=True, timeout=120)
    assert r.returncode == 2 and r.stderr.count("\n") == 1, r.stderr
    assert r.stderr.startswith("error: paths.root=''")
    assert not Path("/outputs").exists() and not list(tmp_path.iterdir())


@pytest.mark.parametrize("value", ["../../../../esc", "a/b", "..", ".hidden", "", "x\0y", "x\ny"])
def test_safe_name_refuses_what_is_not_one_plain_name(value):
    with pytest.raises(io.UnsafeName, match=r"^report\.postures="):
        io.safe_name("report.postures", value)


@pytest.mark.parametrize("value", ["TG1000", "const0.5", "tame | TG10", "eta=0.1", "fïg"])
def test_safe_name_keeps_plain_names(value):
    assert io.safe_name("figure", value) == value


def test_a_posture_figure_named_to_escape_is_refused_in_one_line(tmp_path):
    problem = cli.check(tiny_overrides(tmp_path, "++report.postures={../../../../esc: "
                                                 "[[fig4, TG1000]]}"))
    assert problem == ("report.postures='../../../../esc': must not contain a path separator "
                       "(it names a file or folder)")


def test_stamping_the_findings_needs_the_publishing_run(tmp_path):
    assert cli.check(tiny_overrides(tmp_path, "report.stamp_findings=true")).startswith(
        "report.stamp_findings=true: only with report.publish=true")
    with pytest.raises(ConfigError):
        check_stamp(compose(tiny_overrides(tmp_path, "report.stamp_findings=true")))
    check_stamp(compose(tiny_overrides(tmp_path, "report.stamp_findings=true",
                                       "report.publish=true")))


# ---- limits before planning ---------------------------------------------------------------------
@pytest.mark.parametrize("override, shown", [
    ("trials.count=100000000", "trials.count=100000000: at most 10,000 trials per condition"),
    ("learner.epochs=10000000000", "learner.epochs=10000000000: at most 1e+09 epochs per trial"),
    ("growth.period=99999999999999999999999999", "growth.period=99999999999999999999999999: at "
                                                 "most 9,223,372,036,854,775,807 epochs (int64)"),
    ("+foo=1", "foo: not a config key"),
    ("figure=fïg", "figure=fïg: Hydra reads characters beyond ASCII only inside quotes"),
])
def test_limits_and_unknown_keys_are_one_line_before_planning(tmp_path, override, shown):
    assert cli.check(tiny_overrides(tmp_path, override)).startswith(shown)


def test_a_huge_trial_count_exits_2_at_once_on_the_command_line(tmp_path):
    r = run_cli("pipeline.simulate", *tiny_overrides(tmp_path, "trials.count=100000000"),
                timeout=60)
    assert r.returncode == 2 and r.stderr.count("\n") == 1, r.stderr
    assert not list(tmp_path.iterdir())


def test_a_shrinking_body_is_allowed_with_a_note(tmp_path, capsys):
    assert cli.check(tiny_overrides(tmp_path, "growth.start_size=2", "growth.end_size=1",
                                    "growth.period=10")) is None
    assert "the body shrinks" in capsys.readouterr().err


def test_workers_are_capped_by_the_cpus_with_a_note(capsys, monkeypatch):
    monkeypatch.setattr(execute, "cpus", lambda: 2)
    assert execute.capped(1_000_000, 50) == 2
    assert "workers=1000000: this machine has 2 CPUs; running 2 workers" in capsys.readouterr().err
    assert execute.capped(4, 1) == 1 and execute.capped(2, 8) == 2


# ---- temporary files ----------------------------------------------------------------------------
def test_temp_files_never_follow_a_symlink_nor_reuse_a_file(tmp_path, monkeypatch):
    target = tmp_path / "victim"
    target.write_text("keep")
    monkeypatch.setattr(io, "_serial", iter([0, 1]))
    planted = io._tmp_name(tmp_path / "out.json")
    planted.symlink_to(target)  # someone plants the name the next write would take
    monkeypatch.setattr(io, "_serial", iter([0, 1]))
    io.write_json(tmp_path / "out.json", {"a": 1})
    assert target.read_text() == "keep"
    assert json.loads((tmp_path / "out.json").read_text()) == {"a": 1}
    assert "~" in planted.name and f"~{os.getpid()}~" in planted.name


def test_stale_temp_files_are_judged_by_host_and_pid(tmp_path):
    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"],
                          capture_output=True, text=True).stdout.strip()
    mine_dead = tmp_path / f".a.json~{io._HOST}~{dead}~0.tmp"
    mine_alive = tmp_path / f".b.json~{io._HOST}~{os.getpid()}~0.tmp"
    other_host = tmp_path / f".c.json~another-node.cluster~{dead}~0.tmp"
    old_form = tmp_path / f".d.json.{dead}.tmp"
    for p in (mine_dead, mine_alive, other_host, old_form):
        p.write_text("x")
    assert io.remove_stale_tmp(tmp_path) == [mine_dead]
    assert mine_alive.exists() and other_host.exists() and old_form.exists()


# ---- (a) an output set replaced as one -----------------------------------------------------------
def test_a_new_set_replaces_the_old_one_in_one_step(tmp_path):
    folder = tmp_path / "aggregate" / "fig4"
    folder.mkdir(parents=True)
    (folder / "summary.parquet").write_text("old layout")  # a plain folder, first time
    with io.new_set(folder) as new:
        io.write_text(new / "summary.parquet", "one")
        io.write_text(new / "curves.parquet", "one")
    assert folder.is_symlink() and (folder / "summary.parquet").read_text() == "one"
    first = io.set_of(folder)
    with pytest.raises(RuntimeError):  # killed (or failing) half-way: the old set stays whole
        with io.new_set(folder) as new:
            io.write_text(new / "summary.parquet", "two")
            raise RuntimeError("killed")
    assert io.set_of(folder) == first and (folder / "curves.parquet").read_text() == "one"
    with io.new_set(folder) as new:
        io.write_text(new / "summary.parquet", "three")
    assert sorted(p.name for p in folder.iterdir()) == ["summary.parquet"]
    assert not first.exists()  # the replaced set went
    assert len(list((tmp_path / "aggregate" / ".fig4.sets").iterdir())) == 1


# ---- (b) a seal over a whole record --------------------------------------------------------------
def test_a_seal_covers_every_field_of_a_sidecar():
    record = io.seal(dict(status="ok", M=[[0.1, 0.2]], snapshots={"10": [[1.0]]}, error=None,
                          curve_sha256="ab"))
    back = json.loads(io.dump_json(record))
    assert io.check_seal(back) == back
    for field, value in [("M", [[0.1, 0.3]]), ("status", "diverged"), ("snapshots", {}),
                         ("error", "x")]:
        with pytest.raises(io.DamagedFile, match="side.json: damaged"):
            io.check_seal({**back, field: value}, "side.json")
    with pytest.raises(io.DamagedFile, match="no seal"):
        io.check_seal({k: v for k, v in back.items() if k != "seal"})


# ---- (c) damaged files named --------------------------------------------------------------------
def test_damaged_json_and_parquet_are_named_in_one_line(tmp_path):
    bad = tmp_path / "models.json"
    bad.write_text('{"fig3": [')
    with pytest.raises(io.DamagedFile, match=r"models\.json: damaged, not valid JSON"):
        io.read_json(bad)
    bad.write_text('{"a": 1}')
    with pytest.raises(io.DamagedFile, match="lacks 'choice'"):
        io.read_json(bad, need=("choice",))
    curves = tmp_path / "curves.parquet"
    io.write_table(curves, pa.table({"a": [1, 2, 3]}))
    curves.write_bytes(curves.read_bytes()[:-20])
    with pytest.raises(io.DamagedFile, match=r"curves\.parquet: damaged") as err:
        io.read_table(curves)
    assert "\n" not in str(err.value)
    io.write_table(curves, pa.table({"a": [1]}))
    with pytest.raises(io.DamagedFile, match="lacks the columns"):
        io.read_table(curves, schema=io.CURVE)


def test_finish_turns_damage_a_full_disk_and_a_read_only_folder_into_one_line(capsys):
    def damaged(cfg):
        raise io.DamagedFile("x.json: damaged")

    def full(cfg):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), "/data/out/a.parquet")

    def read_only(cfg):
        raise OSError(errno.EROFS, os.strerror(errno.EROFS), "/data/out/plans/1.json")

    for run, shown in [(damaged, "error: x.json: damaged\n"),
                       (full, "error: /data/out/a.parquet: no space left on the device; free "
                              "space or choose a writable paths.root\n"),
                       (read_only, "error: /data/out/plans/1.json: read-only file system; free "
                                   "space or choose a writable paths.root\n")]:
        with pytest.raises(SystemExit) as ex:
            cli.finish(run, None)
        assert ex.value.code == 2 and capsys.readouterr().err == shown


@pytest.mark.skipif(os.geteuid() == 0, reason="root writes into read-only folders")
def test_a_read_only_folder_is_named_with_the_final_file(tmp_path):
    folder = tmp_path / "ro"
    folder.mkdir()
    folder.chmod(0o555)
    try:
        with pytest.raises(PermissionError) as err:
            io.write_json(folder / "plan.json", {})
        assert err.value.filename == str(folder / "plan.json")
        assert cli.disk_message(err.value) == (f"{folder / 'plan.json'}: permission denied; "
                                               "free space or choose a writable paths.root")
    finally:
        folder.chmod(0o755)


def test_a_full_disk_while_writing_names_the_file_and_leaves_no_temp(tmp_path, monkeypatch):
    def no_space(*a, **k):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    import pyarrow.parquet as pq
    monkeypatch.setattr(pq, "write_table", no_space)
    with pytest.raises(OSError) as err:
        io.write_table(tmp_path / "curves.parquet", pa.table({"a": [1]}))
    assert err.value.errno == errno.ENOSPC and err.value.filename == str(tmp_path / "curves.parquet")
    assert not list(tmp_path.iterdir())


# ---- (d) a trial's files written with few system calls, the same bytes ------------------------
def test_a_sealed_sidecar_is_the_bytes_of_seal_and_write_json(tmp_path):
    records = [dict(status="ok", M=[[0.1, -2e-300, 1 / 3]], snapshots={"10": [[float("nan"), 1e300]]},
                    key="ab", labels={"trial": 1, "é": "ü\n"}, largest_jump=float("inf"),
                    error=None, curve_sha256="ff", seed={"spawn_key": [1, 2]}),
               {}, dict(seal="an old one", a=True, b=[]), dict(z=1, A=2, _=3, a=-0.0)]
    for r in records:
        io.write_json(tmp_path / "a.json", io.seal(r), compact=True)
        assert io.sealed_json(r) == (tmp_path / "a.json").read_bytes()
        assert io.check_seal(json.loads(io.sealed_json(r)))


def test_a_write_in_a_checked_folder_makes_it_and_never_follows_a_link(tmp_path, monkeypatch):
    root = tmp_path / "root"
    path = root / "trials" / "ab" / "x.json"
    with io.confined(root):
        io.write_in_checked(str(path), b"one")  # the folder is made
        assert path.read_bytes() == b"one"
        monkeypatch.setattr(io, "_serial", iter([0, 1]))
        planted = io._tmp_name(path)
        victim = tmp_path / "victim"
        victim.write_text("keep")
        planted.symlink_to(victim)  # the temporary name the next write would take
        monkeypatch.setattr(io, "_serial", iter([0, 1]))
        io.write_in_checked(str(path), memoryview(b"two"))
        assert path.read_bytes() == b"two" and victim.read_text() == "keep"
        planted.unlink()
        monkeypatch.setattr(io, "_serial", itertools.count(2))
        link = path.with_name("y.json")
        link.symlink_to(victim)  # a link leading outside the root is refused, as check_inside does
        with pytest.raises(io.UnsafeName, match="outside paths.root"):
            io.write_in_checked(str(link), b"three")
        assert victim.read_text() == "keep"

    def no_space(*a, **k):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    monkeypatch.setattr(os, "write", no_space)
    with pytest.raises(OSError) as err:
        io.write_in_checked(str(path), b"four")
    assert err.value.errno == errno.ENOSPC and err.value.filename == str(path)
    assert sorted(p.name for p in path.parent.iterdir()) == ["x.json", "y.json"]  # no temp left
    assert path.read_bytes() == b"two"


def test_a_trials_files_are_those_write_table_and_write_json_write(tmp_path):
    from pipeline import cache
    from pipeline.plan import plan

    trials = plan(compose(tiny_overrides(tmp_path, "body=arm5", "learner.epochs=3",
                                         "trials.count=2", "conditions.periods=[2]")))
    for t in trials:
        result = execute.run_one(t)
        cache.write_trial(tmp_path / "new", t, result)
        curve, side = cache.trial_paths(tmp_path / "old", t)
        record = {k: t[k] for k in cache.CONTENT} | dict(status="ok")
        record["curve_sha256"] = io.write_table(curve, io.trial_curve_table(result), False)
        record.update(largest_jump=float(result["largest_jump"]), M=result["M"].tolist(),
                      snapshots={})
        io.write_json(side, io.seal(record), compact=True)
        for old, new in zip((curve, side), cache.trial_paths(tmp_path / "new", t)):
            assert new.read_bytes() == old.read_bytes()
        assert cache.check(tmp_path / "new", t)[0]["status"] == "ok"


def test_a_trials_curve_is_written_without_pandas():
    """pa.array asks pandas about every array it is given (importing it: 0.6 s of CPU in
    simulate's driver, which needs no pandas); the curve's columns are taken as buffers."""
    code = ("import sys, numpy as np; from pipeline import io; "
            "r = dict(epoch=np.arange(1, 4), samples=np.arange(3) * 7, size=np.ones(3), "
            "abs_error=np.array([0.1, np.nan, 2.0]), rel_error=np.ones(3), "
            "heldout_abs_error=np.zeros(3), uniform_abs_error=np.zeros(3), "
            "path_abs_error=np.zeros(3)); t = io.trial_curve_table(r); "
            "assert t.column('abs_error').null_count == 0; io.table_bytes(t); "
            "print('pandas' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], env=ENV, capture_output=True, text=True)
    assert out.stdout.strip() == "False", out.stderr
    r = dict(epoch=[1, 2], samples=[3, 4], size=[0.5, 1.0], abs_error=[0.1, float("nan")],
             rel_error=[1.0, 2.0], heldout_abs_error=[0.0, 1.0], uniform_abs_error=[0.0, 1.0],
             path_abs_error=[0.0, 1.0])  # lists: pa.array as before
    assert io.table_bytes(io.trial_curve_table(r)) == io.table_bytes(pa.Table.from_arrays(
        [pa.array(r[f.name], type=f.type) for f in io.TRIAL_CURVE], schema=io.TRIAL_CURVE))
