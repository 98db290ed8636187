"""Two 7-DOF arms the project was not tuned for, as a new user would bring them: a URDF and a
body file (docs/bodies.md) with the URDF's limits, the middle of every joint's range as home,
and a target grid in front of the robot. Used by tests/e2e/test_new_robot.py and by the measurement
in docs/bodies.md ("A new robot"):

    .venv/bin/python tests/new_robots.py             # held-out errors and times, 3 seeds each
    .venv/bin/python tests/new_robots.py defaults    # the same with the paper's arm settings
    .venv/bin/python tests/new_robots.py gradient    # the recipe's R, K, L with the gradient step

- `panda_like`: Franka Panda's kinematics (0.333 m column, 0.316 + 0.384 m upper/forearm with
  the 0.0825 m elbow offsets, 0.088 m wrist offset, flange + hand 0.21 m) and joint limits;
- `iiwa_like`: a KUKA LBR iiwa 7-like chain (0.34 m column, 0.40 + 0.40 m links, 0.126 m
  flange, axes z, y, z, -y, z, y, z; +-170 / 120 / 175 degree limits).
"""
from __future__ import annotations

import math

_ROBOTS = {
    # joint name: (xyz of its origin in the parent link, rpy, axis, lower, upper) [m, rad]
    "panda_like": dict(
        joints=[((0, 0, 0.333), (0, 0, 0), (0, 0, 1), -2.8973, 2.8973),
                ((0, 0, 0), (-math.pi / 2, 0, 0), (0, 0, 1), -1.7628, 1.7628),
                ((0, -0.316, 0), (math.pi / 2, 0, 0), (0, 0, 1), -2.8973, 2.8973),
                ((0.0825, 0, 0), (math.pi / 2, 0, 0), (0, 0, 1), -3.0718, -0.0698),
                ((-0.0825, 0.384, 0), (-math.pi / 2, 0, 0), (0, 0, 1), -2.8973, 2.8973),
                ((0, 0, 0), (math.pi / 2, 0, 0), (0, 0, 1), -0.0175, 3.7525),
                ((0.088, 0, 0), (math.pi / 2, 0, 0), (0, 0, 1), -2.8973, 2.8973)],
        tool=(0, 0, 0.2104), shoulder=(0, 0, 0.333),
        grid=dict(lo=[0.3, -0.3, 0.15], hi=[0.6, 0.3, 0.55], num=[4, 4, 4])),
    "iiwa_like": dict(
        joints=[((0, 0, 0.15), (0, 0, 0), (0, 0, 1), -2.967, 2.967),
                ((0, 0, 0.19), (0, 0, 0), (0, 1, 0), -2.094, 2.094),
                ((0, 0, 0.21), (0, 0, 0), (0, 0, 1), -2.967, 2.967),
                ((0, 0, 0.19), (0, 0, 0), (0, -1, 0), -2.094, 2.094),
                ((0, 0, 0.21), (0, 0, 0), (0, 0, 1), -2.967, 2.967),
                ((0, 0, 0.19), (0, 0, 0), (0, 1, 0), -2.094, 2.094),
                ((0, 0, 0.081), (0, 0, 0), (0, 0, 1), -3.054, 3.054)],
        tool=(0, 0, 0.045), shoulder=(0, 0, 0.34),
        grid=dict(lo=[0.4, -0.3, 0.2], hi=[0.7, 0.3, 0.6], num=[4, 4, 4])),
}
NAMES = tuple(_ROBOTS)
# the README's settings for a new robot ("Another body")
RECIPE = ("learner.solver=lstsq", "learner.radius=0.1", "learner.targets_per_epoch=30",
          "learner.steps=10")


def urdf(name: str) -> str:
    """The robot's URDF: base_link, link1 ... link7, a fixed joint to tool0."""
    r = _ROBOTS[name]
    fmt = lambda v: " ".join(f"{x:g}" for x in v)  # noqa: E731
    links = ["base_link"] + [f"link{i + 1}" for i in range(7)] + ["tool0"]
    parts = [f'<robot name="{name}">'] + [f'  <link name="{n}"/>' for n in links]
    for i, (xyz, rpy, axis, lo, hi) in enumerate(r["joints"]):
        parts.append(
            f'  <joint name="joint{i + 1}" type="revolute"><parent link="{links[i]}"/>'
            f'<child link="{links[i + 1]}"/><origin xyz="{fmt(xyz)}" rpy="{fmt(rpy)}"/>'
            f'<axis xyz="{fmt(axis)}"/><limit lower="{lo}" upper="{hi}" effort="1" '
            f'velocity="1"/></joint>')
    parts.append(f'  <joint name="flange" type="fixed"><parent link="link7"/>'
                 f'<child link="tool0"/><origin xyz="{fmt(r["tool"])}" rpy="0 0 0"/></joint>')
    return "\n".join(parts + ["</robot>", ""])


def body_yaml(name: str, urdf_path) -> str:
    """conf/body/<name>.yaml as docs/bodies.md's recipe writes it."""
    g = _ROBOTS[name]["grid"]
    return (f"name: {name}\ndescription: a 7-DOF arm from its URDF, tool position\n"
            f"urdf: {{file: {urdf_path}, root: base_link, tip: tool0}}\n"
            f"outputs: [0, 1, 2]\nnormalise: true\nhome: [0, 0, 0, 0, 0, 0, 0]\n"
            f"grid: {{lo: {g['lo']}, hi: {g['hi']}, num: {g['num']}}}\n")


def reach(name: str, body, samples: int = 20000) -> float:
    """The arm's reach: the largest distance of the tool from the shoulder (the second joint,
    on the first one's axis) over random postures within the limits [m]."""
    import numpy as np

    q = np.random.default_rng(0).uniform(-1.0, 1.0, size=(samples, body.m))
    return float(np.linalg.norm(body.forward(q) - np.array(_ROBOTS[name]["shoulder"]),
                                axis=-1).max())


def write(name: str, folder) -> None:
    """<folder>/<name>.urdf and the config folder <folder>/conf/body/<name>.yaml."""
    from pathlib import Path

    folder = Path(folder)
    (folder / "conf" / "body").mkdir(parents=True, exist_ok=True)
    (folder / f"{name}.urdf").write_text(urdf(name))
    (folder / "conf" / "body" / f"{name}.yaml").write_text(
        body_yaml(name, folder / f"{name}.urdf"))


if __name__ == "__main__":  # the measurement of docs/bodies.md
    import sys
    import tempfile
    import time
    from pathlib import Path

    import numpy as np

    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
    import gbmodel
    from pipeline.config import compose
    from pipeline.plan import plan

    with tempfile.TemporaryDirectory() as tmp:
        for name in NAMES:
            write(name, tmp)
            for growth in ("none", "proportional"):
                cfg = compose([f"hydra.searchpath=[file://{tmp}/conf]", f"body={name}",
                               f"growth={growth}", "learner.epochs=1000", "trials.count=3",
                               *(() if "defaults" in sys.argv else
                                 RECIPE[1:] if "gradient" in sys.argv else RECIPE)])
                rows = []
                for t in plan(cfg):
                    t0 = time.perf_counter()
                    seed = np.random.SeedSequence(**t["seed"])
                    r = gbmodel.run_trial(gbmodel.TrialSpec.from_dict(t["spec"]),
                                          np.random.default_rng(seed))
                    rows.append((r.heldout_abs_error[-1], time.perf_counter() - t0))
                body = gbmodel.make_body(t["spec"]["body"])
                R = reach(name, body)
                err = np.array([e for e, _ in rows])
                print(f"{name} growth={growth}: reach {R:.3f} m, held-out after 1000 epochs "
                      f"{', '.join(f'{1e3 * e:.1f}' for e in err)} mm "
                      f"(max {100 * err.max() / R:.2f} % of the reach), "
                      f"{', '.join(f'{s:.1f}' for _, s in rows)} s per trial", flush=True)
