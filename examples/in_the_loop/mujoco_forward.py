"""A body in the loop that drives MuJoCo itself: the forward-function protocol of
gbmodel/body_loop.py implemented with `mujoco` (examples/05_mujoco_in_the_loop.py uses it).

make(file, root, tip, hand, base) loads the model once and returns forward(angles, factors):
for every posture it sets the chain's joints (qpos; the model's other joints at qpos0), runs
MuJoCo's mj_kinematics and reads the tip's frame (a body's or a site's), the point `hand` in
it, expressed in the root body's frame with `base` before it: what an MJCF body
(gbmodel/mjcf.py) computes in its compiled chain. Growth scales, as for that body, the
translation after each joint: the position of every body of the chain after joint i (and of
the tip site and hand point after the last joint) by factors[i]. That needs the chain's
hinges anchored at their bodies' origins (joint pos 0, as in Gymnasium's models).
"""
from __future__ import annotations

import mujoco
import numpy as np

import gbmodel


@gbmodel.body_factory  # the author's mark: a body description may name it (gbmodel/body_loop.py)
def make(file: str, root: str, tip: str, hand=(0.0, 0.0, 0.0), base=None):
    model = mujoco.MjModel.from_xml_path(file)
    data = mujoco.MjData(model)
    is_site = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, tip) < 0
    tip_body = model.site(tip).bodyid[0] if is_site else model.body(tip).id
    root_id = 0 if root == "world" else model.body(root).id
    chain = []  # the bodies from the root (exclusive) to the tip's body, root first
    b = tip_body
    while b != root_id:
        if b == 0:
            raise ValueError(f"body {root!r} is not on the path from {tip!r} to the world")
        chain.append(b)
        b = model.body_parentid[b]
    chain.reverse()
    joints, grows_with = [], []  # hinge joints in chain order; per body, the joint before it
    for b in chain:
        grows_with.append(len(joints) - 1)  # -1: before the first joint, never scaled
        for j in range(model.body_jntadr[b], model.body_jntadr[b] + model.body_jntnum[b]):
            if model.jnt_type[j] != mujoco.mjtJoint.mjJNT_HINGE or np.any(model.jnt_pos[j]):
                raise ValueError(f"joint {model.joint(j).name!r}: only hinges at their body's "
                                 "origin")
            joints.append(j)
    adr = model.jnt_qposadr[joints]
    pos0 = model.body_pos[chain].copy()
    site_pos0 = model.site_pos[model.site(tip).id].copy() if is_site else None
    hand = np.asarray(hand, np.float64)
    base = np.eye(4)[:3] if base is None else np.asarray(base, np.float64)

    def forward(angles: np.ndarray, factors: np.ndarray) -> np.ndarray:
        k = np.append(factors, 1.0)  # k[-1]: the factor of what is before the first joint
        model.body_pos[chain] = pos0 * k[grows_with][:, None]
        if is_site:
            model.site_pos[model.site(tip).id] = site_pos0 * factors[-1]
        point = hand * factors[-1]
        out = np.empty((len(angles), 3))
        data.qpos[:] = model.qpos0
        for n, q in enumerate(angles):
            data.qpos[adr] = q
            mujoco.mj_kinematics(model, data)
            if is_site:
                s = model.site(tip).id
                x, R = data.site_xpos[s], data.site_xmat[s].reshape(3, 3)
            else:
                x, R = data.xpos[tip_body], data.xmat[tip_body].reshape(3, 3)
            p = x + R @ point
            if root_id:
                p = data.xmat[root_id].reshape(3, 3).T @ (p - data.xpos[root_id])
            out[n] = base[:, :3] @ p + base[:, 3]
        return out

    forward.joints = [model.joint(j).name for j in joints]
    return forward
