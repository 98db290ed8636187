"""A body in the loop (gbmodel/body_loop.py): a Python forward function as a body. It computes
what a chain body computes, learns the same curve on the reference path, is refused on the
kernel, is keyed by its function's source and declared files, and bad functions are one line;
the MuJoCo example reproduces the MJCF body's curve."""
from __future__ import annotations

import importlib.util
import itertools
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import gbmodel
from gbmodel.bodies import body_from
from pipeline import cli
from pipeline.config import compose
from pipeline.plan import plan

REPO = Path(__file__).resolve().parents[2]
# a planar arm of two segments as a forward function: segment i's length times its factor
FORWARD = '''
import numpy as np

import gbmodel

@gbmodel.body_factory
def make(lengths=(0.3, 0.2), offset=0.0, width=3):
    lengths = np.asarray(lengths, float)

    def forward(angles, factors):
        a = np.cumsum(angles, axis=1)
        x = (lengths * factors * np.cos(a)).sum(axis=1) + offset
        y = (lengths * factors * np.sin(a)).sum(axis=1)
        return np.column_stack([x, y, np.zeros(len(a))])[:, :width]
    return forward

not_a_factory = 3

@gbmodel.body_factory
def gives_a_number():
    return 3
'''
GRID = {"lo": [0.1, 0.15], "hi": [0.3, 0.35], "num": [3, 3]}
_count = itertools.count()


@pytest.fixture
def module(tmp_path, monkeypatch):
    """A module of the test's own (a fresh name per test, as imports are cached), importable in
    this process and in the stages' worker processes."""
    name = f"loop_arm_{os.getpid()}_{next(_count)}"
    (tmp_path / f"{name}.py").write_text(FORWARD)
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.setenv("PYTHONPATH", os.pathsep.join([str(tmp_path), str(REPO)]))
    return name, tmp_path / f"{name}.py"


def _desc(factory, **callable_):
    return {"name": "loop_arm", "callable": {"factory": factory, **callable_},
            "outputs": [0, 1], "home": [1.0, 0.5], "grid": GRID}


DH = {"name": "dh_arm", "dh": [[0.3, 0, 0, 0], [0.2, 0, 0, 0]], "outputs": [0, 1],
      "home": [1.0, 0.5], "grid": GRID}


def test_the_forward_function_is_the_body(module):
    body = body_from(_desc(f"{module[0]}:make", lengths=[0.3, 0.2]))
    dh = body_from(DH)
    q = np.random.default_rng(0).uniform(-2, 2, size=(4, 5, 2))  # any leading shape
    k = np.array([0.6, 0.8])
    np.testing.assert_allclose(body.forward(q, k), dh.forward(q, k), atol=1e-15)
    np.testing.assert_array_equal(body.segment_lengths, [0.3, 0.2])
    assert body.frame_points(q[0, 0], k).shape == (1, 3)  # the hand: its joints are unknown


def test_it_learns_the_chain_bodys_curve(module):
    """The same draws, the same forward kinematics: the curve of the DH body, on the reference
    path, to floating-point tolerance (growing, with the exact solver)."""
    def trial(body):
        spec = gbmodel.TrialSpec(body=body, epochs=30, evals_per_decade=5,
                                 learner={"name": "goal_babbling", "fast": False,
                                          "solver": "lstsq", "ridge": 0.1},
                                 growth={"pattern": "proportional", "start_size": 0.5,
                                         "period": 15})
        return gbmodel.run_trial(spec, np.random.default_rng(4))
    loop, dh = trial(_desc(f"{module[0]}:make", lengths=[0.3, 0.2])), trial(DH)
    np.testing.assert_allclose(loop.abs_error, dh.abs_error, rtol=1e-9)
    np.testing.assert_allclose(loop.M, dh.M, rtol=1e-9, atol=1e-12)


def test_the_kernel_refuses_it(module, tmp_path):
    spec = gbmodel.TrialSpec(body=_desc(f"{module[0]}:make"), epochs=5,
                             learner={"name": "goal_babbling"})
    with pytest.raises(gbmodel.SpecError, match=r"^learner.fast=True: body 'loop_arm' is a body "
                                                r"in the loop .*set learner.fast=false$"):
        spec.validate()
    spec = gbmodel.TrialSpec(body=_desc(f"{module[0]}:make"), epochs=5,
                             learner={"name": "goal_babbling", "fast": False})
    assert spec.validate()


def _conf(tmp_path, body: dict) -> Path:
    conf = tmp_path / "conf" / "body"
    conf.mkdir(parents=True, exist_ok=True)
    (conf / f"{body['name']}.yaml").write_text(json.dumps(body))
    return conf.parent


def _key(conf, *overrides):
    cfg = compose([f"hydra.searchpath=[file://{conf}]", "body=loop_arm", "learner.fast=false",
                   "trials.count=1", "learner.epochs=10", *overrides])
    trial = plan(cfg)[0]
    return trial["key"], trial["spec"]["body"]["callable"]["sha256"]


def test_the_key_holds_the_function_its_files_and_version(module, tmp_path):
    name, source = module
    data = tmp_path / "lengths.txt"
    data.write_text("0.3 0.2")
    conf = _conf(tmp_path, _desc(f"{name}:make", files=[str(data)]))
    first = _key(conf)
    assert len(first[1]) == 64 and _key(conf) == first  # the same function: the same key
    source.write_text(FORWARD + "\n# an edit\n")
    edited = _key(conf)
    assert edited[0] != first[0] and edited[1] != first[1]
    data.write_text("0.3 0.25")
    assert _key(conf)[0] not in (first[0], edited[0])
    assert _key(conf, "+body.callable.version=2")[0] != _key(conf)[0]


def test_planning_says_what_the_key_does_not_hold(module, tmp_path, capsys):
    conf = _conf(tmp_path, _desc(f"{module[0]}:make"))
    assert cli.check([f"hydra.searchpath=[file://{conf}]", "body=loop_arm", "learner.fast=false",
                      f"paths.root={tmp_path / 'out'}", "trials.count=1"]) is None
    err = capsys.readouterr().err
    assert f"note: body.callable: the cache key holds {module[0]}:make" in err
    assert "change body.callable.version" in err


@pytest.mark.parametrize("factory, changes, says", [
    ("no_such_module_here:make", {}, "body.callable.factory='no_such_module_here:make': cannot "
                                     "import no_such_module_here"),
    ("{m}:nothing", {}, "has no callable nothing"),
    ("{m}", {}, "give module:attribute"),
    ("{m}:not_a_factory", {}, "has no callable not_a_factory"),
    ("{m}:gives_a_number", {}, "must return the forward function"),
    ("{m}:make", {"args": {"width": 2}}, "returned shape (1, 2) for 1 postures"),
    ("{m}:make", {"args": {"offset": float("nan")}}, "plain data"),
    ("{m}:make", {"args": [1]}, "body.callable.args=[1]: a mapping"),
    ("{m}:make", {"args": {"nosuch": 1}}, "TypeError"),
    ("{m}:make", {"lengths": [0.3]}, "body.callable.lengths=[0.3]: needs 2 lengths"),
    ("{m}:make", {"sha": 1}, "body.callable={"),
])
def test_bad_functions_are_one_line(module, factory, changes, says):
    with pytest.raises(ValueError) as err:
        body = body_from(_desc(factory.format(m=module[0]), **changes))
        body.forward(np.zeros(2))
    assert says in str(err.value) and "\n" not in str(err.value), str(err.value)


def test_fast_true_stops_the_command_line(module, tmp_path):
    conf = _conf(tmp_path, _desc(f"{module[0]}:make"))
    out = cli.check([f"hydra.searchpath=[file://{conf}]", "body=loop_arm",
                     f"paths.root={tmp_path / 'out'}", "trials.count=1"])
    assert out.startswith("learner.fast=True: body 'loop_arm' is a body in the loop"), out


def test_its_trials_are_cached(module, tmp_path):
    """Through simulate, twice: the second run finds every trial in the cache."""
    conf = _conf(tmp_path, _desc(f"{module[0]}:make"))
    cmd = [sys.executable, "-m", "pipeline.simulate", f"hydra.searchpath=[file://{conf}]",
           "body=loop_arm", "learner.fast=false", "learner.epochs=20", "trials.count=2",
           "growth=proportional", "growth.period=10", f"paths.root={tmp_path / 'out'}",
           "workers=1"]
    env = {"PYTHONPATH": os.environ["PYTHONPATH"], "PATH": "/usr/bin:/bin"}
    runs, stamps = [], []
    for _ in range(2):
        runs.append(subprocess.run(cmd, cwd=REPO, capture_output=True, text=True, timeout=300,
                                   env=env))
        assert runs[-1].returncode == 0, runs[-1].stderr[-2000:]
        files = sorted((tmp_path / "out").rglob("cache/trials/*/*.json"))
        stamps.append({p: p.stat().st_mtime_ns for p in files})
    assert len(stamps[0]) == 2 and stamps[1] == stamps[0]  # nothing run again, nothing added
    records = [json.loads(p.read_text()) for p in stamps[0]]
    assert all(r["status"] == "ok" for r in records)
    assert all(len(r["spec"]["body"]["callable"]["sha256"]) == 64 for r in records)
    assert "note: body.callable" in runs[0].stderr


@pytest.mark.skipif(None in (importlib.util.find_spec("mujoco"),
                            importlib.util.find_spec("gymnasium")),
                    reason="the example drives MuJoCo (pip install -e '.[mujoco]')")
def test_the_mujoco_example_reproduces_the_mjcf_curve(tmp_path):
    env = dict(os.environ, GBGROWTH_EPOCHS="20", GBGROWTH_EXAMPLE_OUT=str(tmp_path),
               PYTHONPATH=str(REPO))
    proc = subprocess.run([sys.executable, str(REPO / "examples" / "05_mujoco_in_the_loop.py")],
                          cwd=tmp_path, capture_output=True, text=True, timeout=600, env=env)
    assert proc.returncode == 0, proc.stderr[-2000:]
    lines = dict(line.split(": ", 1) for line in proc.stdout.splitlines() if ": " in line)
    gap = float(lines["forward kinematics, 1000 postures grown unevenly"].split()[2])
    curve = float(lines["curves, in the loop against the MJCF body (both reference)"].split()[-1])
    assert gap < 1e-12 and curve < 1e-9, proc.stdout
    assert (tmp_path / "mujoco_in_the_loop.png").stat().st_size
