"""The front door (issue 53, item 1; issue 54, rows 38, 41 and 44): Hydra's own settings are
allowed key by key and checked as they resolve, a user's config file that a shipped one hides is
named in one line, and a composed config and a stage write nothing of the project's own into
its package tree.
"""
import pytest

from conftest import REPO_ROOT, declare_plugin, run_cli, tiny_overrides
from pipeline import cli

BASE = ["figure=bi", "learner.epochs=20", "trials.count=1", "workers=1"]


# ---- rows 41 and 44: Hydra's folders and names behind an interpolation ---------------------------
@pytest.mark.parametrize("args, value, says", [
    # row 41: the folder Hydra writes its three files to, named by the environment
    (["hydra.run.dir=${paths.out}/runs/x", "hydra.output_subdir=${oc.env:GBG_X}"], "HIT",
     "hydra.output_subdir='HIT'"),
    (["hydra.run.dir=${paths.out}/runs/x", "hydra.output_subdir=${oc.env:GBG_X}"],
     "../../../../esc", "hydra.output_subdir='../../../../esc'"),  # a variant: climbs out
    (["hydra.run.dir=${oc.env:GBG_X}", "hydra.output_subdir=.hydra"], "HIT",
     "hydra.run.dir='HIT': outside paths.root"),
    # row 44: a sweep's subfolder and the job's name
    (["hydra.sweep.subdir=${oc.env:GBG_X}"], "HIT", "hydra.sweep.subdir='HIT'"),
    (["hydra.sweep.subdir=a/${oc.env:GBG_X}"], "../../../esc", "hydra.sweep.subdir='a/../../../esc'"),
    (["hydra.sweep.dir=${oc.env:GBG_X}/sweeps"], "HIT", "hydra.sweep.dir='HIT/sweeps': outside"),
    (["hydra.job.name=${oc.env:GBG_X}"], "../../x", "hydra.job.name"),
    (["hydra.job.name=job_${oc.env:GBG_X}"], "a/b", "hydra.job.name"),
    (["hydra.output_subdir=${oc.env:GBG_UNSET_ZZ}", "hydra.run.dir=${paths.out}/r"], None,
     "hydra.output_subdir: cannot be resolved before the run"),
])
def test_hydra_settings_are_checked_as_they_resolve(tmp_path, monkeypatch, args, value, says):
    hit = tmp_path / "outside"
    if value is not None:
        monkeypatch.setenv("GBG_X", value.replace("HIT", str(hit)))
    out = cli.check([*args, *BASE, f"paths.root={tmp_path / 'root'}"])
    says = says.replace("HIT", str(hit))
    assert out is not None and says in out and "\n" not in out, out
    assert not (tmp_path / "root").exists() and not hit.exists()


@pytest.mark.parametrize("args", [
    ["hydra.run.dir=${paths.out}/runs/x", "hydra.output_subdir=${oc.env:GBG_X}"],
    ["hydra.job.name=${oc.env:GBG_X}"],
    ["hydra.sweep.subdir=${oc.env:GBG_X}_${hydra.job.num}"],
])
def test_an_interpolation_that_resolves_inside_the_root_passes(tmp_path, monkeypatch, args):
    monkeypatch.setenv("GBG_X", "mine")
    assert cli.check([*args, *BASE, f"paths.root={tmp_path}"]) is None


def test_a_hydra_key_outside_the_allow_list_is_one_line(tmp_path):
    for arg in ("+hydra.runtimes.x=1", "+hydra.job.env_copy=[PATH]", "hydra.job.env_copy=[HOME]"):
        out = cli.check([arg, *BASE, f"paths.root={tmp_path}"])
        assert out is not None and out.startswith("hydra.") and "\n" not in out, (arg, out)


def test_a_config_file_on_the_searchpath_is_checked_as_it_resolves(tmp_path, monkeypatch):
    """A body YAML on hydra.searchpath that sets Hydra's output_subdir from the environment."""
    (tmp_path / "conf" / "body").mkdir(parents=True)
    (tmp_path / "conf" / "body" / "sly.yaml").write_text(
        "# @package _global_\ndefaults:\n  - /body/arm5@body\nhydra:\n  run:\n"
        "    dir: ${paths.out}/r\n  output_subdir: ${oc.env:GBG_X}\n")
    monkeypatch.setenv("GBG_X", str(tmp_path / "outside"))
    out = cli.check([f"hydra.searchpath=[file://{tmp_path / 'conf'}]", "body=sly", *BASE,
                     f"paths.root={tmp_path / 'root'}"])
    assert out is not None and out.startswith("hydra.output_subdir="), out


def test_the_command_line_refuses_hydra_files_outside_the_root_and_writes_nothing(tmp_path):
    hit = tmp_path / "outside"
    r = run_cli("pipeline.simulate", "hydra.run.dir=${paths.out}/runs/x",
                "hydra.output_subdir=${oc.env:GBG_X}", *BASE, f"paths.root={tmp_path / 'root'}",
                env={"GBG_X": str(hit)})
    assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1, r.stderr
    assert r.stderr.startswith("error: hydra.output_subdir=")
    assert not hit.exists() and not (tmp_path / "root").exists()


# ---- row 38: a user's config file that a shipped one hides -----------------------------------------
def test_a_conf_file_of_the_working_directory_that_a_shipped_one_hides_is_named(
        tmp_path, monkeypatch, capsys):
    (tmp_path / "conf" / "body").mkdir(parents=True)
    (tmp_path / "conf" / "body" / "arm5.yaml").write_text("name: arm5\n")
    (tmp_path / "conf" / "body" / "my_arm.yaml").write_text("name: my_arm\n")  # its own name
    monkeypatch.chdir(tmp_path)
    assert cli.check([*BASE, f"paths.root={tmp_path / 'out'}"]) is None
    err = capsys.readouterr().err.splitlines()
    ignored = [ln for ln in err if "is ignored" in ln]
    assert ignored == [f"note: {tmp_path / 'conf' / 'body' / 'arm5.yaml'} is ignored: the "
                       "shipped config body/arm5 has that name (Hydra reads the shipped one); "
                       "give yours another name"], err


def test_a_searchpath_file_that_a_shipped_one_hides_is_named(tmp_path, capsys):
    """The same for a folder of hydra.searchpath (a variant: an experiment of the same name)."""
    (tmp_path / "mine" / "experiment").mkdir(parents=True)
    (tmp_path / "mine" / "experiment" / "fig2.yaml").write_text("# @package _global_\n")
    assert cli.check([f"hydra.searchpath=[file://{tmp_path / 'mine'}]", *BASE,
                      f"paths.root={tmp_path / 'out'}"]) is None
    err = capsys.readouterr().err
    assert "experiment/fig2.yaml is ignored: the shipped config experiment/fig2" in err, err


def test_a_config_package_declared_as_an_entry_point_adds_its_bodies(tmp_path):
    """A distribution's package of config files (an entry point of gbgrowth.conf) is on the
    search path after the shipped ones: its body composes and runs; a package not declared
    adds nothing."""
    package = tmp_path / "plugins" / "gbgrowth_bodies_toy"
    (package / "body").mkdir(parents=True)
    (package / "body" / "toy_arm.yaml").write_text(
        (REPO_ROOT / "conf" / "body" / "arm5.yaml").read_text().replace("name: arm5",
                                                                         "name: toy_arm"))
    args = tiny_overrides(tmp_path / "run", "body=toy_arm", "growth=none", "figure=toy")
    r = run_cli("pipeline.simulate", *args, env={"PYTHONPATH": str(tmp_path / "plugins")})
    assert r.returncode == 2 and "body=toy_arm: unknown option" in r.stderr, r.stderr
    declare_plugin(tmp_path / "plugins", "gbgrowth.conf", "toy", "gbgrowth_bodies_toy", "")
    (tmp_path / "plugins" / "gbgrowth_bodies_toy.py").unlink()  # the package, not a module
    (package / "__init__.py").write_text("")
    r = run_cli("pipeline.simulate", *args, env={"PYTHONPATH": str(tmp_path / "plugins")})
    assert r.returncode == 0 and "1 trials: 0 cached, 1 run, 0 failed" in r.stderr, r.stderr


# ---- issue 53 item 4: no memo of the project's own in its package tree ----------------------------
def _package_files() -> dict[str, tuple]:
    """The files under gbmodel/, pipeline/, conf/ but Python's and numba's caches (*.pyc,
    numba's *.nbi/*.nbc and the stamp that keeps them fresh: gbmodel/simd.py)."""
    out = {}
    for top in ("gbmodel", "pipeline", "conf"):
        for p in (REPO_ROOT / top).rglob("*"):
            if p.is_file() and not p.name.endswith((".pyc", ".nbi", ".nbc", "kernels.stamp")):
                st = p.stat()
                out[str(p.relative_to(REPO_ROOT))] = (st.st_size, st.st_mtime_ns)
    return out


def test_composing_and_running_a_stage_write_nothing_into_the_package(tmp_path):
    before = _package_files()
    args = tiny_overrides(tmp_path, "figure=quiet", "growth=none")
    for stage in ("pipeline.simulate", "pipeline.aggregate", "pipeline.report"):
        r = run_cli(stage, *args, "report.explain=false", "report.animate=false")
        assert r.returncode == 0, r.stderr[-2000:]
    after = _package_files()
    assert {k: v for k, v in after.items() if before.get(k) != v} == {}
    assert (tmp_path / "outputs").is_dir()
