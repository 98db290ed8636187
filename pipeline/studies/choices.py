"""The choices the paper leaves open: the table of what each alternative changes, measured.

The runs are ordinary experiments (conf/experiment/choices_*.yaml: one variant per alternative,
each a few dotted overrides of the paper's settings, all with common random numbers), simulated,
cached and aggregated like the paper's figures. This module turns their aggregates into
choices.csv / choices.md: per variant the final error, and the same final models scored in other
ways (RMS, the mean squared distance printed in eq. 10, the worst target, off-grid points), and
the rise of the error during growth where the variant grows.
"""
from __future__ import annotations

import numpy as np
import pandas as pd

import gbmodel
from gbmodel import evaluation
from gbmodel.bodies import cell_centres

from .sections import Context, register


def scores(spec: dict, M) -> dict:
    """The final model M of a trial scored over the grid and off it, with the body at its end."""
    s = gbmodel.TrialSpec.from_dict(spec)
    body, learner_params = s.make_body(), s.make_learner()
    learner, params = learner_params
    g = s.make_growth()
    size = g.end_size
    scale = g.scales(body, size)

    def dist(xs):
        return evaluation.distances(lambda x: learner.predict(np.asarray(M), params, body, x),
                                    body, scale, xs)

    d = dist(body.target_set(size))
    return dict(rms_m=float(np.sqrt(np.mean(d ** 2))), mean_sq_m2=float(np.mean(d ** 2)),
                worst_m=float(d.max()), off_grid_m=float(dist(cell_centres(body.targets) * size).mean()))


def table(aggs: dict) -> pd.DataFrame:
    """One row per variant of every choices experiment in `aggs` (figure -> aggregate)."""
    rows = []
    for figure, agg in aggs.items():
        conds = agg["models"]["conditions"]
        for r in agg["summary"].itertuples():
            c = conds[r.condition]
            per_trial = [scores(c["spec"], t["M"]) for t in c["trials"].values()
                         if t["M"] is not None]
            mean = {k: float(np.mean([p[k] for p in per_trial])) if per_trial else np.nan
                    for k in ("rms_m", "mean_sq_m2", "worst_m", "off_grid_m")}
            before = r.peak_abs_error_growth - r.rise_abs_error_growth
            rows.append(dict(
                figure=figure, body=r.body, choice=r.choice, variant=r.variant, chosen=r.chosen,
                final_abs_mm_mean=1e3 * r.final_abs_error_mean,
                final_abs_mm_std=1e3 * r.final_abs_error_std, rms_mm=1e3 * mean["rms_m"],
                mean_sq_mm2=1e6 * mean["mean_sq_m2"], worst_mm=1e3 * mean["worst_m"],
                off_grid_mm=1e3 * mean["off_grid_m"],
                growth_rise_pct=100 * r.rise_abs_error_growth / before if before > 0 else np.nan,
                trials=r.n_trials, diverged=r.n_diverged))
    return pd.DataFrame(rows)


def escape(text) -> str:
    """A Markdown table cell's text: its pipes escaped (labels such as |g - home| or a sweep's
    `R=0.1 | TG1000`) and line breaks folded, so the row keeps its header's cells."""
    return " ".join(str(text).splitlines()).replace("|", "\\|")


def markdown(t: pd.DataFrame, aggs: dict) -> str:
    setups = []
    for figure, agg in aggs.items():
        s = agg["summary"]
        setups.append(f"`{figure}`: {int(s['n_trials'].max())} trials x "
                      f"{int(s['epochs'].min()):,}-{int(s['epochs'].max()):,} epochs")
    lines = [
        "# Open choices: measured effect of the alternatives",
        "",
        "Each row: one variant of the paper's settings, at full size without growth unless it "
        "says otherwise, with common random numbers across variants (conf/experiment/"
        f"choices_*.yaml; {'; '.join(setups)}). Final error = mean Euclidean distance over the "
        "target grid (the chosen formula); the next columns score the same final estimates as "
        "the RMS distance, as the mean squared distance printed in eq. 10 (mm^2), by the worst "
        "target, and over off-grid points (the centres of the grid cells). Rows with growth "
        "(0.5 -> 1.0 over T_G epochs) give the temporary rise of the mean absolute error during "
        "growth. * = chosen.",
        "",
        "| body | choice | variant | final error [mm] | RMS [mm] | mean squared [mm^2] "
        "| worst target [mm] | off-grid [mm] | rise during growth |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for r in t.itertuples():
        final = (f"{r.final_abs_mm_mean:.1f} ± {r.final_abs_mm_std:.1f}"
                 if np.isfinite(r.final_abs_mm_std) else f"{r.final_abs_mm_mean:.1f}")
        if r.diverged:
            final += f" ({r.diverged} of {r.trials + r.diverged} trials diverged)"
        lines.append(
            f"| {r.body} | {r.choice} | {escape(r.variant)}{' *' if r.chosen else ''} | {final} "
            f"| {r.rms_mm:.1f} | {r.mean_sq_mm2:.0f} | {r.worst_mm:.1f} | {r.off_grid_mm:.1f} "
            f"| {'' if np.isnan(r.growth_rise_pct) else f'+{r.growth_rise_pct:.0f} %'} |")
    return "\n".join(lines) + "\n"


@register("choices", 60)
def section(ctx: Context) -> list[str]:
    chosen = ctx.of("choices")
    t = table(chosen)
    if not len(t):
        return []
    ctx.text("choices.csv", t.to_csv(index=False, float_format="%.6g"))
    text = markdown(t, chosen)
    ctx.text("choices.md", text)
    return ["## Choices the paper leaves open: measured effect of the alternatives",
            text.split("\n", 1)[1]]
