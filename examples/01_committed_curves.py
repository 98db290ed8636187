# %% [markdown]
# # The committed learning curves, reloaded and plotted
#
# `outputs/report/curves.parquet` holds the aggregated learning curves of every figure of the
# committed full-scale run (mean and quartiles over trials per condition and evaluated epoch).
# No simulation: this reads the table and draws Fig. 4's absolute error.
#
# Run: `.venv/bin/python examples/01_committed_curves.py` (or open it in Jupyter via jupytext).

# %%
import os
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import pandas as pd  # noqa: E402

REPO = Path(__file__).resolve().parents[1] if "__file__" in globals() else Path.cwd()
CURVES = Path(os.environ.get("GBGROWTH_CURVES", REPO / "outputs" / "report" / "curves.parquet"))
FIGURE = os.environ.get("GBGROWTH_FIGURE", "fig4")
# the figures go under outputs/examples/ (ignored by git), never into the repository itself
OUT = Path(os.environ.get("GBGROWTH_EXAMPLE_OUT", REPO / "outputs" / "examples"))
OUT.mkdir(parents=True, exist_ok=True)

# %%
curves = pd.read_parquet(CURVES)
fig4 = curves[curves["figure"] == FIGURE]
print(sorted(curves["figure"].unique()))
print(fig4.groupby("condition")["epoch"].max())

# %%
fig, ax = plt.subplots(figsize=(5, 3.5))
for condition, c in fig4.groupby("condition", sort=False):
    c = c.sort_values("epoch")
    ax.plot(c["epoch"], 1000 * c["abs_error_mean"], label=condition)
    ax.fill_between(c["epoch"], 1000 * c["abs_error_q25"], 1000 * c["abs_error_q75"], alpha=0.2)
ax.set(xscale="log", yscale="log", xlabel="epoch", ylabel="absolute error [mm]",
       title=f"{FIGURE}: mean and quartiles over trials")
fig.legend(loc="lower center", ncol=4, frameon=False, fontsize=7)
fig.tight_layout(rect=(0, 0.12, 1, 1))
fig.savefig(OUT / f"{FIGURE}_abs_error.png", dpi=100)
final = fig4.sort_values("epoch").groupby("condition").last()["abs_error_mean"]
print((1000 * final).round(1).to_string())
