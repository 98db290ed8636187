"""The section of every experiment that declares no other study (paper.study): the paper's own
(paper.claims: true) with the scorecard, claims, discussion and conventions, and for each its
curves, summary, stages, postures and animations (one's own: the settings that made it)."""
from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import numpy as np
import pandas as pd
from omegaconf import OmegaConf

from .. import io
from . import claims, conventions, discussion, figures, replicate, scorecard
from .choices import escape
from .claims import DIVERGED, diverged_conditions
from .sections import Context, declares_claims, prose, register
from .quoted import CONTROLLED, RANGED, SCORECARD, SUMMARY, SUMMARY_RATIOS
from .values import printed

MAX_PANELS = 4  # posture panels of a figure that report.postures does not name


def counted_figures(declared: dict) -> list[str]:
    """The figures the headline counts: those declaring the claims, less one judged on another
    that is there (paper.judged_on: Fig. 7 on fig7_20trials)."""
    return [k for k, a in declared.items()
            if a["models"].get("paper", {}).get("judged_on") not in declared]


def _mm(v) -> str:
    return "" if v is None or not np.isfinite(v) else f"{1000 * v:.1f}"


def _pm(mean, std) -> str:
    return "" if not np.isfinite(mean) else _mm(mean) + (f" ± {_mm(std)}" if np.isfinite(std)
                                                         else "")


def _heldout(r) -> str:
    """The held-out error [mm] ± its std, and its mean in % of the body's reach."""
    text = _pm(r.get("final_heldout_abs_error_mean", np.nan),
               r.get("final_heldout_abs_error_std", np.nan))
    pct = r.get("final_heldout_abs_error_pct_reach", np.nan)
    return f"{text} ({pct:.2f} %)" if text and np.isfinite(pct) else text


def summary_markdown(summary: pd.DataFrame) -> str:
    """The summary as a Markdown table, errors in mm (relative: mm per unit size)."""
    head = ("| figure | condition | body | growth | T_G | trials | final abs. error [mm] "
            "| held-out error [mm] (% of reach) | final rel. error [mm/size] | peak abs. error during growth [mm] (rise, epoch) "
            "| run failures | diverged | failed to bootstrap | paper: final abs. error [mm] |")
    lines = [head, "|" + "---|" * head.count(" | ") + "---|"]
    dead = set(diverged_conditions(summary))
    for _, r in summary.iterrows():
        peak = (f"{_mm(r['peak_abs_error_growth'])} (+{_mm(r['rise_abs_error_growth'])}, "
                f"epoch {r['peak_epoch_growth']})" if np.isfinite(r["peak_abs_error_growth"]) else "")
        gone = DIVERGED if r["condition"] in dead else ""  # no trial left a curve
        lines.append(
            f"| {escape(r['figure'])} | {escape(r['condition'])} | {escape(r['body'])} "
            f"| {escape(r['growth'])} "
            f"| {r['growth_period'] if r['growth'] != 'none' else ''} | {r['n_trials']} "
            f"| {_pm(r['final_abs_error_mean'], r['final_abs_error_std']) or gone} "
            f"| {_heldout(r) or gone} "
            f"| {_pm(r['final_rel_error_mean'], r['final_rel_error_std']) or gone} | {peak or gone} "
            f"| {r['n_run_failures']} | {r['n_diverged']} | {r['n_bootstrap_failures']} "
            f"| {_mm(r['paper_final_abs_error'])} |")
    return "\n".join(lines) + "\n"


def figure_options(cfg) -> dict:
    """learning_curves' options from report.title ("": the figure's), report.error_unit,
    report.log_error_axis and report.log_epoch_axis; a key the config lacks keeps its default."""
    from ..config import ConfigError

    get = lambda key, default: OmegaConf.select(cfg, f"report.{key}", default=default)  # noqa: E731
    unit = get("error_unit", "m")
    if unit not in figures.UNITS:
        raise ConfigError(f"report.error_unit={unit}: one of {', '.join(figures.UNITS)}")
    return dict(log_y=bool(get("log_error_axis", True)), log_x=bool(get("log_epoch_axis", True)),
                unit=unit, suptitle=get("title", "") or None)


def _stages(cond: dict, trial: dict) -> list[tuple[str, list]]:
    """(label, M) of a trial's snapshots, then its final M unless the last snapshot is it."""
    out = [(f"after epoch {e}", M) for e, M in
           sorted(trial["snapshots"].items(), key=lambda kv: int(kv[0]))]
    if str(cond["spec"]["epochs"]) not in trial["snapshots"]:
        out.append((f"final, epoch {cond['spec']['epochs']}", trial["M"]))
    return out


def _stages_figure(agg: dict) -> tuple | None:
    """(spec, [(label, M)]) of trial 0 of the first condition that has one."""
    for cond in agg["models"]["conditions"].values():
        if "0" in cond["trials"]:
            return cond["spec"], [(f"({chr(97 + i)}) {label}", M) for i, (label, M) in
                                  enumerate(_stages(cond, cond["trials"]["0"]))]
    return None


def _trial_stages(agg: dict) -> list[list]:
    """Each trial's M at every stage of the first condition with trials (the scorecard's
    interval over Fig. 2's trials)."""
    for cond in agg["models"]["conditions"].values():
        out = [[M for _, M in _stages(cond, t)]
               for _, t in sorted(cond["trials"].items(), key=lambda kv: int(kv[0]))]
        if out:
            return out
    return []


def _posture_panels(aggs: dict, wanted) -> list:
    panels = []
    for figure, condition in wanted:
        cond = aggs.get(figure, {}).get("models", {}).get("conditions", {}).get(condition)
        # a posture needs a stored model its learner predicts from (predict_model)
        if cond and cond["trials"].get("0", {}).get("M") is not None \
                and figures.draws_model(cond["spec"]):
            label = f"{figure} {condition}, trial 0"
            panels.append((label, cond["spec"], cond["trials"]["0"]["M"]))
    return panels


@dataclass
class Paper:
    """What the parts of the figures section share, computed once (Paper.of)."""

    aggs: dict  # figure -> aggregate: every figure of the section
    declared: dict  # the figures that declare the paper's claims (paper.claims: true)
    js: str  # Fig. 2's figure: stages in a joint space over one target axis
    stages: tuple | None  # its (spec, [(label, M)]), when it has a one-joint-axis body
    summary: pd.DataFrame  # every figure's summary
    measured: list  # the claims' per-trial measures (scorecard.figure_measures)
    measures: list  # judged under every reading (none decided at a reduced scale)
    cards: pd.DataFrame | None  # the scorecard's cells
    claim_rows: list  # the claims table, a row per cell
    discussion: str  # findings.md, if these are its run's numbers, else a note

    @classmethod
    def of(cls, ctx: Context, aggs: dict) -> "Paper":
        cfg = ctx.cfg
        declared = {k: a for k, a in aggs.items() if declares_claims(a)}
        js = cfg.report.joint_space_figure
        stages = _stages_figure(aggs[js]) if js in aggs else None
        if stages is not None and figures.final_body(stages[0])[0].n != 1:
            stages = None
        summary = pd.concat([a["summary"] for a in aggs.values()], ignore_index=True)
        judge_stages = stages is not None and js in declared
        measured = scorecard.figure_measures(declared, dict(
            figure=js, spec=stages[0], trials=_trial_stages(aggs[js])) if judge_stages else None)
        measures = scorecard.judged(measured) if measured else []
        if cfg.report.scale:  # a reduced scale (the smoke profile): measured, never decided
            measures = scorecard.no_verdicts(measures, cfg.report.scale)
        cards = scorecard.cells(measures) if measures else None
        claim_rows = scorecard.claims_table(cards).to_dict("records") if measures else []
        text = ""
        if claim_rows:
            if cfg.report.stamp_findings:
                discussion.stamp_findings(summary, claim_rows)
            text = discussion.findings(summary, claim_rows)  # of the committed run, if it is
        return cls(aggs, declared, js, stages, summary, measured, measures, cards, claim_rows,
                   text)


@register("figures", 10)
def section(ctx: Context) -> list[str]:
    """The section's parts in their order; each draws and writes its own files."""
    aggs = ctx.of("figures")
    if not aggs:
        return []
    p = Paper.of(ctx, aggs)
    return [line for part in PARTS for line in part(ctx, p)]


def scorecard_part(ctx: Context, p: Paper) -> list[str]:
    """The scorecard of the paper's claims: its figure, its tables and measures.parquet."""
    if not p.claim_rows:
        return []
    from . import readings

    counted = counted_figures(p.declared)
    ctx.text("claims.csv", pd.DataFrame(p.claim_rows).to_csv(index=False))
    every = pd.DataFrame(p.measures)  # the primary reading's; the others' beside
    ctx.text("scorecard.csv", every[every["primary"]].to_csv(index=False, float_format="%.6g"))
    ctx.text("scorecard_readings.csv", every[~every["primary"]].to_csv(
        index=False, float_format="%.6g"))
    ctx.quote(every[every["primary"]], ("figure", "claim", "where"), SCORECARD)
    ctx.quote(every[~every["primary"]], ("figure", "claim", "where", "reading"), CONTROLLED)
    ctx.value("headline.default", scorecard.headline_text(scorecard.headline(p.cards, counted)))
    bad = replicate.failing(replicate.calibrate(ctx), ctx.cfg.report.scale or "")
    p.cards["replicate"] = [(f, c) in bad for f, c in zip(p.cards["figure"], p.cards["claim"])]
    first, _ = scorecard.first_cells(p.measures)
    ctx.value("headline.first", scorecard.headline_text(scorecard.headline(first, counted))
              if len(first) else "")
    _write_measures(ctx, p.measured, counted)
    ctx.save(scorecard.figure(p.cards, ctx.title.split(":")[0] + ": the paper's claims, "
                              "t intervals over trials"), "scorecard")
    ours = our_reading(p.cards) if p.discussion == discussion.FINDINGS.read_text() else None
    return ["## Scorecard: the paper's claims, with their uncertainty", "",
            "![scorecard](scorecard.png)", "",
            # the readings' headline: at the paper's scale only (a reduced scale decides nothing)
            scorecard.markdown(p.cards, p.measures, counted, ours, "" if ctx.cfg.report.scale else
                               scorecard.recommended_headline(readings.shared_cards(ctx),
                                                              readings.recommended()),
                               scorecard.first_headline(p.measures, counted)),
            prose("scorecard.after"), ""]


def claims_part(ctx: Context, p: Paper) -> list[str]:
    """The claims, their criteria and every registered reading (pipeline/studies/register.yaml)."""
    if not p.claim_rows:
        return []
    return ["## The claims, their criteria and measures", "", claims_markdown(), "",
            prose("paper.readings"), "",
            readings_markdown()]


def claims_markdown() -> str:
    """The claims, their criteria and measures (the register's primary readings)."""
    lines = ["| claim | figures | criterion (on the mean over trials) | measure, per trial |",
             "|---|---|---|---|"]
    lines += [f"| {scorecard.TITLES[c.id]} | {c.figures} | {c.criterion} | {c.measure} |"
              for c in claims.CLAIMS]
    return "\n".join(lines) + "\n"


def readings_markdown() -> str:
    """Every registered reading of every claim."""
    lines = ["| claim | reading | criterion | counted | why (the paper's words) | fixed at |",
             "|---|---|---|---|---|---|"]
    for c in claims.CLAIMS:
        for r in c.readings:
            counted = ("primary" if r.primary and not c.diagnostic else
                       "diagnostic" if r.diagnostic or c.diagnostic else "shown where it differs")
            lines.append(f"| {scorecard.TITLES[c.id]} | {r.label} | {r.criterion} | {counted} "
                         f"| {' '.join(r.why.split())} | {r.fixed_at} |")
    return "\n".join(lines) + "\n"


def our_reading(cards: pd.DataFrame, register: list | None = None) -> dict:
    """claim -> our reading where every verdict it was written for is this run's, else a note."""
    now = {(r["claim"], r["figure"]): r["verdict"] for r in cards.to_dict("records")}
    out = {}
    for c in claims.CLAIMS if register is None else register:
        if not c.our_reading:
            continue
        off = [f"{f}: {v}, now {now[(c.id, f)]}" for f, v in c.our_reading["written_for"].items()
               if (c.id, f) in now and now[(c.id, f)] != v]
        out[c.id] = (c.our_reading["text"] if not off else
                     "(our reading was written for other verdicts: " + "; ".join(off)
                     + "; see the discussion)")
    return out


def findings_part(ctx: Context, p: Paper) -> list[str]:
    """The discussion of the committed run (findings.md), or the note that it is left out."""
    return [p.discussion] if p.claim_rows else []


def curves_part(ctx: Context, p: Paper) -> list[str]:
    """Each figure's learning curves and summary (one's own: the settings that made it too);
    summary.csv, summary.md and curves.parquet of them all."""
    cfg, md = ctx.cfg, []
    ctx.text("summary.csv", p.summary.to_csv(index=False, float_format="%.6g"))
    ctx.text("summary.md", summary_markdown(p.summary))
    _name_summary(ctx, p.summary)
    curves = pd.concat([a["curves"] for a in p.aggs.values()], ignore_index=True)
    io.write_table(ctx.out / "curves.parquet", io.frame_to_table(curves))
    ctx.written.append(ctx.out / "curves.parquet")
    for name, agg in p.aggs.items():
        title, summ = agg["models"].get("paper", {}).get("title") or name, agg["summary"]
        fig = figures.learning_curves(
            agg["curves"], summ, title, paper_abs=agg["models"].get("paper", {}).get("final_abs_error"),
            **figure_options(cfg))
        image = ctx.save(fig, f"{name}_curves")[0].name
        md += [f"## {title}", ""]
        if len(summ):
            r0 = summ.iloc[0]
            md += [f"Body `{r0['body']}`, {int(r0['epochs'])} epochs, "
                   f"{int(summ['n_trials'].max())} trials per condition.", ""]
        if name not in p.declared:  # one's own experiment: what made it
            md += ["Settings of each condition that differ from the defaults:", "",
                   settings_markdown(agg)]
        md += [f"![{name}]({image})", "", summary_markdown(summ)]
    return md


SKIP = ("body.",)  # the body's geometry: named by the body, its file (urdf) shown on its own


def flatten(d: dict, prefix: str = "") -> dict:
    out = {}
    for k, v in d.items():
        out.update(flatten(v, f"{prefix}{k}.") if isinstance(v, dict) else {f"{prefix}{k}": v})
    return out


@lru_cache(maxsize=None)
def _default_spec(body: str) -> tuple:
    """The default configuration's trial spec for `body`, flattened; the plain default's for a
    body that does not compose by name (a body file of one's own)."""
    from ..config import compose
    from ..plan import plan

    for overrides in ([f"body={body}"], []):
        try:
            return tuple(flatten(plan(compose(overrides))[0]["spec"]).items())
        except Exception:  # a body that is not a config group: the plain default
            continue
    return ()


def differences(spec: dict) -> dict:
    """The settings of one condition's spec that differ from the defaults for its body."""
    base = dict(_default_spec(spec.get("body", {}).get("name", "")))
    return {k: v for k, v in flatten(spec).items()
            if not (k.startswith(SKIP) and k not in ("body.name", "body.urdf"))
            and base.get(k, object()) != v}


def settings_markdown(agg: dict) -> str:
    """What made a figure of one's own: a row per condition, its settings that differ from the
    spec the default configuration gives for the same body, as `key=value`."""
    lines = ["| condition | settings that differ from the defaults |", "|---|---|"]
    lines += [f"| {escape(name)} | "
              + escape("; ".join(f"{k}={v}" for k, v in differences(c["spec"]).items())
                       or "the defaults") + " |"
              for name, c in agg["models"]["conditions"].items()]
    return "\n".join(lines) + "\n"


def _drawing(title: str, paths: list[Path]) -> list[str]:
    return [f"## {title}", "", f"![{paths[0].stem}]({paths[0].name})", ""]


def stages_part(ctx: Context, p: Paper) -> list[str]:
    """Fig. 2: the inverse estimate in joint space at each stage of learning."""
    if p.stages is None:
        return []
    fig = figures.joint_space_stages(
        *p.stages, "Fig. 2: inverse estimate of the 2-DOF arm in joint space "
        "(contours: equal hand height)")
    return _drawing("Fig. 2: stages of learning (joint space)", ctx.save(fig, f"{p.js}_stages"))


def postures_part(ctx: Context, p: Paper) -> list[str]:
    """Targets, reached positions and postures at the final size: the sets report.postures
    names (the paper's Fig. 3 and 6), and trial 0 of the first conditions of every other figure."""
    posture_sets = {name: wanted for name, wanted in
                    OmegaConf.to_container(ctx.cfg.report.postures).items()
                    if any(f in p.declared for f, _ in wanted)}
    drawn = {f for wanted in posture_sets.values() for f, _ in wanted if f in p.aggs}
    for name in p.aggs:
        if name not in drawn and name != p.js:
            posture_sets[name] = [[name, c] for c in
                                  list(p.aggs[name]["models"]["conditions"])[:MAX_PANELS]]
    md = []
    for name, wanted in posture_sets.items():
        panels = _posture_panels(p.aggs, wanted)
        if panels:
            fig = figures.postures(panels, f"{name}: targets, reached positions and "
                                   "postures at the final size")
            md += _drawing(f"{name}: targets, reached positions and postures",
                           ctx.save(fig, f"{name}_postures"))
    return md


def animation_part(ctx: Context, p: Paper) -> list[str]:
    """A GIF per condition whose trial 0 stored its stages (report.animate)."""
    if not ctx.cfg.report.animate:
        return []
    from . import animation

    md = []
    for title, path in animation.write(p.aggs, ctx.out):
        ctx.written.append(path)
        md += _drawing(f"Watch it learn: {title}", [path])
    return md


def conventions_part(ctx: Context, p: Paper) -> list[str]:
    """The reporting conventions: the measured effect of each alternative on the paper's figures."""
    trials = {k: a["trials"] for k, a in p.aggs.items() if "trials" in a}
    table = conventions.table(p.aggs, trials, ctx.cfg.aggregate.fail_factor,
                              OmegaConf.to_container(ctx.cfg.report.postures))
    if not len(table):
        return []
    ctx.text("conventions.csv", table.to_csv(index=False, float_format="%.6g"))
    for name, x in table.attrs.get("values", {}).items():
        ctx.value(name, x)
    return [conventions.markdown(table)]


def _name_summary(ctx: Context, summary: pd.DataFrame) -> None:
    """The summary's numbers the pages quote, and their ratios (each as summary.csv prints it)."""
    ctx.quote(summary, ("figure", "condition"), SUMMARY)
    row = {(r.figure, r.condition): r for r in summary.itertuples()}
    ctx.shared["paper values"] = {k: printed(r.paper_final_abs_error) for k, r in row.items()
                                  if np.isfinite(r.paper_final_abs_error)}  # readings' ratios
    for name, (a, b, col) in SUMMARY_RATIOS.items():
        x = (printed(row[a].final_abs_error_mean) / printed(getattr(row[b], col))
             if a in row and b in row else np.nan)
        if np.isfinite(x):
            ctx.value(name, x)
    iCub = summary[summary["figure"] == "fig7_20trials"]  # the range the pages quote
    for col, names in RANGED.items():  # the iCub's range over its conditions, wherever measured
        for name, x in zip(names, (iCub[col].min(), iCub[col].max()) if col in iCub else ()):
            if np.isfinite(x):
                ctx.value(name, printed(x) * 1e3)




PARTS = (scorecard_part, claims_part, findings_part, curves_part, stages_part, postures_part,
         animation_part, conventions_part)  # the section's order


def _write_measures(ctx: Context, measured: list, counted: list) -> None:
    """measures.parquet: every per-trial measure of the figures, the readings study, the
    replicate sets, the baselines and the choices."""
    from . import measures_table, readings, replicate

    frames = [measures_table.frame([m for m in measured if m.figure == f], "figures",
                                   counted=f in counted)
              for f in dict.fromkeys(m.figure for m in measured)]
    recs = {(r["figure"], r["reading"]) for r in readings.recommended()}
    frames += [measures_table.frame(ms, "readings", reading=label,
                                    recommended=(fig, label) in recs)
               for (fig, label), ms in readings.shared_measures(ctx).items()]
    frames += replicate.frames(ctx)
    frames += measures_table.study_frames(ctx.of("baselines"), ctx.of("choices"))
    ctx.written.append(measures_table.write(ctx.out / measures_table.NAME, frames,
                                            ctx.cfg.report.scale))
