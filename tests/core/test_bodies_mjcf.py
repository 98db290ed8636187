"""Bodies from MJCF files (MuJoCo's models): the chain read with the standard library's XML
parser agrees with MuJoCo's own mj_kinematics (where `mujoco` is installed) on a model written to
exercise the format (default classes, childclass, every orientation, frames, includes, joint
anchors and refs, sites) and on Gymnasium's Pusher, Reacher and humanoid arm; bad models are one
line naming the key; an MJCF body learns on the kernels and through the pipeline."""
from __future__ import annotations

import importlib.util
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import gbmodel
from gbmodel import mjcf
from gbmodel.bodies import body_from
from pipeline import cli

import gym_robots

REPO = Path(__file__).resolve().parents[2]

# every feature of the format the reader takes: default classes (nested, class=, childclass
# through a frame), euler (compiler's angle and eulerseq), axisangle, quat, xyaxes, zaxis, a
# site's fromto, two hinges in one body, joint anchors (pos) and refs, an include from a
# subfolder; a floating body beside the arm
MODEL = """<mujoco model="skew">
  {compiler}
  <default>
    <joint axis="0 1 0" range="-90 90"/>
    <site size="0.01"/>
    <default class="arm">
      <joint axis="1 0 0" pos="0.01 0 0"/>
      <default class="wrist">
        <joint axis="0 0.6 -0.8" range="-45 60" ref="10"/>
        <site pos="0.02 0.01 -0.03" quat="0.9 0.1 0.2 0.3"/>
      </default>
    </default>
  </default>
  <worldbody>
    <body name="base" pos="0.1 -0.05 0.3" euler="10 -5 20">
      <geom type="sphere" size="0.05"/>
      <joint name="j1" axis="0 0 1" range="-120 120"/>
      <body name="upper" pos="0.05 0.02 0.2" axisangle="1 1 0 30" childclass="arm">
        <geom type="sphere" size="0.05"/>
        <joint name="j2"/>
        <joint name="j2b" class="main" axis="0 1 1" range="-30 30"/>
        <frame pos="0.01 0.0 0.05" xyaxes="0 1 0 -1 0 0.2">
          <body name="fore" pos="0.25 0 -0.03" quat="0.8 0.1 -0.3 0.2">
            <geom type="sphere" size="0.05"/>
            <joint name="j3" ref="-20" pos="0 0.02 0"/>
            <include file="parts/hand.xml"/>
          </body>
        </frame>
      </body>
    </body>
    <body name="floating" pos="0 1 1">
      <freejoint name="float"/>
      <geom type="sphere" size="0.05"/>
      <body name="limb" pos="0.2 0 0">
        <joint name="limb_hinge" axis="0 1 0"/>
        <geom type="sphere" size="0.05"/>
      </body>
    </body>
  </worldbody>
  {extra}
</mujoco>
"""
HAND = """<mujoco>
  <body name="hand" pos="0.18 0.03 0" zaxis="0.3 0.4 0.8" childclass="wrist">
    <geom type="sphere" size="0.05"/>
    <joint name="j4"/>
    <site name="tool"/>
    <site name="pointer" class="main" fromto="0 0 0 0.05 0.02 0.01" type="capsule" size="0.005"/>
  </body>
</mujoco>
"""
COMPILERS = ["", '<compiler eulerseq="zyx"/>', '<compiler angle="radian" eulerseq="ZYX"/>',
             '<compiler eulerseq="XzY"/>']
CHAINS = [("world", "tool"), ("world", "pointer"), ("world", "hand"), ("base", "tool"),
          ("upper", "hand"), ("floating", "limb")]
GRID = {"lo": [0.0, 0.0, 0.0], "hi": [0.1, 0.1, 0.1], "num": [2, 2, 2]}


def write_model(folder: Path, compiler: str = "", extra: str = "", model: str = MODEL) -> Path:
    (folder / "parts").mkdir(parents=True, exist_ok=True)
    (folder / "parts" / "hand.xml").write_text(HAND)
    path = folder / "skew.xml"
    path.write_text(model.format(compiler=compiler, extra=extra))
    return path


def _desc(path, root="world", tip="tool", **changes) -> dict:
    m = len(mjcf.read_chain(str(path), root, tip)["frames"])
    return {"name": "skew", "mjcf": {"file": str(path), "root": root, "tip": tip},
            "outputs": [0, 1, 2], "normalise": False, "home": [0.0] * m, "grid": GRID, **changes}


def mujoco_positions(path, names, angles, root, tip, hand, base=None):
    """MuJoCo's own forward kinematics (mj_kinematics) of the hand point `hand` of `tip` (a body
    or a site) in `root`'s frame, with the named joints at `angles` (N, m) and every other
    joint at its qpos0; `base` (3 x 4) before the root."""
    import mujoco

    model = mujoco.MjModel.from_xml_path(str(path))
    data = mujoco.MjData(model)
    adr = [model.jnt_qposadr[model.joint(n).id] for n in names]
    out = []
    for q in angles:
        data.qpos[:] = model.qpos0
        data.qpos[adr] = q
        mujoco.mj_kinematics(model, data)
        try:
            b = model.body(tip).id
            x, R = data.xpos[b], data.xmat[b].reshape(3, 3)
        except KeyError:
            s = model.site(tip).id
            x, R = data.site_xpos[s], data.site_xmat[s].reshape(3, 3)
        p = x + R @ np.asarray(hand, float)
        if root != "world":
            r = model.body(root).id
            p = data.xmat[r].reshape(3, 3).T @ (p - data.xpos[r])
        out.append(p if base is None else base[:, :3] @ p + base[:, 3])
    return np.array(out)


@pytest.mark.parametrize("compiler", COMPILERS)
@pytest.mark.parametrize("root, tip", CHAINS)
def test_forward_matches_mujoco(tmp_path, monkeypatch, compiler, root, tip):
    """Random postures agree with MuJoCo's mj_kinematics to 1e-12 m."""
    pytest.importorskip("mujoco")
    monkeypatch.chdir(tmp_path)  # MuJoCo's log file, if it writes one
    path = write_model(tmp_path, compiler)
    hand = [0.01, -0.02, 0.03]
    body = body_from(_desc(path, root, tip, hand=hand))
    names = mjcf.read_chain(str(path), root, tip)["names"]
    q = np.random.default_rng(0).uniform(-3.0, 3.0, size=(200, body.m))
    want = mujoco_positions(path, names, q, root, tip, hand)
    np.testing.assert_allclose(body.forward(q), want, rtol=0, atol=1e-12)


def test_held_joints_match_mujoco(tmp_path, monkeypatch):
    """joints: the commanded hinges; hold: the others' qpos (default: their ref)."""
    pytest.importorskip("mujoco")
    monkeypatch.chdir(tmp_path)
    path = write_model(tmp_path)
    spec = {"file": str(path), "root": "world", "tip": "tool", "joints": ["j1", "j3"],
            "hold": {"j2": 0.4}}
    body = body_from(_desc(path, mjcf=spec, home=[0.0, 0.0]))
    q = np.random.default_rng(1).uniform(-2.0, 2.0, size=(50, 2))
    full = np.column_stack([q[:, 0], np.full(50, 0.4), np.zeros(50), q[:, 1],
                            np.full(50, np.deg2rad(10))])  # j2b at 0 = its ref, j4 at its ref
    want = mujoco_positions(path, ["j1", "j2", "j2b", "j3", "j4"], full, "world", "tool",
                            [0, 0, 0])
    np.testing.assert_allclose(body.forward(q), want, rtol=0, atol=1e-12)


NO_GYMNASIUM = pytest.mark.skipif(importlib.util.find_spec("gymnasium") is None,
                                  reason="gymnasium is not installed (the test extra)")
GYM = [pytest.param(name, marks=NO_GYMNASIUM) for name in gym_robots.NAMES]


@pytest.mark.parametrize("name", GYM)
def test_gymnasium_bodies_match_mujoco(tmp_path, monkeypatch, name):
    """The shipped Gymnasium bodies (their hand point and base included) against MuJoCo."""
    pytest.importorskip("mujoco")
    monkeypatch.chdir(tmp_path)
    body, whole = gbmodel.make_body(name), gbmodel.bodies.read_description(name)
    desc = whole["mjcf"]
    names = mjcf.read_chain(desc["file"], desc["root"], desc["tip"])["names"]
    q = np.random.default_rng(2).uniform(-1.0, 1.0, size=(200, body.m))
    want = mujoco_positions(gbmodel.urdf.resolve(desc["file"]), names, body.joint_angles(q),
                            desc["root"], desc["tip"], whole.get("hand", [0, 0, 0]),
                            np.array(whole.get("base", np.eye(4)[:3]), float))
    np.testing.assert_allclose(body.forward(q), want[:, list(body.outputs)], rtol=0, atol=1e-12)


@pytest.mark.parametrize("name", GYM)
@pytest.mark.parametrize("size", [0.5, 1.0])
def test_gymnasium_grids_are_reachable(name, size):
    body = gbmodel.make_body(name)
    assert gbmodel.bodies.unreachable(body, np.random.default_rng(0), size=size).size == 0


def test_a_planar_arm_in_degrees_without_mujoco(tmp_path, monkeypatch):
    """Read with the standard library alone: MuJoCo's default angle unit is the degree (range,
    ref, euler), a hinge turns by qpos - ref, a body's euler places it, a site is the tip."""
    monkeypatch.chdir(tmp_path)  # MuJoCo's log file, if it writes one
    path = tmp_path / "planar.xml"
    path.write_text("""<mujoco><worldbody>
      <body name="upper" pos="0 0 0.1"><joint name="shoulder" axis="0 0 1" range="-150 150"/>
        <geom size="0.05"/>
        <body name="fore" pos="0.3 0 0" euler="0 0 90">
          <joint name="elbow" axis="0 0 1" range="-90 135" ref="30"/><geom size="0.05"/>
          <site name="tip" pos="0.2 0 0"/></body></body></worldbody></mujoco>""")
    body = body_from({"name": "planar", "mjcf": {"file": str(path), "root": "world",
                                                 "tip": "tip"},
                      "outputs": [0, 1, 2], "normalise": True, "home": [0.0, 0.0], "grid": GRID})
    np.testing.assert_allclose(np.rad2deg([body.q_min, body.q_max]), [[-150, -90], [150, 135]])
    q = np.array([[0.2, -0.4], [-1.0, 1.0]])
    a, b = body.joint_angles(q).T  # qpos [rad]
    elbow = a + np.pi / 2 + b - np.deg2rad(30)  # the fore body's 90 degrees, minus the ref
    want = np.column_stack([0.3 * np.cos(a) + 0.2 * np.cos(elbow),
                            0.3 * np.sin(a) + 0.2 * np.sin(elbow), np.full(2, 0.1)])
    np.testing.assert_allclose(body.forward(q), want, atol=1e-15)
    if importlib.util.find_spec("mujoco") is not None:  # and MuJoCo's reading of the same file
        np.testing.assert_allclose(mujoco_positions(path, ["shoulder", "elbow"], np.column_stack(
            [a, b]), "world", "tip", [0, 0, 0]), want, rtol=0, atol=1e-12)


def test_growth_scales_the_links(tmp_path):
    """Under growth the translations after each joint scale, as for a URDF body; the base's
    placement (world -> the first joint) does not."""
    path = write_model(tmp_path)
    body = body_from(_desc(path))
    first = body_from(_desc(path, tip="base")).forward([0.0])  # where the first joint sits
    q = np.full(body.m, 0.3)
    half = body.forward(q, gbmodel.Growth(pattern="proportional").scales(body, 0.5))
    np.testing.assert_allclose(half - first, 0.5 * (body.forward(q) - first), atol=1e-12)
    assert body.segment_lengths.shape == (5,)


def test_the_digest_covers_the_includes(tmp_path):
    """An edited include is another body: the digest changes, and a body planned with the old
    digest is refused."""
    path = write_model(tmp_path)
    before = mjcf.digest(str(path))
    assert before == gbmodel.bodies.source_digest("mjcf", {"file": str(path)})
    (tmp_path / "parts" / "hand.xml").write_text(HAND.replace("0.18 0.03 0", "0.19 0.03 0"))
    assert mjcf.digest(str(path)) != before
    with pytest.raises(ValueError, match=r"^body\.mjcf\.file=.*changed since"):
        body_from(_desc(path, mjcf={"file": str(path), "root": "world", "tip": "tool",
                                    "sha256": before}))


TENDON = '<tendon><fixed name="couple"><joint joint="j2" coef="1"/><joint joint="j1" ' \
         'coef="-1"/></fixed></tendon>'
EQUALITY = '<equality><joint name="same" joint1="j3" joint2="j1"/></equality>'
BAD = {  # name: (model text changes, mjcf section changes, the line's start, what it says)
    "missing_tip": ({}, dict(tip="nowhere"), "body.mjcf.tip='nowhere'", "0 bodies and 0 sites"),
    "missing_root": ({}, dict(root="nobody"), "body.mjcf.root='nobody'", "0 bodies"),
    "root_off_the_path": ({}, dict(root="floating"), "body.mjcf.root='floating'",
                          "not on the path"),
    "ball_joint": ({'<joint name="j3" ref': '<joint name="j3" type="ball" ref'}, {},
                   "body.mjcf.root=", "'j3' on the chain is ball"),
    "slide_joint": ({'<joint name="j2"/>': '<joint name="j2" type="slide"/>'}, {},
                    "body.mjcf.root=", "'j2' on the chain is slide"),
    "free_joint": ({}, dict(tip="limb"), "body.mjcf.root=", "'float' on the chain is free"),
    "tendon_coupled": ({"{extra}": TENDON}, {}, "body.mjcf.root=",
                       "'j1' on the chain is coupled to others by fixed tendon 'couple'"),
    "equality_coupled": ({"{extra}": EQUALITY}, {}, "body.mjcf.root=",
                         "coupled to others by joint equality 'same'"),
    "include_outside": ({"parts/hand.xml": "../hand.xml"}, {}, "body.mjcf.file=",
                        "is outside the model's folder"),
    "include_absolute": ({"parts/hand.xml": "/etc/hostname"}, {}, "body.mjcf.file=",
                         "is outside the model's folder"),
    "include_itself": ({"parts/hand.xml": "skew.xml"}, {}, "body.mjcf.file=", "includes itself"),
    "not_mjcf": ({"<mujoco model=\"skew\">": "<robot name=\"skew\">",
                  "</mujoco>\n": "</robot>\n"}, {}, "body.mjcf.file=",
                 "not an MJCF file: its root element is <robot>"),
    "not_xml": ({"<mujoco model": "mujoco model"}, {}, "body.mjcf.file=", "cannot read skew.xml"),
    "unknown_class": ({'<joint name="j2"/>': '<joint name="j2" class="nosuch"/>'}, {},
                      "body.mjcf.file=", "default class 'nosuch'"),
    "two_orientations": ({'euler="10 -5 20"': 'euler="10 -5 20" quat="1 0 0 0"'}, {},
                         "body.mjcf.file=", "orientation given twice"),
    "unknown_joint": ({}, dict(joints=["j1", "j9"]), "body.mjcf.joints=", "choose distinct"),
}


def _bad_model(tmp_path, name):
    model, section, start, says = BAD[name]
    text = MODEL
    for old, new in model.items():
        assert old in text, old
        text = text.replace(old, new)
    if "{extra}" not in text:
        text = text.replace("</mujoco>", "{extra}</mujoco>")
    outside = tmp_path / "hand.xml"
    outside.write_text(HAND)  # the include outside the model's folder exists
    path = write_model(tmp_path / "model", model=text)
    return path, section, start, says


@pytest.mark.parametrize("name", sorted(BAD))
def test_bad_models_are_one_line(tmp_path, name):
    path, section, start, says = _bad_model(tmp_path, name)
    desc = {"name": "skew", "mjcf": {"file": str(path), "root": "world", "tip": "tool",
                                     **section},
            "outputs": [0, 1, 2], "home": [0.0] * 5, "grid": GRID}
    with pytest.raises(ValueError) as err:
        body_from(desc)
    line = str(err.value)
    assert line.startswith(start) and says in line and "\n" not in line, line


@pytest.mark.parametrize("name", ["missing_tip", "ball_joint", "free_joint", "tendon_coupled",
                                  "include_outside", "not_mjcf"])
def test_bad_models_stop_the_command_line(tmp_path, name):
    """The issue's five kinds of bad model, through the stage's check: one line (exit 2)."""
    path, section, start, says = _bad_model(tmp_path, name)
    conf = tmp_path / "conf" / "body"
    conf.mkdir(parents=True)
    (conf / "skew.yaml").write_text(json.dumps(
        {"name": "skew", "mjcf": {"file": str(path), "root": "world", "tip": "tool", **section},
         "outputs": [0, 1, 2], "home": [0.0] * 5, "grid": GRID}))
    out = cli.check([f"hydra.searchpath=[file://{conf.parent}]", "body=skew",
                     f"paths.root={tmp_path / 'out'}", "trials.count=1"])
    assert out is not None and start in out and says in out and "\n" not in out, out


def test_a_bad_model_exits_2(tmp_path):
    path, section, start, says = _bad_model(tmp_path, "tendon_coupled")
    conf = tmp_path / "conf" / "body"
    conf.mkdir(parents=True)
    (conf / "skew.yaml").write_text(json.dumps(
        {"name": "skew", "mjcf": {"file": str(path), "root": "world", "tip": "tool"},
         "outputs": [0, 1, 2], "home": [0.0] * 5, "grid": GRID}))
    proc = subprocess.run([sys.executable, "-m", "pipeline.simulate",
                           f"hydra.searchpath=[file://{conf.parent}]", "body=skew",
                           f"paths.root={tmp_path / 'out'}"], cwd=REPO, capture_output=True,
                          text=True, timeout=300,
                          env={"PYTHONPATH": str(REPO), "PATH": "/usr/bin:/bin"})
    assert proc.returncode == 2, proc.stderr[-2000:]
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and says in lines[0], proc.stderr


@pytest.mark.parametrize("pattern", ["proportional", "proximal_first"])
def test_the_fast_kernel_computes_the_mjcf_chain(tmp_path, pattern):
    """The kernel takes an MJCF body as it takes a URDF body (the same general chain)."""
    from test_bodies_urdf import kernel_learns_as_the_reference

    path = write_model(tmp_path)
    reach = body_from(_desc(path)).forward(
        np.random.default_rng(1).uniform(-0.3, 0.3, size=(400, 5)))
    grid = {"lo": np.quantile(reach, 0.3, axis=0).tolist(),
            "hi": np.quantile(reach, 0.7, axis=0).tolist(), "num": [3, 3, 2]}
    kernel_learns_as_the_reference(_desc(path, grid=grid), pattern)


@NO_GYMNASIUM
def test_an_mjcf_body_runs_simulate_aggregate_and_report(tmp_path):
    """body=reacher (an MJCF YAML of conf/body/) through the three stages, like any body."""
    from pipeline import aggregate, report, simulate
    from pipeline.config import compose

    cfg = compose(["body=reacher", "growth=proportional", "growth.period=10",
                   "learner.epochs=20", "trials.count=1", "workers=1", f"paths.root={tmp_path}",
                   "figure=reacher", "report.explain=false"])
    simulate.simulate(cfg)
    aggregate.aggregate(cfg)
    report.report(cfg)
    out = Path(cfg.paths.report)
    assert (out / "reacher_curves.png").stat().st_size
    assert (out / "reacher_postures.png").stat().st_size
    records = [json.loads(p.read_text()) for p in Path(cfg.paths.out).rglob("*.json")
               if "labels" in json.loads(p.read_text())]
    assert records and all(r["status"] == "ok" for r in records)
    assert len(records[0]["spec"]["body"]["mjcf"]["sha256"]) == 64
