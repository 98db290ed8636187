"""Every command of the README's "Your own experiment" section and of the recipes it links to
(docs/running.md, "Recipes") runs as written (on tiny settings in a temporary root), and the
README's Python example loads a model and draws the arm."""
import os
import re
import shlex
import subprocess
import sys
from pathlib import Path

import pytest

from pipeline.config import REPO_ROOT

SECTION = REPO_ROOT.joinpath("README.md").read_text().split("## Your own experiment", 1)[-1]
SECTION = SECTION.split("\n## ", 1)[0]
RECIPES = REPO_ROOT.joinpath("docs", "running.md").read_text().split("\n## Recipes", 1)[-1]
RECIPES = RECIPES.split("\n## ", 1)[0]
BLOCKS = re.findall(r"```(bash|python)\n(.*?)```", SECTION, re.S)
COMMANDS = [ln.strip() for kind, text in BLOCKS + re.findall(r"```(bash)\n(.*?)```", RECIPES, re.S)
            if kind == "bash" for ln in text.splitlines()
            if ln.strip().startswith(".venv/bin/python -m pipeline.")]
PYTHON = [text for kind, text in BLOCKS if kind == "python"]
# tiny settings appended to each command: short trials, one of each, this test's own root
TINY = ("learner.epochs=30", "trials.count=1", "workers=1")


def run(args, root):
    env = dict(os.environ, PYTHONPATH=str(REPO_ROOT))
    return subprocess.run([sys.executable, *args], capture_output=True, text=True, cwd=root,
                          env=env, timeout=300)


def test_the_section_has_every_kind_of_example():
    stages = {c.split()[2] for c in COMMANDS}
    assert {"pipeline.simulate", "pipeline.aggregate", "pipeline.report",
            "pipeline.tools.rate"} <= stages
    assert any(" -m learner." in c or "-m learner=" in c for c in COMMANDS)  # a sweep
    assert any("body=" in c for c in COMMANDS) and any("growth=" in c for c in COMMANDS)
    assert len(PYTHON) == 1 and "models.load" in PYTHON[0]


def _short_periods(arg: str) -> str:
    """growth.period=100,1000 -> growth.period=10,15: as many distinct periods, each within the
    tiny run (a period longer than the run is refused)."""
    if not arg.startswith("growth.period="):
        return arg
    n = len(arg.split("=", 1)[1].split(","))
    return "growth.period=" + ",".join(str(10 + 5 * i) for i in range(n))


@pytest.fixture(scope="module")
def tree(tmp_path_factory):
    """Every command of the section, in order, into one root; then the Python example."""
    root = tmp_path_factory.mktemp("readme")
    done = []
    for command in COMMANDS:
        args = shlex.split(command)[1:]  # `-m pipeline.<stage> ...` under this interpreter
        stage = args[1]
        if stage == "pipeline.simulate":  # growth periods within the tiny run's 30 epochs
            args = [_short_periods(a) for a in args] + list(TINY)
        if stage == "pipeline.tools.rate":
            continue  # its rule runs 3 x 20,000 epochs: tests/e2e/test_own_experiment.py runs it small
        r = run(args + [f"paths.root={root}"], root)
        done.append((command, r))
    return root, done


@pytest.mark.parametrize("i", range(len(COMMANDS)))
def test_every_readme_command_runs(tree, i):
    root, done = tree
    if COMMANDS[i].split()[2] == "pipeline.tools.rate":
        pytest.skip("the rate rule's full run is tested small in e2e/test_own_experiment.py")
    command, r = next(d for d in done if d[0] == COMMANDS[i])
    assert r.returncode == 0, f"{command}\n{r.stderr[-2000:]}"


def test_the_readme_loads_a_model_and_draws_the_arm(tree):
    root, _ = tree
    assert 'models.load("vsweep")' in PYTHON[0]  # by its name: paths.root's outputs/, any profile
    # as in an installed package's folder: paths.root is the working directory (this test's root)
    r = run(["-c", "import os, pipeline.config; pipeline.config.default_root = os.getcwd\n"
             + PYTHON[0]], root)
    assert r.returncode == 0, r.stderr[-2000:]
    assert (root / "outputs" / "reach.png").exists()
