"""The README's new-robot recipe ("Another body"), run as written on a 7-DOF arm that this test
writes as a URDF (tests/new_robots.py: Panda-like), in a config folder of its own:
pipeline.tools.body prints the chain, limits and reach and proposes a reachable grid (pasted into
the body file), pipeline.tools.rate writes the learner settings file itself (--write), and 1,000
epochs reach the held-out targets within 1.5 % of the arm's reach, as read from aggregate's own
output. Also pipeline.tools.rate's file for a shipped body, with its rate, and the reachability
check on the test arms."""
import re
import shlex
import subprocess
import sys

import numpy as np
import pytest
import yaml
from omegaconf import OmegaConf

import gbmodel
from gbmodel import workspace
from pipeline import models
from pipeline.tools import body as body_tool
from pipeline.tools import rate
from pipeline.config import REPO_ROOT, compose

import new_robots

SECTION = REPO_ROOT.joinpath("README.md").read_text().split("**Another body**", 1)[1]
SECTION = SECTION.split("\n**", 1)[0]
CODE = "\n".join(ln.strip() for ln in SECTION.splitlines() if ln.startswith("    "))
RECIPE = CODE.replace(" \\\n", " ").splitlines()  # a line continued by a backslash is one


def run(line, env, root):
    args = [sys.executable] + shlex.split(line.replace("$MY_CONF", env["MY_CONF"]))[1:]
    return subprocess.run(args + [f"paths.root={root}"], capture_output=True, text=True,
                          cwd=root, env=env, timeout=600)


def test_the_readme_recipe_learns_a_new_urdf_robot(tmp_path):
    import os

    assert RECIPE[0] == "MY_CONF=$PWD/my_conf" and len(RECIPE) == 6, RECIPE
    stages = [line.split()[2] for line in RECIPE[1:]]
    assert stages == ["pipeline.tools.body", "pipeline.tools.rate", "pipeline.simulate",
                      "pipeline.aggregate", "pipeline.tools.body"], RECIPE
    assert RECIPE[5].endswith(" --within 1.5")  # the percentage the README promises
    assert RECIPE[2].endswith(" --write")
    folder = tmp_path / "my_conf"
    new_robots.write("panda_like", tmp_path)  # tmp/panda_like.urdf, tmp/conf/body/...
    (tmp_path / "conf").rename(folder)
    body_file = folder / "body" / "my_arm.yaml"
    (folder / "body" / "panda_like.yaml").rename(body_file)
    body_file.write_text(body_file.read_text().replace("name: panda_like", "name: my_arm"))
    env = dict(os.environ, PYTHONPATH=str(REPO_ROOT), MY_CONF=str(folder))

    r = run(RECIPE[1], env, tmp_path)  # the body inspector: chain, limits, reach, a grid
    assert r.returncode == 0, r.stderr
    assert re.search(r"^  7 +joint7 ", r.stdout, re.M) and "-2.897" in r.stdout, r.stdout
    shown = float(re.search(r"^reach: ([\d.]+) m", r.stdout, re.M).group(1))
    body = gbmodel.make_body(OmegaConf.to_container(compose(
        [f"hydra.searchpath=[file://{folder}]", "body=my_arm"]).body))
    assert shown == pytest.approx(new_robots.reach("panda_like", body), rel=0.02)
    grid = re.search(r"^  (grid: \{lo: .*\})$", r.stdout, re.M).group(1)  # pasted as printed
    g = OmegaConf.create(yaml.safe_load(grid.split(": ", 1)[1]))
    home = body.forward(body.home)
    assert all(lo <= h <= hi for lo, h, hi in zip(g.lo, home, g.hi)), (grid, home)
    body_file.write_text(re.sub(r"^grid: .*$", grid, body_file.read_text(), flags=re.M))

    r = run(RECIPE[2], env, tmp_path)  # pipeline.tools.rate --write
    assert r.returncode == 0, r.stderr
    where = folder / "body_learner" / "my_arm_goal_babbling.yaml"
    assert f"wrote {where}" in r.stderr and where.read_text() == r.stdout
    assert where.read_text().startswith("# @package learner\n") and "solver: lstsq" in r.stdout

    r = run(RECIPE[3] + " trials.count=3", env, tmp_path)  # pipeline.simulate
    assert r.returncode == 0, r.stderr[-3000:]
    assert "plain-step rate" not in r.stderr  # lstsq has no rate: no note about one
    r = run(RECIPE[4], env, tmp_path)  # pipeline.aggregate
    assert r.returncode == 0, r.stderr[-3000:]
    said = re.search(r"\[my_arm\] const1\.0: held out ([\d.]+) mm = ([\d.]+) % of the reach "
                     r"\(([\d.]+) m\)", r.stdout + r.stderr)
    assert said, r.stdout + r.stderr
    mm, pct, reach = map(float, said.groups())
    assert pct <= 1.5 and reach == pytest.approx(shown, abs=1e-3)

    r = run(RECIPE[5], env, tmp_path)  # every trial against the README's 1.5 %
    assert r.returncode == 0, r.stdout + r.stderr
    lines = r.stdout.splitlines()
    assert len(lines) == 4 and lines[-1] == "[my_arm] every one of 3 trials within 1.5 % of the reach"
    assert re.match(r"\[my_arm\] const1\.0 trial 0: held out [\d.]+ mm = [\d.]+ % of the reach$",
                    lines[0]), lines
    r = run(RECIPE[5].replace("1.5", "0.001"), env, tmp_path)  # a promise no trial keeps
    assert r.returncode == 1 and r.stdout.splitlines()[-1].startswith(
        "[my_arm] 3 of 3 trials above 0.001 % of the reach: const1.0 trial 0 ("), r.stdout

    fig = models.load("my_arm", tmp_path / "outputs" / "aggregate")
    m = fig["const1.0"]
    assert m.spec.learner["solver"] == "lstsq" and m.spec.learner["steps"] == 10
    assert m.spec.epochs == 1000
    xs = gbmodel.evaluation.heldout_points(m.body, m.size)
    errs = [np.linalg.norm(m.reach(xs, trial) - xs, axis=-1).mean() for trial in range(3)]
    assert mm == pytest.approx(1e3 * np.mean(errs), abs=0.06)  # what aggregate says is so


def test_rate_writes_no_empty_file_and_an_empty_one_is_named(tmp_path):
    """--write refuses a file without a setting; an empty file left by `rate > file` is one
    line naming it, not "Key 'body_learner' not in 'Config'"."""
    from pipeline import cli

    new_robots.write("panda_like", tmp_path)
    search = f"hydra.searchpath=[file://{tmp_path}/conf]"
    cfg = compose([search, "body=panda_like", "learner.solver=lstsq"])
    from pipeline.config import ConfigError

    with pytest.raises(ConfigError, match="no setting to write"):
        rate.write_settings(tmp_path / "x.yaml", rate.settings_file(
            compose(["body=arm5"]), tmp_path / "x.yaml", None))
    assert not (tmp_path / "x.yaml").exists()
    empty = tmp_path / "conf" / "body_learner" / "panda_like_goal_babbling.yaml"
    empty.parent.mkdir()
    empty.write_text("")
    line = cli.check([search, "body=panda_like"])
    assert line and line.startswith(f"{empty}: the file is empty"), line
    assert rate.write_settings(empty, rate.settings_file(cfg, empty, None)) is None
    assert cli.check([search, "body=panda_like", "profile=smoke"]) is None


def test_rate_write_keeps_the_settings_it_replaces(tmp_path):
    """--write over a file with other settings keeps them beside it (nothing silently replaced);
    the same settings again keep nothing."""
    target = tmp_path / "conf" / "body_learner" / "arm5_goal_babbling.yaml"
    target.parent.mkdir(parents=True)
    target.write_text("solver: gradient\nlearning_rate: 0.001\n")
    text = rate.settings_file(compose(["body=arm5", "learner.solver=lstsq"]), target, None)
    kept = rate.write_settings(target, text)
    assert target.read_text() == text
    assert kept == target.with_name(".arm5_goal_babbling.yaml.previous")
    assert kept.read_text() == "solver: gradient\nlearning_rate: 0.001\n"
    kept.unlink()
    assert rate.write_settings(target, text) is None and not kept.exists()


@pytest.mark.parametrize("name", new_robots.NAMES)
def test_the_reachability_check_has_no_false_positives_on_the_test_arms(tmp_path, name):
    """Hand positions of 1,000 random postures within the limits are reachable by definition:
    gbmodel.bodies.unreachable finds every one (one start per target missed up to 5 of 300),
    and the proposed grid is reached at full and half size."""
    import dataclasses

    new_robots.write(name, tmp_path)
    body = gbmodel.make_body(OmegaConf.to_container(compose(
        [f"hydra.searchpath=[file://{tmp_path}/conf]", f"body={name}"]).body))
    q = np.random.default_rng(11).uniform(-1, 1, size=(1000, body.m))
    reachable = dataclasses.replace(body, targets=body.forward(q))
    assert gbmodel.bodies.unreachable(reachable, np.random.default_rng(0)).size == 0
    assert gbmodel.bodies.unreachable(body, np.random.default_rng(0)).size == 0
    grid = body_tool.propose_grid(body, [4, 4, 4])
    assert grid is not None and grid["num"] == [4, 4, 4]
    assert workspace.reach(body) == pytest.approx(new_robots.reach(name, body), rel=0.02)


def test_rate_names_the_shipped_folder_and_prints_the_rate():
    """For a body of conf/ with the gradient step: W by the rule (small here), and the
    body's own settings (the iCub's R, K, L) in a file that composes to the same learner."""
    cfg = compose(["body=icub"])
    path = rate.destination(cfg)
    assert path == REPO_ROOT / "conf" / "body_learner" / "icub_goal_babbling.yaml"
    r = rate.rate(cfg, epochs=50, seeds=(0,))
    text = rate.settings_file(cfg, path, r)
    import yaml

    lines = text.splitlines()
    assert lines[0] == "# @package learner"
    data = yaml.safe_load(text)
    assert data == {"radius": 0.1, "targets_per_epoch": 30, "steps": 10,
                    "learning_rate": float(f"{r['learning_rate']:.3g}"), "rate_samples": 6020}


@pytest.mark.parametrize("learner", ["motor_babbling", "example_memory"])
def test_rate_refuses_another_learner_in_one_line(learner):
    """The rule is Goal Babbling's: another learner is a ConfigError (one line, exit 2); it was
    a traceback, the learner's missing `solver` read before the learner was checked."""
    from pipeline.config import ConfigError

    with pytest.raises(ConfigError, match=f"^learner={learner}: the rate rule is Goal "):
        rate.run(compose([f"learner={learner}"]), write=True)


@pytest.mark.parametrize("name", new_robots.NAMES)
def test_new_robots_are_sound_urdf_bodies(tmp_path, name):
    """Both arms compose from their own folder, are 7-DOF 3-D bodies of about a metre's reach,
    and their grid lies within it."""
    new_robots.write(name, tmp_path)
    cfg = compose([f"hydra.searchpath=[file://{tmp_path}/conf]", f"body={name}"])
    body = gbmodel.make_body(OmegaConf.to_container(cfg.body))
    assert body.m == 7 and body.n == 3 and body.general
    reach = new_robots.reach(name, body)
    assert 0.85 < reach < 1.0
    assert re.search(r"normalise: true", new_robots.body_yaml(name, "x.urdf"))
