"""The choices the paper leaves open (conf/experiment/choices_*.yaml, one variant per alternative,
common random numbers): choices.csv / choices.md, per variant the final error, the same final
models scored otherwise (RMS, eq. 10's mean squared distance, worst target, off-grid points) and
the rise during growth."""
from __future__ import annotations

import numpy as np
import pandas as pd

import gbmodel
from gbmodel import evaluation
from gbmodel.bodies import cell_centres

from .sections import Context, prose, register


def scores(spec: dict, M) -> dict:
    """The final model M of a trial scored over the grid and off it, with the body at its end."""
    s = gbmodel.TrialSpec.from_dict(spec)
    body, (learner, params), g = s.make_body(), s.make_learner(), s.make_growth()
    scale = g.scales(body, g.end_size)

    def dist(xs):
        return evaluation.distances(lambda x: learner.predict(np.asarray(M), params, body, x),
                                    body, scale, xs)

    d = dist(body.target_set(g.end_size))
    return dict(rms_m=float(np.sqrt(np.mean(d ** 2))), mean_sq_m2=float(np.mean(d ** 2)),
                worst_m=float(d.max()),
                off_grid_m=float(dist(cell_centres(body.targets) * g.end_size).mean()))


def table(aggs: dict) -> pd.DataFrame:
    """One row per variant of every choices experiment in `aggs` (figure -> aggregate)."""
    rows = []
    for figure, agg in aggs.items():
        for r in agg["summary"].itertuples():
            c = agg["models"]["conditions"][r.condition]
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
    """A Markdown table cell: pipes escaped (|g - home|, `R=0.1 | TG1000`), line breaks folded."""
    return " ".join(str(text).splitlines()).replace("|", "\\|")


def markdown(t: pd.DataFrame, aggs: dict) -> str:
    setups = "; ".join(f"`{f}`: {int(a['summary']['n_trials'].max())} trials x "
                       f"{int(a['summary']['epochs'].min()):,}-"
                       f"{int(a['summary']['epochs'].max()):,} epochs" for f, a in aggs.items())
    lines = [
        "# Open choices: measured effect of the alternatives", "",
        prose("choices.intro", setups=setups), "",
        "| body | choice | variant | final error [mm] | RMS [mm] | mean squared [mm^2] "
        "| worst target [mm] | off-grid [mm] | rise during growth |",
        "|---|---|---|---|---|---|---|---|---|"]
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
    ctx.quote(t, ("figure", "choice", "variant"), QUOTED)
    text = markdown(t, chosen)
    ctx.text("choices.md", text)
    return ["## Choices the paper leaves open: measured effect of the alternatives",
            text.split("\n", 1)[1]]


# the numbers of choices.csv the pages quote (docs/choices.md, README.md, findings.md), named
# here where the table is made: name -> the row's figure (the name's second part), choice and
# variant, and its column (the name's last part)
QUOTED = {name: (name.split(".")[1], *row, name.rsplit(".", 1)[1]) for name, row in {
    'choices.choices_arm5.gradient_step.normalised.final_abs_mm_mean':
        ('gradient step', 'normalised by sum w, eta = 1.0'),
    'choices.choices_arm5.gradient_step.plain.final_abs_mm_mean':
        ('gradient step', 'plain (eq. 6)'),
    'choices.choices_icub.gradient_step.normalised.final_abs_mm_mean':
        ('gradient step', 'normalised by sum w, eta = 1.0'),
    'choices.choices_icub.gradient_step.plain.final_abs_mm_mean':
        ('gradient step', 'plain (eq. 6)'),
    'choices.choices_arm5.learning_rate_growth_t_g_100.normalised.growth_rise_pct':
        ('learning rate, growth T_G = 100', 'T_G = 100, normalised step'),
    'choices.choices_arm5.learning_rate_growth_t_g_100.t_g_100_eta_1_w.growth_rise_pct':
        ('learning rate, growth T_G = 100', 'T_G = 100, eta = 1 / W'),
    'choices.choices_arm5.learning_rate_w_1142.eta_0.5_w.final_abs_mm_mean':
        ('learning rate (W = 1142)', 'eta = 0.5 / W'),
    'choices.choices_arm5.learning_rate_w_1142.eta_1_w.final_abs_mm_mean':
        ('learning rate (W = 1142)', 'eta = 1 / W'),
    'choices.choices_arm5.learning_rate_w_1142.eta_1.5_w.final_abs_mm_mean':
        ('learning rate (W = 1142)', 'eta = 1.5 / W'),
    'choices.choices_arm5.learning_rate_w_1142.eta_2_w.final_abs_mm_mean':
        ('learning rate (W = 1142)', 'eta = 2 / W'),
    'choices.choices_icub.learning_rate_w_1791.eta_0.5_w.final_abs_mm_mean':
        ('learning rate (W = 1791)', 'eta = 0.5 / W'),
    'choices.choices_icub.learning_rate_w_1791.eta_1_w.final_abs_mm_mean':
        ('learning rate (W = 1791)', 'eta = 1 / W'),
    'choices.choices_icub.learning_rate_w_1791.eta_1.5_w.final_abs_mm_mean':
        ('learning rate (W = 1791)', 'eta = 1.5 / W'),
    'choices.choices_icub.learning_rate_w_1791.eta_2_w.final_abs_mm_mean':
        ('learning rate (W = 1791)', 'eta = 2 / W'),
    'choices.choices_arm5.learning_rate_growth_t_g_100.eta_0.1_w.growth_rise_pct':
        ('learning rate, growth T_G = 100', 'T_G = 100, eta = 0.1 / W'),
    'choices.choices_arm5.learning_rate_growth_t_g_100.eta_0.3_w.growth_rise_pct':
        ('learning rate, growth T_G = 100', 'T_G = 100, eta = 0.3 / W'),
    'choices.choices_arm5.learning_rate_growth_t_g_100.eta_1_w.growth_rise_pct':
        ('learning rate, growth T_G = 100', 'T_G = 100, eta = 1 / W'),
    'choices.choices_arm5.learning_rate_growth_t_g.eta_0.1_w.growth_rise_pct':
        ('learning rate, growth T_G = 1000', 'T_G = 1000, eta = 0.1 / W'),
    'choices.choices_arm5.learning_rate_growth_t_g.eta_0.3_w.growth_rise_pct':
        ('learning rate, growth T_G = 1000', 'T_G = 1000, eta = 0.3 / W'),
    'choices.choices_arm5.learning_rate_growth_t_g.eta_1_w.growth_rise_pct':
        ('learning rate, growth T_G = 1000', 'T_G = 1000, eta = 1 / W'),
    'choices.choices_arm5.updates_per_epoch.two_batch_steps.final_abs_mm_mean':
        ('updates per epoch', 'two batch steps'),
    'choices.choices_arm5.updates_per_epoch.two_batch_steps.final_abs_mm_std':
        ('updates per epoch', 'two batch steps'),
    'choices.choices_arm5.updates_per_epoch.online.final_abs_mm_mean':
        ('updates per epoch', 'online, one step per sample'),
    'choices.choices_icub.updates_per_epoch.online.final_abs_mm_mean':
        ('updates per epoch', 'online, one step per sample'),
    'choices.choices_arm5.learning_rate_growth_t_g_100.online_updates.growth_rise_pct':
        ('learning rate, growth T_G = 100', 'T_G = 100, online updates'),
    'choices.choices_arm5.rate_schedule.annealed.final_abs_mm_mean':
        ('rate schedule', "annealed, tau = 10,000 epochs (not the paper's)"),
    'choices.choices_icub.rate_schedule.annealed.final_abs_mm_mean':
        ('rate schedule', "annealed, tau = 10,000 epochs (not the paper's)"),
    'choices.choices_arm5.initialisation.0.0.final_abs_mm_mean':
        ('initialisation', '|g - home| <= 0.0'),
    'choices.choices_arm5.initialisation.0.1.final_abs_mm_mean':
        ('initialisation', '|g - home| <= 0.1'),
    'choices.choices_arm5.initialisation.0.3.final_abs_mm_mean':
        ('initialisation', '|g - home| <= 0.3'),
    'choices.choices_icub.initialisation.0.0.final_abs_mm_mean':
        ('initialisation', '|g - home| <= 0.0'),
    'choices.choices_icub.initialisation.0.1.final_abs_mm_mean':
        ('initialisation', '|g - home| <= 0.1'),
    'choices.choices_icub.initialisation.0.3.final_abs_mm_mean':
        ('initialisation', '|g - home| <= 0.3'),
    'choices.choices_arm5.target_grid.wider.final_abs_mm_mean':
        ('target grid', 'wider: x -0.6..0.6, y 0.1..0.7 (13 x 7)'),
    'choices.choices_arm5.target_grid.coarser.final_abs_mm_mean':
        ('target grid', 'coarser: 6 x 3 over the same box'),
    'choices.choices_icub.gradient_step.plain.off_grid_mm': ('gradient step', 'plain (eq. 6)'),
    'choices.choices_icub.target_grid.smaller.final_abs_mm_mean':
        ('target grid', 'smaller: the 4 x 4 x 4 grid shrunk to 2/3 about its centre'),
    'choices.choices_arm5.home_posture.0.25_rad.final_abs_mm_mean':
        ('home posture', 'bend 0.25 rad per joint'),
    'choices.choices_arm5.home_posture.0.75_rad.final_abs_mm_mean':
        ('home posture', 'bend 0.75 rad per joint'),
    'choices.choices_icub.joint_limits.final_abs_mm_mean':
        ('joint limits', 'ignored (no saturation)'),
    'choices.choices_arm5.gradient_step.plain.off_grid_mm': ('gradient step', 'plain (eq. 6)'),
    'choices.choices_arm5.gradient_step.plain.rms_mm': ('gradient step', 'plain (eq. 6)'),
    'choices.choices_arm5.gradient_step.plain.mean_sq_mm2': ('gradient step', 'plain (eq. 6)'),
    'choices.choices_arm5.non_proportional_short.proportionally.final_abs_mm_mean':
        ('non-proportional short reference', 'proportionally halved body (0.5 m)'),
    'choices.choices_arm5.non_proportional_short.non_proportional_start.final_abs_mm_mean':
        ('non-proportional short reference', 'non-proportional start body (0.5 m)'),
    'choices.choices_arm5.successive_path_targets.uniform.final_abs_mm_mean':
        ('successive path targets', 'uniform over all targets (repeats allowed)'),
    'choices.choices_arm5.successive_path_targets.differs.final_abs_mm_mean':
        ('successive path targets', 'each differs from the one before'),
    'choices.choices_arm5.growth_schedule_t_g_1000.infant.final_abs_mm_mean':
        ('growth schedule, T_G = 1000', 'T_G = 1000, infant (WHO fit)'),
    'choices.choices_arm5.growth_schedule_t_g_1000.infant.growth_rise_pct':
        ('growth schedule, T_G = 1000', 'T_G = 1000, infant (WHO fit)'),
    'choices.choices_arm5.growth_schedule_t_g_1000.linear.growth_rise_pct':
        ('growth schedule, T_G = 1000', "T_G = 1000, linear (the paper's)"),
    'choices.choices_arm2.100_000_epochs.final_abs_mm_mean': ('Fig. 2 duration', '100,000 epochs'),
    'choices.choices_arm2.10_000_epochs.final_abs_mm_mean': ('Fig. 2 duration', '10,000 epochs'),
    'choices.choices_arm2.100_000_epochs.worst_mm': ('Fig. 2 duration', '100,000 epochs'),
    'choices.choices_arm2.10_000_epochs.worst_mm': ('Fig. 2 duration', '10,000 epochs'),
    'choices.choices_arm5.root_seed.2011.final_abs_mm_mean': ('root seed', '2011'),
    'choices.choices_arm5.root_seed.2011.final_abs_mm_std': ('root seed', '2011'),
    'choices.choices_arm5.root_seed.2010.final_abs_mm_mean': ('root seed', '2010'),
    'choices.choices_arm5.root_seed.2010.final_abs_mm_std': ('root seed', '2010'),
}.items()}
