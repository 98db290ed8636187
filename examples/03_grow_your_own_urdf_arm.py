# %% [markdown]
# # Grow your own URDF arm
#
# A three-joint planar arm written as a URDF, made a body with `gbmodel.make_body`, grown with
# relative growth rates (the upper arm twice as fast as the forearm) and learned by Goal
# Babbling, all in Python: no config files. The same URDF works from the command line as
# `conf/body/<name>.yaml` (docs/bodies.md).
#
# Run: `.venv/bin/python examples/03_grow_your_own_urdf_arm.py`

# %%
import os
import tempfile
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

import gbmodel  # noqa: E402

EPOCHS = int(os.environ.get("GBGROWTH_EPOCHS", 2000))
REPO = Path(__file__).resolve().parents[1] if "__file__" in globals() else Path.cwd()
# the figures go under outputs/examples/ (ignored by git), never into the repository itself
OUT = Path(os.environ.get("GBGROWTH_EXAMPLE_OUT", REPO / "outputs" / "examples"))
OUT.mkdir(parents=True, exist_ok=True)

# %%
URDF = """<robot name="arm3">
  <link name="base"/><link name="upper"/><link name="fore"/><link name="hand"/><link name="tip"/>
  <joint name="shoulder" type="revolute"><parent link="base"/><child link="upper"/>
    <origin xyz="0 0 0"/><axis xyz="0 0 1"/><limit lower="-3.1" upper="3.1" effort="1" velocity="1"/></joint>
  <joint name="elbow" type="revolute"><parent link="upper"/><child link="fore"/>
    <origin xyz="0.3 0 0"/><axis xyz="0 0 1"/><limit lower="-3.1" upper="3.1" effort="1" velocity="1"/></joint>
  <joint name="wrist" type="revolute"><parent link="fore"/><child link="hand"/>
    <origin xyz="0.25 0 0"/><axis xyz="0 0 1"/><limit lower="-3.1" upper="3.1" effort="1" velocity="1"/></joint>
  <joint name="tool" type="fixed"><parent link="hand"/><child link="tip"/><origin xyz="0.1 0 0"/></joint>
</robot>"""
urdf = Path(tempfile.mkdtemp()) / "arm3.urdf"
urdf.write_text(URDF)
description = dict(
    name="arm3_urdf", description="3-joint planar arm from a URDF",
    urdf=dict(file=str(urdf), root="base", tip="tip"),
    outputs=[0, 1], normalise=False, home=[1.0, 0.5, 0.5],
    grid=dict(lo=[-0.3, 0.2], hi=[0.3, 0.45], num=[7, 4]))
body = gbmodel.make_body(description)
print(body.m, "joints, segments", np.round(body.segment_lengths, 3))

# %% [markdown]
# Growth: from 0.5 to the full size over half the epochs, each segment's length factor changing
# at its rate (shoulder-elbow link 2, elbow-wrist 1, wrist-tool 1): "twice as fast" holds at
# every epoch (gbmodel.growth.rate_factors).

# %%
growth = dict(pattern="per_segment", period=EPOCHS // 2, start_size=0.5, end_size=1.0,
              rates=[2.0, 1.0, 1.0])
spec = gbmodel.TrialSpec(body=description, growth=growth, epochs=EPOCHS,
                         learner=dict(name="goal_babbling"))
g = spec.make_growth().validate(body)
sizes = g.sizes(np.arange(1, EPOCHS + 1))
factors = g.scales(body, sizes)
print("start factors", np.round(factors[0], 3), "end", np.round(factors[-1], 3))

# %%
result = gbmodel.run_trial(spec, np.random.default_rng(0))
print(f"final error {1000 * result.abs_error[-1]:.1f} mm at size {result.size[-1]:g}")

fig, (a, b) = plt.subplots(1, 2, figsize=(8, 3.2))
for i, name in enumerate(["upper", "fore", "hand"]):
    a.plot(np.arange(1, EPOCHS + 1), factors[:, i], label=name)
a.set(xlabel="epoch", ylabel="length factor", title="segments grow at rates 2 : 1 : 1")
a.legend(frameon=False)
b.plot(result.epoch, 1000 * result.abs_error)
b.set(xscale="log", yscale="log", xlabel="epoch", ylabel="absolute error [mm]",
      title="Goal Babbling while growing")
fig.tight_layout()
fig.savefig(OUT / "arm3_urdf_growth.png", dpi=100)
