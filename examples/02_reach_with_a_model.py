# %% [markdown]
# # Reach with a trained model
#
# `pipeline.models.load(figure)` gives the final inverse estimate of every condition and trial:
# a polynomial g(x) = M phi(x) from a target x to the commands q. It reads the local aggregate
# (`outputs/aggregate/<figure>/models.json`) or, on a fresh clone, the models the report stage
# wrote beside the committed report (`outputs/report/models/<figure>.json`).
#
# Run: `.venv/bin/python examples/02_reach_with_a_model.py`

# %%
import os

import numpy as np

from pipeline import models

FIGURE = os.environ.get("GBGROWTH_FIGURE", "fig4")
FOLDER = os.environ.get("GBGROWTH_MODELS")  # None: the local aggregate, else the committed report

# %%
fig = models.load(FIGURE, FOLDER)
print(fig.labels)
m = fig[fig.labels[-1]]  # the last condition (fig4: the full-size reference)
print(m.label, "body", m.body.name, "size", m.size)

# %% [markdown]
# A target in the middle of the (full-size) grid, and a few random ones inside it:

# %%
targets = m.body.target_set(m.size)
lo, hi = targets.min(axis=0), targets.max(axis=0)
x = np.vstack([(lo + hi) / 2, np.random.default_rng(0).uniform(lo, hi, (4, len(lo)))])
q = m.posture(x)
hand = m.reach(x)
for xi, qi, hi_ in zip(x, q, hand):
    print(f"target {np.round(xi, 3)} -> q {np.round(qi, 2)} -> hand {np.round(hi_, 3)}, "
          f"miss {1000 * np.linalg.norm(hi_ - xi):.1f} mm")
print(f"mean miss over the grid: "
      f"{1000 * np.linalg.norm(m.reach(targets) - targets, axis=1).mean():.1f} mm")
