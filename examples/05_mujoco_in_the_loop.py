# %% [markdown]
# # A body in the loop: MuJoCo itself as the forward function
#
# Gymnasium's Pusher arm two ways: as an MJCF body (`conf/body/pusher.yaml`, its chain read from
# the MJCF and compiled into the kernels), and as a body in the loop (gbmodel/body_loop.py),
# whose forward function calls MuJoCo's `mj_kinematics` for every posture
# (`examples/in_the_loop/mujoco_forward.py`). Both learn with the same draws on the numpy
# reference path: the curves agree to floating-point tolerance. Then what each path costs per
# sample, against the compiled kernel.
#
# Needs `mujoco` and `gymnasium` (`pip install -e '.[mujoco]'`).
# Run: `.venv/bin/python examples/05_mujoco_in_the_loop.py`

# %%
import os
import sys
import time
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

import gbmodel  # noqa: E402

EPOCHS = int(os.environ.get("GBGROWTH_EPOCHS", 1000))
REPO = Path(__file__).resolve().parents[1] if "__file__" in globals() else Path.cwd()
# the figures go under outputs/examples/ (ignored by git), never into the repository itself
OUT = Path(os.environ.get("GBGROWTH_EXAMPLE_OUT", REPO / "outputs" / "examples"))
OUT.mkdir(parents=True, exist_ok=True)
sys.path.insert(0, str(REPO / "examples" / "in_the_loop"))  # the factory's module

# %% [markdown]
# The MJCF body as shipped, and the same arm as a body in the loop: the factory
# `mujoco_forward:make` with the model's file, root, tip, hand point and base as arguments;
# the limits, home and grid are the MJCF body's (a callable body has no file to read them from),
# and its segment lengths too (what growth patterns that weigh segments read).

# %%
mjcf_desc = gbmodel.bodies.read_description("pusher")
mjcf_body = gbmodel.make_body(mjcf_desc)
model = str(gbmodel.urdf.resolve(mjcf_desc["mjcf"]["file"]))
loop_desc = dict(
    name="pusher_in_the_loop", description="Gymnasium's Pusher arm, MuJoCo in the loop",
    callable=dict(factory="mujoco_forward:make",
                  args=dict(file=model, root="world", tip="tips_arm", hand=mjcf_desc["hand"],
                            base=mjcf_desc["base"]),
                  files=[model], lengths=mjcf_body.segment_lengths.tolist()),
    outputs=mjcf_desc["outputs"], normalise=True,
    limits=np.column_stack([mjcf_body.q_min, mjcf_body.q_max]).tolist(),
    home=mjcf_desc["home"], grid=mjcf_desc["grid"])
loop_body = gbmodel.make_body(loop_desc)
q = np.random.default_rng(0).uniform(-1, 1, size=(1000, mjcf_body.m))
k = np.linspace(0.5, 1.0, mjcf_body.m)  # a body grown unevenly
gap = np.abs(loop_body.forward(q, k) - mjcf_body.forward(q, k)).max()
print(f"forward kinematics, 1000 postures grown unevenly: largest difference {gap:.1e} m")
print("cache key of the function:", gbmodel.bodies.source_digest("callable",
                                                                loop_desc["callable"])[:16])

# %% [markdown]
# One trial each, growing from half size over the first half of the epochs, with the recipe's
# settings (conf/body_learner/pusher_goal_babbling.yaml): the MJCF body on the kernel (float32)
# and on the numpy reference path (float64), and the body in the loop on the reference path
# (the only path that calls Python).

# %%
settings = dict(name="goal_babbling", solver="lstsq", radius=0.1, targets_per_epoch=30, steps=10)
growth = dict(pattern="proportional", start_size=0.5, period=max(EPOCHS // 2, 1))


def trial(body, fast):
    spec = gbmodel.TrialSpec(body=body, growth=growth, epochs=EPOCHS,
                             learner=dict(settings, fast=fast))
    t0 = time.process_time()
    result = gbmodel.run_trial(spec, np.random.default_rng(7))
    seconds = time.process_time() - t0
    module, params = spec.make_learner()
    samples = EPOCHS * module.samples_per_epoch(params, spec.make_body())
    return result, seconds, samples


runs = {"MJCF body, kernel": trial(mjcf_desc, True),
        "MJCF body, reference": trial(mjcf_desc, False),
        "MuJoCo in the loop, reference": trial(loop_desc, False)}
ref, loop = runs["MJCF body, reference"][0], runs["MuJoCo in the loop, reference"][0]
curve_gap = np.max(np.abs(loop.abs_error - ref.abs_error) / ref.abs_error)
kernel_gap = np.max(np.abs(runs["MJCF body, kernel"][0].abs_error - ref.abs_error)
                    / ref.abs_error)
print(f"curves, in the loop against the MJCF body (both reference): largest relative "
      f"difference {curve_gap:.1e}")
print(f"curves, kernel (float32) against reference (float64): {kernel_gap:.1e}")
for name, (result, seconds, samples) in runs.items():
    print(f"{name}: final error {1000 * result.abs_error[-1]:.2f} mm, {seconds:.1f} CPU s, "
          f"{1e9 * seconds / samples:.0f} ns per sample")

# %% [markdown]
# The forward function alone, per posture: the MJCF chain in numpy against MuJoCo's
# mj_kinematics called once per posture.

# %%
Q = np.random.default_rng(1).uniform(-1, 1, size=(6020, mjcf_body.m))  # one epoch's samples
for name, body in (("MJCF chain, numpy", mjcf_body), ("MuJoCo in the loop", loop_body)):
    t0 = time.process_time()
    body.forward(Q, k)
    print(f"forward, {name}: {1e9 * (time.process_time() - t0) / len(Q):.0f} ns per posture")

fig, ax = plt.subplots(figsize=(5, 3.2))
for (name, (result, _, _)), style in zip(runs.items(), ("-", "--", "-")):
    loop_line = "loop" in name  # drawn wide beneath the others: they lie on it
    ax.plot(result.epoch, 1000 * result.abs_error, style, label=name, lw=5 if loop_line else 1,
            alpha=0.4 if loop_line else 1.0, zorder=1 if loop_line else 2)
ax.set(xscale="log", yscale="log", xlabel="epoch", ylabel="absolute error [mm]",
       title="Pusher arm, growing")
ax.legend(frameon=False, fontsize=8)
fig.tight_layout()
fig.savefig(OUT / "mujoco_in_the_loop.png", dpi=100)
