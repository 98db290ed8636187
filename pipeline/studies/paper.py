"""The paper's figures as a report section: their curves, postures, summary, the scorecard of
the paper's claims, the discussion of the committed run, and the reporting conventions.

Every experiment that declares no other study (paper.study) is reported here: the paper's own
(paper.claims: true) with the scorecard, one's own by its curves, summary and the settings that
made it (studies/settings.py).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
from omegaconf import OmegaConf

from .. import io
from . import claims, conventions, figures, scorecard, settings
from .choices import escape
from .claims import DIVERGED, diverged_conditions
from .sections import Context, declares_claims, register

MAX_PANELS = 4  # posture panels of a figure that report.postures does not name


def counted_figures(declared: dict) -> list[str]:
    """The figures whose cells the headline counts: every one that declares the paper's claims,
    except one judged on another that is there (paper.judged_on: Fig. 7 on fig7_20trials)."""
    return [k for k, a in declared.items()
            if a["models"].get("paper", {}).get("judged_on") not in declared]


def _mm(v) -> str:
    return "" if v is None or not np.isfinite(v) else f"{1000 * v:.1f}"


def _pm(mean, std) -> str:
    if not np.isfinite(mean):
        return ""
    return _mm(mean) + (f" ± {_mm(std)}" if np.isfinite(std) else "")


def _heldout(r) -> str:
    """The held-out error [mm] ± its std, and its mean in % of the body's reach."""
    text = _pm(r.get("final_heldout_abs_error_mean", np.nan),
               r.get("final_heldout_abs_error_std", np.nan))
    pct = r.get("final_heldout_abs_error_pct_reach", np.nan)
    return f"{text} ({pct:.2f} %)" if text and np.isfinite(pct) else text


def summary_markdown(summary: pd.DataFrame) -> str:
    """The summary as a Markdown table, errors in mm (relative errors: mm per unit body size)."""
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


def _title(figure: str, agg: dict) -> str:
    return agg["models"].get("paper", {}).get("title") or f"{figure}"


def _stages_figure(agg: dict) -> tuple | None:
    """(spec, [(label, M)]) of trial 0 of the first condition: its snapshots, then the final M."""
    for cond in agg["models"]["conditions"].values():
        trial = cond["trials"].get("0")
        if trial is None:
            continue
        stages = [(f"after epoch {e}", M) for e, M in
                  sorted(trial["snapshots"].items(), key=lambda kv: int(kv[0]))]
        if str(cond["spec"]["epochs"]) not in trial["snapshots"]:
            stages.append((f"final, epoch {cond['spec']['epochs']}", trial["M"]))
        stages = [(f"({chr(97 + i)}) {label}", M) for i, (label, M) in enumerate(stages)]
        return cond["spec"], stages
    return None


def _trial_stages(agg: dict) -> list[list]:
    """Each trial's M at every stage of _stages_figure (snapshots, then the final M), for the
    scorecard's interval over Fig. 2's trials."""
    for cond in agg["models"]["conditions"].values():
        out = []
        for _, trial in sorted(cond["trials"].items(), key=lambda kv: int(kv[0])):
            ms = [M for _, M in sorted(trial["snapshots"].items(), key=lambda kv: int(kv[0]))]
            if str(cond["spec"]["epochs"]) not in trial["snapshots"]:
                ms.append(trial["M"])
            out.append(ms)
        if out:
            return out
    return []


def _posture_panels(aggs: dict, wanted) -> list:
    panels = []
    for figure, condition in wanted:
        cond = aggs.get(figure, {}).get("models", {}).get("conditions", {}).get(condition)
        # a posture needs a polynomial inverse M (Goal Babbling's); other learners have none
        if cond and "0" in cond["trials"] and "degree" in cond["spec"]["learner"]:
            label = f"{figure} {condition}, trial 0"
            panels.append((label, cond["spec"], cond["trials"]["0"]["M"]))
    return panels


@register("figures", 10)
def section(ctx: Context) -> list[str]:
    cfg, out, aggs = ctx.cfg, ctx.out, ctx.of("figures")
    if not aggs:
        return []
    declared = {k: a for k, a in aggs.items() if declares_claims(a)}
    sections, extra = [], []
    js = cfg.report.joint_space_figure  # Fig. 2: stages in a joint space over one target axis
    stages = _stages_figure(aggs[js]) if js in aggs else None
    if stages is not None and figures.final_body(stages[0])[0].n != 1:
        stages = None
    for name, agg in aggs.items():
        fig = figures.learning_curves(
            agg["curves"], agg["summary"], _title(name, agg), log_y=cfg.report.log_error_axis,
            paper_abs=agg["models"].get("paper", {}).get("final_abs_error"))
        paths = ctx.save(fig, f"{name}_curves")
        sections.append((name, _title(name, agg), [paths[0].name], agg["summary"]))
    if stages is not None:
        fig = figures.joint_space_stages(
            *stages, "Fig. 2: inverse estimate of the 2-DOF arm in joint space "
            "(contours: equal hand height)")
        extra.append(("Fig. 2: stages of learning (joint space)", ctx.save(fig, f"{js}_stages")))
    posture_sets = OmegaConf.to_container(cfg.report.postures)
    posture_sets = {name: wanted for name, wanted in posture_sets.items()
                    if any(f in declared for f, _ in wanted)}
    drawn = {f for wanted in posture_sets.values() for f, _ in wanted if f in aggs}
    for name in aggs:  # every other figure: trial 0 of each of its first conditions
        if name not in drawn and name != js:
            posture_sets[name] = [[name, c] for c in
                                  list(aggs[name]["models"]["conditions"])[:MAX_PANELS]]
    for name, wanted in posture_sets.items():
        panels = _posture_panels(aggs, wanted)
        if panels:
            fig = figures.postures(panels, f"{name}: targets, reached positions and "
                                   "postures at the final size")
            extra.append((f"{name}: targets, reached positions and postures",
                          ctx.save(fig, f"{name}_postures")))
    if cfg.report.animate:  # a GIF per condition whose trial 0 stored its stages
        from . import animation
        for title, path in animation.write(aggs, out):
            ctx.written.append(path)
            extra.append((f"Watch it learn: {title}", [path]))

    summary = pd.concat([a["summary"] for a in aggs.values()], ignore_index=True)
    ctx.text("summary.csv", summary.to_csv(index=False, float_format="%.6g"))
    ctx.text("summary.md", summary_markdown(summary))

    judge_stages = stages is not None and js in declared
    measured = scorecard.figure_measures(declared, dict(
        figure=js, spec=stages[0], trials=_trial_stages(aggs[js])) if judge_stages else None)
    measures = scorecard.judged(measured) if measured else []
    if cfg.report.scale:  # a reduced scale (the smoke profile): measured, never decided
        measures = scorecard.no_verdicts(measures, scorecard.reduced_scale(cfg.report.scale))
    cards = scorecard.cells(measures) if measures else None
    claim_rows = scorecard.claims_table(cards).to_dict("records") if measures else []
    md = []
    if claim_rows:
        counted = counted_figures(declared)
        readings_cards, recommended = _recommended(ctx)
        ctx.text("claims.csv", pd.DataFrame(claim_rows).to_csv(index=False))
        every = pd.DataFrame(measures)  # the primary reading's; the others' beside
        ctx.text("scorecard.csv", every[every["primary"]].to_csv(index=False,
                                                                  float_format="%.6g"))
        ctx.text("scorecard_readings.csv", every[~every["primary"]].to_csv(
            index=False, float_format="%.6g"))
        _write_measures(ctx, measured, counted)
        ctx.save(scorecard.figure(cards, ctx.title.split(":")[0] + ": the paper's claims, "
                                  "calibrated intervals over trials"), "scorecard")
        if cfg.report.stamp_findings:
            stamp_findings(summary, claim_rows)
        discussion = findings(summary, claim_rows)  # of the committed run, if it is
        ours = claims.our_reading(cards) if discussion == FINDINGS.read_text() else None
        md += ["## Scorecard: the paper's claims, with their uncertainty", "",
               "![scorecard](scorecard.png)", "",
               scorecard.markdown(cards, measures, counted, ours,
                                  "" if cfg.report.scale else
                                  scorecard.recommended_headline(readings_cards, recommended)),
               "Each cell: its verdict, how many of its conditions are reproduced, and its worst "
               "condition: the mean over trials of the measure and its interval "
               "(`scorecard.csv` holds every measure, `scorecard_readings.csv` the same under "
               "the other registered readings, `claims.csv` every "
               "cell, `measures.parquet` every per-trial value: `python -m "
               "pipeline.tools.rescore` judges them again under an edited register); "
               "pipeline/studies/scorecard.py says how.", "",
               "## The claims, their criteria and measures", "", claims.markdown(), "",
               "Every registered reading of a criterion (pipeline/studies/register.yaml; the "
               "cells above show a reading's verdict where it differs from the primary's):", "",
               claims.readings_markdown()]
        md += [discussion]
    curves = pd.concat([a["curves"] for a in aggs.values()], ignore_index=True)
    io.write_table(out / "curves.parquet", io.frame_to_table(curves))
    ctx.written.append(out / "curves.parquet")
    for name, title, images, summ in sections:
        r0 = summ.iloc[0] if len(summ) else None
        md += [f"## {title}", ""]
        if r0 is not None:
            md += [f"Body `{r0['body']}`, {int(r0['epochs'])} epochs, "
                   f"{int(summ['n_trials'].max())} trials per condition.", ""]
        if name not in declared:  # one's own experiment: what made it
            md += ["Settings of each condition that differ from the defaults:", "",
                   settings.markdown(aggs[name])]
        md += [f"![{name}]({img})" for img in images] + ["", summary_markdown(summ)]
    for title, paths in extra:
        md += [f"## {title}", "", f"![{paths[0].stem}]({paths[0].name})", ""]
    convention_table = conventions.table(  # the paper's figures: reporting conventions
        aggs, conventions.read_trials(cfg.paths.aggregate, aggs), cfg.aggregate.fail_factor,
        OmegaConf.to_container(cfg.report.postures))
    if len(convention_table):
        ctx.text("conventions.csv", convention_table.to_csv(index=False, float_format="%.6g"))
        md += [conventions.markdown(convention_table)]
    return md


def _recommended(ctx: Context) -> tuple[pd.DataFrame, pd.DataFrame]:
    """(the readings study's cells, the recommended readings) for the second headline."""
    from . import readings

    read = {k: a for k, a in ctx.of("readings").items() if declares_claims(a)}
    cards = readings.intervals(read) if read else pd.DataFrame()
    return cards, readings.recommended()


def _write_measures(ctx: Context, measured: list, counted: list) -> None:
    """measures.parquet: every per-trial measure of the figures, the readings study, the
    baselines and the choices."""
    from . import measures_table, readings

    frames = [measures_table.frame([m for m in measured if m.figure == f], "figures",
                                   counted=f in counted)
              for f in dict.fromkeys(m.figure for m in measured)]
    read = {k: a for k, a in ctx.of("readings").items() if declares_claims(a)}
    recs = set(zip(*readings.recommended()[["figure", "reading"]].to_numpy().T))
    frames += [measures_table.frame(ms, "readings", reading=label,
                                    recommended=(fig, label) in recs)
               for (fig, label), ms in readings.readings_measures(read).items()]
    frames += measures_table.study_frames(ctx.of("baselines"), ctx.of("choices"))
    ctx.written.append(measures_table.write(ctx.out / measures_table.NAME, frames,
                                            ctx.cfg.report.scale))


FINDINGS = Path(__file__).parent / "findings.md"
FINDINGS_NUMBERS = Path(__file__).parent / "findings_numbers.csv"
TOLERANCE = 1e-6  # relative: the discussion holds for numbers this close to its run's


FINDINGS_COLUMNS = ["final_abs_error_mean", "final_rel_error_mean", "peak_abs_error_growth"]


def findings_numbers(summary: pd.DataFrame, claim_rows: list[dict]) -> pd.DataFrame:
    """What the discussion was written against: every final and peak error, and every verdict."""
    rows = [dict(what=f"{r.figure} {r.condition} {c}", value=float(getattr(r, c)), verdict="")
            for r in summary.itertuples() for c in FINDINGS_COLUMNS]
    rows += [dict(what=f"{r['figure']} {r['claim']}", value=float("nan"), verdict=r["verdict"])
             for r in claim_rows]
    return pd.DataFrame(rows)


def findings(summary: pd.DataFrame, claim_rows: list[dict]) -> str:
    """pipeline/studies/findings.md, hand-written about one run, if these are that run's numbers (every
    verdict the same, every number within TOLERANCE); else a note that it is left out."""
    now = findings_numbers(summary, claim_rows)
    if FINDINGS_NUMBERS.exists():
        ref = pd.read_csv(FINDINGS_NUMBERS, keep_default_na=False,
                          dtype={"what": str, "verdict": str}, converters={"value": float})
        if (len(ref) == len(now) and (ref["what"] == now["what"]).all()
                and (ref["verdict"] == now["verdict"]).all()
                and np.allclose(now["value"], ref["value"], rtol=TOLERANCE, atol=0,
                                equal_nan=True)):
            return FINDINGS.read_text()
    return ("## Discussion\n\n`pipeline/studies/findings.md` discusses the committed full-scale run; "
            "these numbers come from another run, so it is left out.\n")


def stamp_findings(summary: pd.DataFrame, claim_rows: list[dict]) -> None:
    """Record the numbers findings.md was written against (after rereading it against them)."""
    io.write_text(FINDINGS_NUMBERS, findings_numbers(summary, claim_rows)
                  .to_csv(index=False, float_format="%.17g", na_rep="nan"))


