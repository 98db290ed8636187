"""Beyond the paper: Goal Babbling against its alternatives under growth, measured.

The runs are experiments (conf/experiment/baselines_arm5|icub.yaml): four learners x {no growth,
the paper's linear growth, an infant-like schedule}, each with the same budget of reaching
movements (forward-kinematics samples). This module lays out their final errors and redundancy
measure, draws error against samples, and answers the paper's arguments with numbers.
"""
from __future__ import annotations

import numpy as np
import pandas as pd

from . import figures
from .choices import escape

STUDIES = ("baselines_arm5", "baselines_icub")
LEARNERS = ("Goal Babbling", "motor babbling", "motor babbling over the whole joint range",
            "example memory", "online Goal Babbling")  # the variants' labels, before ", <growth>"
GB, MB, MB_WIDE, MEMORY = LEARNERS[0], LEARNERS[1], LEARNERS[2], LEARNERS[3]
FACTOR = 1.5  # "fails" / "degrades": an error this many times the comparison's, fixed beforehand


def _growth(row) -> str:
    if row.growth == "none":
        return "no growth"
    return "infant" if row.variant.endswith("infant") else "linear"


def table(aggs: dict) -> pd.DataFrame:
    """One row per (body, learner, growth): final errors at the common sample budget."""
    rows = []
    for study in STUDIES:
        if study not in aggs:
            continue
        for r in aggs[study]["summary"].itertuples():
            rows.append(dict(body=r.body, learner=r.variant.rsplit(", ", 1)[0], growth=_growth(r),
                             samples=r.final_samples, trials=r.n_trials, diverged=r.n_diverged,
                             final_abs_mm=1e3 * r.final_abs_error_mean,
                             final_abs_mm_std=1e3 * r.final_abs_error_std,
                             final_rel_mm=1e3 * r.final_rel_error_mean,
                             largest_jump=r.largest_jump_mean, condition=r.condition,
                             figure=study))
    return pd.DataFrame(rows)


def _err(t, body, learner, growth):
    sel = t[(t.body == body) & (t.learner == learner) & (t.growth == growth)]
    return float(sel["final_abs_mm"].iloc[0]) if len(sel) else np.nan


def _answer(holds: bool, *numbers) -> str:
    return "not measured" if not np.all(np.isfinite(numbers)) else "yes" if holds else "no"


def claims(t: pd.DataFrame) -> list[dict]:
    """The paper's arguments about the alternatives (sec. 1-2), answered with the numbers."""
    out = []
    bodies = list(dict.fromkeys(t["body"]))
    for body in bodies:
        mb, gb = _err(t, body, MB_WIDE, "no growth"), _err(t, body, GB, "no growth")
        local = _err(t, body, MB, "no growth")
        jumps = t[(t.body == body) & (t.growth == "no growth")].set_index("learner")["largest_jump"]
        out.append(dict(body=body, argument="motor babbling cannot resolve redundancy: over the "
                        "whole joint range it ends worse than Goal Babbling (by more than "
                        f"{FACTOR:g}x), without growth",
                        measured=f"motor babbling {mb:.1f} mm (around home: {local:.1f} mm), "
                                 f"Goal Babbling {gb:.1f} mm "
                                 f"(largest joint-space jump between neighbouring points: "
                                 + ", ".join(f"{k} {v:.3g}" for k, v in jumps.items()) + ")",
                        answer=_answer(mb > FACTOR * gb, mb, gb)))
    if len(bodies) == 2:
        ratios = {b: _err(t, b, MB_WIDE, "no growth") / _err(t, b, GB, "no growth")
                  for b in bodies}
        out.append(dict(body=" and ".join(bodies), argument="motor babbling does not scale to "
                        "many joints: its error relative to Goal Babbling's grows from arm5 to "
                        "the iCub", measured=", ".join(f"{b}: {r:.2f}x" for b, r in ratios.items()),
                        answer=_answer(ratios[bodies[1]] > ratios[bodies[0]], *ratios.values())))
    for body in bodies:
        for learner, arg in ((MEMORY, "stored experience is void after growth: the "
                              f"example memory ends more than {FACTOR:g}x worse after growing "
                              "than without growth"),
                             (GB, "Goal Babbling keeps its error: after growing it "
                              f"ends within {FACTOR:g}x of its error without growth")):
            fixed = _err(t, body, learner, "no growth")
            grown = {g: _err(t, body, learner, g) for g in ("linear", "infant")}
            worse = max(grown.values()) > FACTOR * fixed
            out.append(dict(body=body, argument=arg,
                            measured=f"no growth {fixed:.1f} mm; " + ", ".join(
                                f"{g} {v:.1f} mm ({v / fixed:.2f}x)" for g, v in grown.items()),
                            answer=_answer(worse if learner == MEMORY else not worse,
                                           fixed, *grown.values())))
    return out


def markdown(t: pd.DataFrame, claim_rows: list[dict]) -> str:
    lines = ["| body | learner | growth | samples | trials | final abs. error [mm] "
             "| final rel. error [mm/size] | largest jump [command units] |",
             "|---|---|---|---|---|---|---|---|"]
    for r in t.itertuples():
        err = f"{r.final_abs_mm:.1f} ± {r.final_abs_mm_std:.1f}"
        if r.diverged:
            err += f" ({r.diverged} diverged)"
        lines.append(f"| {r.body} | {r.learner} | {r.growth} | {r.samples:,} | {r.trials} | {err} "
                     f"| {r.final_rel_mm:.1f} | {r.largest_jump:.3g} |")
    lines += ["", "| body | the paper's argument | measured | holds? |", "|---|---|---|---|"]
    lines += [f"| {c['body']} | {escape(c['argument'])} | {escape(c['measured'])} | {c['answer']} |"
              for c in claim_rows]
    return "\n".join(lines) + "\n"


def figure(aggs: dict, title: str):
    """Mean absolute error against samples: one panel per body and growth, a line per learner."""
    studies = [s for s in STUDIES if s in aggs]
    growths = ("no growth", "linear", "infant")
    fig, axes = figures.plt.subplots(len(studies), 3, squeeze=False, sharey="row",
                                     figsize=(9.0, 2.8 * len(studies)))
    colors = dict(zip(LEARNERS, figures.plt.get_cmap("tab10")(np.arange(len(LEARNERS)))))
    for i, s in enumerate(studies):
        summ, curves = aggs[s]["summary"], aggs[s]["curves"]
        for r in summ.itertuples():
            ax = axes[i, growths.index(_growth(r))]
            cu = curves[curves["condition"] == r.condition].sort_values("samples")
            name = r.variant.rsplit(", ", 1)[0]
            ax.plot(cu["samples"], cu["abs_error_mean"], color=colors.get(name), lw=1.2, label=name)
        for j, g in enumerate(growths):
            axes[i, j].set(xscale="log", yscale="log", title=f"{summ['body'].iloc[0]}, {g}",
                           xlabel="samples (reaching movements)")
        axes[i, 0].set_ylabel("absolute error [m]")
    axes[0, 0].legend(frameon=False, fontsize=7)
    fig.suptitle(title)
    fig.tight_layout()
    return fig
