"""Bodies from URDF files: the chain compiled into fixed transforms and rotations about
local z is exact against yourdfpy, and such a body learns through pipeline.simulate from a config
folder of its own (hydra.searchpath)."""
from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import gbmodel
from gbmodel.bodies import body_from

yourdfpy = pytest.importorskip("yourdfpy")
REPO = Path(__file__).resolve().parents[2]

# skewed axes, fixed joints between the revolute ones, a tool link, and a branch off the chain
ARM = """<?xml version="1.0"?>
<robot name="skew">
  <link name="world"/><link name="base"/><link name="l1"/><link name="l1b"/><link name="l2"/>
  <link name="l3"/><link name="l4"/><link name="tool"/><link name="camera"/>
  <joint name="mount" type="fixed"><parent link="world"/><child link="base"/>
    <origin xyz="0.1 -0.05 0.3" rpy="0.2 -0.1 0.4"/></joint>
  <joint name="j1" type="revolute"><parent link="base"/><child link="l1"/>
    <origin xyz="0 0 0.12" rpy="0 0 0"/><axis xyz="0 0 1"/>
    <limit lower="-2.0" upper="2.0" effort="1" velocity="1"/></joint>
  <joint name="elbow_mount" type="fixed"><parent link="l1"/><child link="l1b"/>
    <origin xyz="0.05 0.02 0.2" rpy="0.3 0.1 -0.2"/></joint>
  <joint name="j2" type="revolute"><parent link="l1b"/><child link="l2"/>
    <origin xyz="0.01 0 0.05" rpy="0 0.5 0"/><axis xyz="0.3 -0.8 0.52"/>
    <limit lower="-1.5" upper="1.0" effort="1" velocity="1"/></joint>
  <joint name="j3" type="revolute"><parent link="l2"/><child link="l3"/>
    <origin xyz="0.25 0.0 -0.03" rpy="-0.4 0 0.25"/><axis xyz="-1 0 0"/>
    <limit lower="-1.0" upper="1.8" effort="1" velocity="1"/></joint>
  <joint name="j4" type="revolute"><parent link="l3"/><child link="l4"/>
    <origin xyz="0.18 0.03 0.0" rpy="0 0 0"/><axis xyz="0 0.6 -0.8"/>
    <limit lower="-1.2" upper="1.2" effort="1" velocity="1"/></joint>
  <joint name="tool_joint" type="fixed"><parent link="l4"/><child link="tool"/>
    <origin xyz="0.07 -0.01 0.02" rpy="0.1 0.2 0.3"/></joint>
  <joint name="cam" type="fixed"><parent link="l2"/><child link="camera"/>
    <origin xyz="0 0.1 0" rpy="0 0 0"/></joint>
</robot>
"""
JOINTS = ["j1", "j2", "j3", "j4"]
BODY_YAML = """name: skew
description: a 4-DOF arm with skewed axes, from a URDF written by the test
urdf: {{file: {file}, root: world, tip: tool}}
outputs: [0, 1, 2]
normalise: true   # the URDF's limits
home: [0.0, 0.0, 0.0, 0.0]
grid: {{lo: [{lo0}, {lo1}, {lo2}], hi: [{hi0}, {hi1}, {hi2}], num: [3, 3, 2]}}
"""


@pytest.fixture(scope="module")
def urdf_file(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("urdf") / "skew.urdf"
    path.write_text(ARM)
    return path


def _desc(path, **changes) -> dict:
    return {"name": "skew", "urdf": {"file": str(path), "root": "world", "tip": "tool"},
            "outputs": [0, 1, 2], "normalise": True, "home": [0.0] * 4,
            "grid": {"lo": [0.0, 0.0, 0.0], "hi": [0.1, 0.1, 0.1], "num": [2, 2, 2]}, **changes}


def test_forward_matches_yourdfpy(urdf_file):
    body = body_from(_desc(urdf_file))
    robot = yourdfpy.URDF.load(str(urdf_file), load_meshes=False, build_collision_scene_graph=False)
    rng = np.random.default_rng(0)
    q = rng.uniform(-1, 1, size=(200, 4))
    got = body.forward(q)
    for qi, p in zip(q, got):
        angles = body.joint_angles(qi)
        robot.update_cfg(dict(zip(JOINTS, angles)))
        want = robot.get_transform(frame_to="tool", frame_from="world")[:3, 3]
        np.testing.assert_allclose(p, want, rtol=0, atol=1e-9)
    # the limits are the URDF's
    np.testing.assert_array_equal(body.q_min, [-2.0, -1.5, -1.0, -1.2])


def test_held_joints_and_a_hand_point(urdf_file):
    """joints: the commanded ones; hold: the others' angles; hand: a point in the tip's frame."""
    body = body_from(_desc(urdf_file, urdf={"file": str(urdf_file), "root": "world",
                                            "tip": "tool", "joints": ["j1", "j3", "j4"],
                                            "hold": {"j2": 0.4}},
                           home=[0.0] * 3, hand=[0.01, 0.02, -0.03]))
    robot = yourdfpy.URDF.load(str(urdf_file), load_meshes=False, build_collision_scene_graph=False)
    q = np.array([0.3, -0.2, 0.5])
    robot.update_cfg(dict(zip(["j1", "j2", "j3", "j4"], [*body.joint_angles(q)[:1], 0.4,
                                                         *body.joint_angles(q)[1:]])))
    T = robot.get_transform(frame_to="tool", frame_from="world")
    np.testing.assert_allclose(body.forward(q), T[:3, :3] @ [0.01, 0.02, -0.03] + T[:3, 3],
                               atol=1e-12)


def test_growth_scales_the_links(urdf_file):
    """Under growth the translations after each joint scale; the base's placement does not."""
    body = body_from(_desc(urdf_file))
    g = gbmodel.Growth(pattern="proportional")
    q = np.full(4, 0.2)
    base_point = body_from(_desc(urdf_file, urdf={"file": str(urdf_file), "root": "world",
                                                  "tip": "l1"}, home=[0.0])).forward([0.0])
    half = body.forward(q, g.scales(body, 0.5))
    full = body.forward(q)
    # the first joint sits where the base puts it: the hand's offset from it halves
    np.testing.assert_allclose(half - base_point, 0.5 * (full - base_point), atol=1e-12)
    assert body.segment_lengths.shape == (4,) and (body.segment_lengths > 0).all()


@pytest.mark.parametrize("changes, key", [
    (dict(tip="nowhere"), "body.urdf.tip"),
    (dict(root="camera"), "body.urdf.tip"),  # camera is a branch: camera -> tool is not serial
    (dict(joints=["j1", "j9"]), "body.urdf.joints"),
    (dict(joints=["j2", "j1"]), "body.urdf.joints"),
    (dict(hold={"j1": 0.1}), "body.urdf.hold"),
    (dict(file="/nonexistent/robot.urdf"), "body.urdf.file"),
    (dict(file={"package": "no-such-package", "path": "x.urdf"}), "body.urdf.file"),
])
def test_bad_urdf_descriptions_name_the_key(urdf_file, changes, key):
    urdf = {"file": str(urdf_file), "root": "world", "tip": "tool", **changes}
    with pytest.raises(ValueError) as err:
        body_from(_desc(urdf_file, urdf=urdf))
    assert str(err.value).startswith(key + "="), str(err.value)
    assert "\n" not in str(err.value)


@pytest.mark.parametrize("kind", ["prismatic", "floating", "planar"])
def test_other_joint_types_are_refused(tmp_path, kind):
    path = tmp_path / "p.urdf"
    path.write_text(ARM.replace('name="j3" type="revolute"', f'name="j3" type="{kind}"'))
    with pytest.raises(ValueError, match=rf"^body.urdf.root=.*'j3' on the chain is {kind}"):
        body_from(_desc(path))


def test_no_limits_with_normalise(tmp_path):
    path = tmp_path / "c.urdf"
    path.write_text(ARM.replace('name="j2" type="revolute"', 'name="j2" type="continuous"'))
    with pytest.raises(ValueError, match=r"^body.limits=None: .*URDF has none"):
        body_from(_desc(path))
    assert body_from(_desc(path, normalise=False)).m == 4


def kernel_learns_as_the_reference(body: dict, pattern: str) -> None:
    """The compiled kernel (float32) learns the general-chain body as the numpy reference
    (float64) does, with the same draws: the same curve and M up to float32 rounding (also
    tests/core/test_bodies_mjcf.py)."""
    def trial(fast):
        spec = gbmodel.TrialSpec(body=body, epochs=20, evals_per_decade=5,
                                 learner={"name": "goal_babbling", "fast": fast},
                                 growth={"pattern": pattern, "start_size": 0.5, "period": 10})
        return gbmodel.run_trial(spec, np.random.default_rng(3))
    fast, ref = trial(True), trial(False)
    np.testing.assert_allclose(fast.abs_error, ref.abs_error, rtol=1e-4, atol=1e-7)
    np.testing.assert_allclose(fast.M, ref.M, rtol=0, atol=1e-5)
    assert not np.array_equal(fast.M, ref.M)  # two paths indeed


@pytest.mark.parametrize("pattern", ["proportional", "proximal_first"])
def test_the_fast_kernel_computes_the_urdf_chain(urdf_file, pattern):
    kernel_learns_as_the_reference(_desc(urdf_file), pattern)


def test_fast_distances_of_a_urdf_body(urdf_file):
    """The fast path's evaluation (its own kinematics) against Body.forward."""
    from gbmodel.learners.goal_babbling import fast
    body = body_from(_desc(urdf_file))
    exps = gbmodel.exponents(3)
    M = np.random.default_rng(0).normal(0, 0.3, size=(4, len(exps)))
    xs = body.targets
    scale = np.array([0.9, 0.8, 0.7, 0.6])
    want = np.linalg.norm(body.forward(gbmodel.predict(M, xs, exps), scale) - xs, axis=-1)
    np.testing.assert_allclose(fast.distances(M, body, exps, scale, xs), want, atol=2e-6)


@pytest.mark.parametrize("pattern", ["proportional", "proximal_first"])
def test_online_goal_babbling_runs_the_urdf_chain(urdf_file, pattern):
    """Online Goal Babbling's compiled float64 loop takes the general chain too: the same curve
    and M as its numpy reference (Body.forward's chain_position) up to rounding, under growth;
    its compiled distances are Body.forward's."""
    from gbmodel.learners import online_goal_babbling as online

    def trial(fast):
        spec = gbmodel.TrialSpec(body=_desc(urdf_file), epochs=20, evals_per_decade=5,
                                 learner={"name": "online_goal_babbling", "fast": fast},
                                 growth={"pattern": pattern, "start_size": 0.5, "period": 10})
        return gbmodel.run_trial(spec, np.random.default_rng(3))
    fast, ref = trial(True), trial(False)
    np.testing.assert_allclose(fast.abs_error, ref.abs_error, rtol=1e-9)
    np.testing.assert_allclose(fast.M, ref.M, rtol=1e-9, atol=1e-12)
    body = body_from(_desc(urdf_file))
    params = online.Params()
    M = np.random.default_rng(0).normal(0, 0.3, size=(4, len(gbmodel.exponents(3))))
    state = online.State(M, np.zeros((4, 4)), 0, True, ())
    scale = np.array([0.9, 0.8, 0.7, 0.6])
    want = np.linalg.norm(body.forward(body.saturate(gbmodel.predict(M, body.targets,
                                                                     gbmodel.exponents(3))),
                                       scale) - body.targets, axis=-1)
    np.testing.assert_allclose(online.distances(state, params, body, scale, body.targets), want,
                               rtol=1e-12, atol=1e-15)


def test_a_urdf_body_learns_through_simulate(urdf_file, tmp_path):
    """A body YAML in the test's own config folder, found with hydra.searchpath."""
    body = body_from(_desc(urdf_file))
    reach = body.forward(np.random.default_rng(1).uniform(-0.3, 0.3, size=(400, 4)))
    lo, hi = np.quantile(reach, 0.3, axis=0), np.quantile(reach, 0.7, axis=0)
    conf = tmp_path / "conf" / "body"
    conf.mkdir(parents=True)
    (conf / "skew.yaml").write_text(BODY_YAML.format(
        file=urdf_file, **{f"lo{i}": round(float(v), 3) for i, v in enumerate(lo)},
        **{f"hi{i}": round(float(v), 3) for i, v in enumerate(hi)}))
    root = tmp_path / "out"
    cmd = [sys.executable, "-m", "pipeline.simulate", f"hydra.searchpath=[file://{conf.parent}]",
           "body=skew", "profile=smoke", "learner.epochs=60",
           "trials.count=1", "growth=none", f"paths.root={root}", "workers=1"]
    proc = subprocess.run(cmd, cwd=REPO, capture_output=True, text=True, timeout=300,
                          env={"PYTHONPATH": str(REPO), "PATH": "/usr/bin:/bin"})
    assert proc.returncode == 0, proc.stderr[-2000:] + proc.stdout[-2000:]
    records = [json.loads(p.read_text()) for p in root.rglob("*.json")
               if "labels" in json.loads(p.read_text())]
    assert records and all(r["status"] == "ok" for r in records), records[:1]
    assert records[0]["spec"]["body"]["urdf"]["tip"] == "tool"
