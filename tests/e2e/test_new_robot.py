"""The README's new-robot recipe ("Another body"), run as written on a 7-DOF arm that this test
writes as a URDF (tests/new_robots.py: Panda-like), in a config folder of its own: pipeline.tools.rate
prints a settings file that names where it goes, the file works when pasted there, and 1,000
epochs reach the held-out targets within 1.5 % of the arm's reach. Also pipeline.tools.rate's file for
a shipped body, with its rate."""
import re
import shlex
import subprocess
import sys

import numpy as np
import pytest
from omegaconf import OmegaConf

import gbmodel
from gbmodel import evaluation
from pipeline import models
from pipeline.tools import rate
from pipeline.config import REPO_ROOT, compose

import new_robots

SECTION = REPO_ROOT.joinpath("README.md").read_text().split("**Another body**", 1)[1]
SECTION = SECTION.split("\n**", 1)[0]
RECIPE = [ln.strip() for ln in SECTION.splitlines() if ln.startswith("    ")]


def run(line, env, root):
    args = [sys.executable] + shlex.split(line.replace("$MY_CONF", env["MY_CONF"]))[1:]
    return subprocess.run(args + [f"paths.root={root}"], capture_output=True, text=True,
                          cwd=root, env=env, timeout=600)


def test_the_readme_recipe_learns_a_new_urdf_robot(tmp_path):
    import os

    assert RECIPE[0] == "MY_CONF=$PWD/my_conf" and len(RECIPE) == 4, RECIPE
    folder = tmp_path / "my_conf"
    new_robots.write("panda_like", tmp_path)  # tmp/panda_like.urdf, tmp/conf/body/...
    (tmp_path / "conf").rename(folder)
    body_file = folder / "body" / "my_arm.yaml"
    (folder / "body" / "panda_like.yaml").rename(body_file)
    body_file.write_text(body_file.read_text().replace("name: panda_like", "name: my_arm"))
    env = dict(os.environ, PYTHONPATH=str(REPO_ROOT), MY_CONF=str(folder))

    r = run(RECIPE[1], env, tmp_path)  # pipeline.tools.rate
    assert r.returncode == 0, r.stderr
    where = folder / "body_learner" / "my_arm_goal_babbling.yaml"
    assert r.stdout.startswith("# @package learner\n") and f"# {where}:" in r.stdout, r.stdout
    assert f"put these lines into {where}" in r.stderr
    where.parent.mkdir()
    where.write_text(r.stdout)  # pasted as printed

    r = run(RECIPE[2] + " trials.count=3", env, tmp_path)  # pipeline.simulate
    assert r.returncode == 0, r.stderr[-3000:]
    r = run(RECIPE[3], env, tmp_path)  # pipeline.aggregate
    assert r.returncode == 0, r.stderr[-3000:]

    fig = models.load("my_arm", tmp_path / "outputs" / "aggregate")
    m = fig["const1.0"]
    assert m.spec.learner["solver"] == "lstsq" and m.spec.learner["steps"] == 10
    assert m.spec.epochs == 1000
    body = m.body
    reach = new_robots.reach("panda_like", body)
    xs = evaluation.heldout_points(body, m.size)
    for trial in range(3):
        err = np.linalg.norm(m.reach(xs, trial) - xs, axis=-1).mean()
        assert err <= 0.015 * reach, (trial, err, reach)


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
