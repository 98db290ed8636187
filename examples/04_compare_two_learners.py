# %% [markdown]
# # Compare two learners on the same growing body
#
# Goal Babbling (the paper's batch learner) against online Goal Babbling on the 5-DOF arm
# growing from half to full size, a few trials each, with the same seeds. Plain `gbmodel`
# calls; the pipeline does the same at scale with
# `python -m pipeline.simulate -m learner=goal_babbling,online_goal_babbling figure=learners`.
#
# Run: `.venv/bin/python examples/04_compare_two_learners.py`

# %%
import os
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

import gbmodel  # noqa: E402

EPOCHS = int(os.environ.get("GBGROWTH_EPOCHS", 1000))
TRIALS = int(os.environ.get("GBGROWTH_TRIALS", 3))
REPO = Path(__file__).resolve().parents[1] if "__file__" in globals() else Path.cwd()
# the figures go under outputs/examples/ (ignored by git), never into the repository itself
OUT = Path(os.environ.get("GBGROWTH_EXAMPLE_OUT", REPO / "outputs" / "examples"))
OUT.mkdir(parents=True, exist_ok=True)

# %%
growth = dict(pattern="proportional", period=EPOCHS // 2, start_size=0.5, end_size=1.0)
curves = {}
for learner in ("goal_babbling", "online_goal_babbling"):
    spec = gbmodel.TrialSpec(body={"name": "arm5"}, growth=growth, epochs=EPOCHS,
                             learner=dict(name=learner))
    runs = [gbmodel.run_trial(spec, np.random.default_rng(seed)) for seed in range(TRIALS)]
    curves[learner] = (runs[0].epoch, np.stack([r.abs_error for r in runs]))
    print(f"{learner}: final error {1000 * curves[learner][1][:, -1].mean():.1f} mm "
          f"(mean of {TRIALS} trials)")

# %%
fig, ax = plt.subplots(figsize=(5, 3.5))
for (learner, (epoch, err)), ls in zip(curves.items(), ("-", "--")):
    ax.plot(epoch, 1000 * err.mean(axis=0), ls=ls, color="black", label=learner)
ax.axvline(growth["period"], color="0.6", lw=0.8, ls=":")
ax.set(xscale="log", yscale="log", xlabel="epoch", ylabel="absolute error [mm]",
       title="arm5 growing 0.5 -> 1.0")
ax.legend(frameon=False)
fig.tight_layout()
fig.savefig(OUT / "learners.png", dpi=100)
