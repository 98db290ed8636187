# ---
# jupyter:
#   jupytext:
#     formats: py:percent
#   kernelspec:
#     display_name: Python 3
#     language: python
#     name: python3
# ---

# %% [markdown]
# # Quick start: growing bodies that learn to reach
#
# Open with Jupyter through jupytext (`pip install -e '.[notebooks]'`, then `jupyter lab` and
# open this file as a notebook), or run it as a script. Nothing here simulates at the paper's
# scale: the first two parts read the committed report (outputs/report/), the third grows an arm
# of your own for a few hundred epochs, the last steps through the Gymnasium environment.
# `make notebooks` runs it (tests/e2e/test_notebooks.py).

# %%
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd

import gbmodel
from pipeline import models

REPO = Path.cwd() if (Path.cwd() / "outputs").is_dir() else Path.cwd().parent
REPORT = REPO / "outputs" / "report"

# %% [markdown]
# ## 1. Fig. 4, redrawn from the committed curves
# `curves.parquet`: the mean and quartiles over 20 trials of every condition and evaluated epoch.

# %%
curves = pd.read_parquet(REPORT / "curves.parquet")
fig4 = curves[curves["figure"] == "fig4"]
fig, ax = plt.subplots(figsize=(6, 3.5))
for condition, c in fig4.groupby("condition", sort=False):
    c = c.sort_values("epoch")
    ax.plot(c["epoch"], 1000 * c["abs_error_mean"], label=condition)
ax.set(xscale="log", yscale="log", xlabel="epoch", ylabel="absolute error [mm]",
       title="Fig. 4: 5-DOF arm, proportional growth")
ax.legend(frameon=False, fontsize=7, ncol=2)
plt.show()

# %% [markdown]
# ## 2. Reach with a committed model
# The final inverse estimate of every condition and trial, g(x) = M phi(x), from the report's
# `models/fig4.json`: the full-size reference's, asked for the grid's targets.

# %%
fig4_models = models.load(str(REPORT / "models" / "fig4.json"))
model = fig4_models[fig4_models.labels[-1]]
targets = model.body.target_set(model.size)
miss = np.linalg.norm(model.reach(targets) - targets, axis=1)
print(f"{model.label}: mean miss over the {len(targets)} targets {1000 * miss.mean():.1f} mm")

# %% [markdown]
# ## 3. Grow your own URDF arm
# Two links in a URDF, made a body, grown from half to full size over 150 epochs of 300 while
# Goal Babbling learns it (smoke scale: a few seconds).

# %%
urdf = REPO / "outputs" / "notebooks" / "arm2.urdf"
urdf.parent.mkdir(parents=True, exist_ok=True)
joint = ('<joint name="{0}" type="revolute"><parent link="{1}"/><child link="{2}"/>'
         '<origin xyz="{3} 0 0"/><axis xyz="0 0 1"/>'
         '<limit lower="-3" upper="3" effort="1" velocity="1"/></joint>')
urdf.write_text('<robot name="mine"><link name="a"/><link name="b"/><link name="c"/>'
                + joint.format("shoulder", "a", "b", 0) + joint.format("elbow", "b", "c", 0.4)
                + '<link name="tip"/><joint name="t" type="fixed"><parent link="c"/>'
                  '<child link="tip"/><origin xyz="0.3 0 0"/></joint></robot>')
mine = dict(name="mine", urdf=dict(file=str(urdf), root="a", tip="tip"), outputs=[0, 1],
            normalise=False, home=[1.0, 0.8], grid=dict(lo=[-0.2, 0.2], hi=[0.2, 0.45],
                                                        num=[5, 4]))
spec = gbmodel.TrialSpec(body=mine, epochs=300, learner=dict(name="goal_babbling"),
                         growth=dict(pattern="proportional", period=150, start_size=0.5,
                                     end_size=1.0))
result = gbmodel.run_trial(spec, np.random.default_rng(0))
print(f"held-out error {1000 * result.heldout_abs_error[-1]:.1f} mm at size {result.size[-1]:g}")
plt.figure(figsize=(6, 3))
plt.plot(result.epoch, 1000 * result.heldout_abs_error)
plt.gca().set(xscale="log", xlabel="epoch", ylabel="held-out error [mm]")
plt.show()

# %% [markdown]
# ## 4. The same body in Gymnasium, for your own agent
# `gbgrowth/GrowingReach-v0` (docs/gym.md): a posture per step, the body grows across episodes
# (here over 5), `info["body_size"]`; score an agent on the pipeline's held-out targets with
# `observe`, `hand` and `heldout_goals`. A random policy, as the baseline to beat:

# %%
import gymnasium as gym  # noqa: E402

import pipeline.envs  # noqa: E402,F401  (registers the id)

env = gym.make("gbgrowth/GrowingReach-v0", body="arm5", growth="proportional", period=5)
obs, info = env.reset(seed=0)
for episode in range(8):
    obs, reward, terminated, truncated, info = env.step(env.action_space.sample())
    print(f"episode {info['episode']}: body size {info['body_size']:.2f}, "
          f"distance {info['distance']:.3f} m")
    obs, info = env.reset()
arm = env.unwrapped
goals = arm.heldout_goals()
random_postures = np.random.default_rng(0).uniform(-1, 1, (len(goals), arm.body.m))
error = np.linalg.norm(arm.hand(random_postures) - goals, axis=1).mean()
print(f"random policy: held-out error {1000 * error:.0f} mm, {100 * error / arm.reach:.0f} % of reach")
