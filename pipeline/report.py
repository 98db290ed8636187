"""Stage 3, report: figures and tables from the aggregated data, tied together by report.md.

    python -m pipeline.report              # everything under paths.aggregate -> paths.report

Writes under paths.report (all bytes reproducible, no timestamps, only relative paths):
    <figure>_curves.png/.pdf   (a) absolute and (b) relative error against epochs (Fig. 4, 5, 7)
    fig2_stages.png/.pdf       the inverse estimate of arm2 in joint space at successive stages
    fig3_postures.png/.pdf     target grid vs reached grid with postures, 5-DOF arm (Fig. 3)
    fig6_postures.png/.pdf     the same for the iCub (Fig. 6)
    summary.csv, summary.md    per condition: final errors, peak during growth, failures, paper
    scorecard.png, scorecard.csv  each claim of the paper on each figure: the verdict of its 95 %
                               interval over trials (pipeline/studies/scorecard.py)
    claims.csv                 each claim of the paper, what was measured, and the verdict on the
                               mean (the pre-set criteria)
    readings.csv, readings_scorecard.csv, readings_curves.png   the readings x claims study
    explanations.csv           the decisive experiments explain_*, read from their aggregates
    choices.csv, choices.md    the open choices (experiments choices_*): each variant's effect
    conventions.csv            the reporting conventions: each alternative's effect, measured
    curves.parquet             the aggregated learning curves of every figure, in one table
    report.md                  the above, and the list of every file this stage writes
The paper's claims are checked only on the experiments that declare them (`paper.claims: true`
in conf/experiment/*.yaml); any other figure is reported by its curves, summary and postures, under
a title that names it. It reads only the aggregate stage's output, never the cache, and runs no
trial. It writes into paths.report; only
`report.publish=true` (make reproduce) writes the committed report, paths.published, and only
when every paper experiment is aggregated at its full scale.
"""
from __future__ import annotations

import hashlib
import json
import logging
from pathlib import Path

import hydra
import numpy as np
import pandas as pd
import pyarrow as pa
from omegaconf import DictConfig, OmegaConf

from . import cli, io
from .config import ConfigError, check_stamp

log = logging.getLogger("pipeline.report")
MAX_PANELS = 4  # posture panels of a figure that report.postures does not name


def load_aggregates(folder: Path, names=None) -> dict:
    """figure -> dict(curves, summary, trials, models, inputs) for the aggregated figures `names`
    (None: every one), sorted by name (trials: every trial's curve, for the scorecard's
    intervals; inputs: the digest aggregate made it of). Each figure's set is resolved once
    (pipeline.io.set_of), so its files come from one set even while aggregate replaces it; a
    damaged file is an io.DamagedFile naming it."""
    out = {}
    folder = Path(folder)
    for name in sorted(names if names is not None else aggregated(folder)):
        try:
            out[name] = _load_set(folder / io.safe_name("figure", name))
        except FileNotFoundError:  # aggregate switched sets and removed the old one meanwhile
            out[name] = _load_set(folder / name)
    return out


# the columns of an aggregate's curves.parquet the report reads (pipeline.aggregate.curve_stats)
_CURVES = pa.schema([(c, pa.null()) for c in [
    *[c for c in io.LABEL_COLUMNS if c != "trial"], "epoch", "samples", "size", "n_trials",
    *[f"{e}_{s}" for e in ("abs_error", "rel_error") for s in ("mean", "std", "q25", "q75")]]])


def _load_set(link: Path) -> dict:
    """One figure's aggregate, every file from the one set `link` resolves to now."""
    d = io.set_of(link)
    models = io.read_json(d / "models.json", need=("figure", "conditions"))
    out = dict(curves=io.read_table(d / "curves.parquet", schema=_CURVES).to_pandas(),
               summary=io.read_table(d / "summary.parquet").to_pandas(),
               trials=io.read_table(d / "trials.parquet", schema=io.CURVE).to_pandas(),
               models=models, inputs=io.read_json(d / "manifest.json").get("inputs"))
    if "choice" not in out["summary"]:
        raise io.DamagedFile(f"{d / 'summary.parquet'}: not an aggregate summary (no choice)")
    return out


def aggregated(folder: Path) -> list[str]:
    folder = Path(folder)
    return sorted(p.name for p in folder.iterdir()  # a dot: a temporary name, never a figure
                  if not p.name.startswith(".") and (p / "summary.parquet").exists()) \
        if folder.exists() else []


def selected(cfg: DictConfig, explicit: bool) -> list[str] | None:
    """The figures to report: those of `experiments=[...]`, or the one figure= / experiment=
    names, or None (every aggregated figure). An unknown one is a FileNotFoundError (one line)."""
    folder = Path(cfg.paths.aggregate)
    known = aggregated(folder)
    if cfg.get("experiments"):
        wanted = list(cfg.experiments)  # an experiment's figure is its name (tested)
    elif explicit:
        wanted = [cfg.figure]
    else:
        return None
    missing = [f for f in wanted if f not in known]
    if missing:
        raise FileNotFoundError(f"figure={missing[0]}: not aggregated under {folder} "
                                f"(aggregated: {', '.join(known) or 'none'})")
    return wanted


def inputs_digest(cfg: DictConfig, inputs: dict) -> str:
    """What a report is made of: each figure's aggregate digest (`inputs`: figure -> the digest
    in its manifest), the report's settings, the
    failure factor, whether it publishes, and the code that draws it (studies included, with the
    discussion and its numbers). The same digest, the same files: nothing to redo."""
    here = Path(__file__).parent
    files = [here / "report.py", here / "io.py",
             *sorted(p for p in (here / "studies").iterdir() if p.suffix in (".py", ".md", ".csv"))]
    code = hashlib.sha256()
    for f in files:
        code.update(f.name.encode() + b"\0" + f.read_bytes() + b"\0")
    body = dict(figures=inputs, code=code.hexdigest(),
                report=OmegaConf.to_container(cfg.report), fail_factor=cfg.aggregate.fail_factor)
    return hashlib.sha256(io.dump_json(body).encode()).hexdigest()[:20]


def _record_of(out: Path) -> Path:
    """Where a report folder's input digest is kept: beside it, not in it (the folder holds
    exactly the files its report.md lists)."""
    return out.parent / f".{out.name}.inputs.json"


def up_to_date(out: Path, digest: str) -> bool:
    try:
        if io.read_json(_record_of(out)).get("inputs") != digest:
            return False
        return all((out / f).exists() for f in listed_files(out / "report.md"))
    except (OSError, ValueError):
        return False


def declares_claims(agg: dict) -> bool:
    """Whether the figure's experiment declares the paper's claims (paper.claims: true)."""
    return bool(agg["models"].get("paper", {}).get("claims", False))


def scale_mismatches(cfg: DictConfig, aggs: dict, experiments) -> list[str]:
    """For each of `experiments` whose figure is not aggregated with exactly the trials of its
    full-scale plan, one line saying so (an empty list: all at the paper's scale)."""
    from .config import compose
    from .plan import plan

    out = []
    for exp in experiments:
        want = {t["key"] for t in plan(compose([f"experiment={exp}", "profile=full"]))}
        fig = compose([f"experiment={exp}"]).figure
        have = {t["key"] for c in aggs.get(fig, {}).get("models", {}).get("conditions", {}).values()
                for t in c["trials"].values()}
        if want != have:
            out.append(f"{fig} holds {len(want & have)} of the {len(want)} trials of "
                       f"experiment={exp} at full scale (and {len(have - want)} others)")
    return out


def check_published_scale(cfg: DictConfig, aggs: dict) -> None:
    """report.publish=true: every experiment of report.paper_experiments must be aggregated with
    exactly the trials its full-scale plan lists; otherwise ConfigError (nothing is written)."""
    bad = scale_mismatches(cfg, aggs, cfg.report.paper_experiments)
    if bad:
        raise ConfigError(
            f"report.publish=true: {bad[0]}; the committed report is written only by make "
            "reproduce at the paper's scale")


def _mm(v) -> str:
    return "" if v is None or not np.isfinite(v) else f"{1000 * v:.1f}"


def _pm(mean, std) -> str:
    if not np.isfinite(mean):
        return ""
    return _mm(mean) + (f" ± {_mm(std)}" if np.isfinite(std) else "")


def summary_markdown(summary: pd.DataFrame) -> str:
    """The summary as a Markdown table, errors in mm (relative errors: mm per unit body size)."""
    head = ("| figure | condition | body | growth | T_G | trials | final abs. error [mm] "
            "| final rel. error [mm/size] | peak abs. error during growth [mm] (rise, epoch) "
            "| run failures | diverged | failed to bootstrap | paper: final abs. error [mm] |")
    lines = [head, "|" + "---|" * head.count(" | ") + "---|"]
    from .studies.claims import DIVERGED, diverged_conditions

    dead = set(diverged_conditions(summary))
    for _, r in summary.iterrows():
        peak = (f"{_mm(r['peak_abs_error_growth'])} (+{_mm(r['rise_abs_error_growth'])}, "
                f"epoch {r['peak_epoch_growth']})" if np.isfinite(r["peak_abs_error_growth"]) else "")
        gone = DIVERGED if r["condition"] in dead else ""  # no trial left a curve
        lines.append(
            f"| {r['figure']} | {r['condition']} | {r['body']} | {r['growth']} "
            f"| {r['growth_period'] if r['growth'] != 'none' else ''} | {r['n_trials']} "
            f"| {_pm(r['final_abs_error_mean'], r['final_abs_error_std']) or gone} "
            f"| {_pm(r['final_rel_error_mean'], r['final_rel_error_std']) or gone} | {peak or gone} "
            f"| {r['n_run_failures']} | {r['n_diverged']} | {r['n_bootstrap_failures']} "
            f"| {_mm(r['paper_final_abs_error'])} |")
    return "\n".join(lines) + "\n"


def report_title(cfg: DictConfig, aggs: dict) -> str:
    """A report is "Reproduction of ..." only when every figure that declares the paper's claims
    holds its experiment's full-scale trials; any other report is titled by its experiments and
    says what it is: a reduced scale (report.scale, set by a profile), a custom scale, or an
    experiment of one's own (no paper claims)."""
    names = ", ".join(aggs)
    if cfg.report.scale:
        return f"{cfg.report.scale.capitalize()} run (not the paper's scale): {names}"
    declared = [k for k, a in aggs.items() if declares_claims(a)]
    if not declared:
        return f"Experiment {names}"
    experiments = [e for e in cfg.report.paper_experiments if e in declared]
    if len(experiments) == len(declared) and not scale_mismatches(cfg, aggs, experiments):
        return "Reproduction of Rolf, Steil & Gienger (2010): Goal Babbling on growing bodies"
    return f"Paper experiments at a custom scale (not the paper's): {names}"


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


def report(cfg: DictConfig, explicit: bool = False) -> list[Path]:
    """Write every report file, unless the report is already made of the same inputs; return
    the paths written. explicit: the command line named a figure (figure= / experiment=)."""
    check_stamp(cfg)  # report.stamp_findings: the publishing run only, before anything is written
    names, folder = selected(cfg, explicit), Path(cfg.paths.aggregate)
    names = names if names is not None else aggregated(folder)
    if not names:
        raise FileNotFoundError(f"nothing aggregated under {cfg.paths.aggregate}: "
                                "run pipeline.simulate and pipeline.aggregate first")
    out = Path(cfg.paths.published if cfg.report.publish else cfg.paths.report)
    digest = inputs_digest(cfg, {n: io.read_json(io.set_of(folder / io.safe_name("figure", n))
                                                 / "manifest.json").get("inputs") for n in names})
    if up_to_date(out, digest) and not cfg.report.stamp_findings:
        log.info("report: up to date (the same aggregates, settings and code) -> %s", out)
        return []
    aggs = load_aggregates(folder, names)
    if cfg.report.publish:
        check_published_scale(cfg, aggs)
    _record_of(out).unlink(missing_ok=True)
    with io.new_dir(out) as tmp:  # the folder is replaced as one set: no file of an older report
        written = [out / p.relative_to(tmp) for p in write_report(cfg, aggs, tmp)]
    io.write_json(_record_of(out), dict(inputs=digest))  # last: the files are all there
    log.info("report: %d files -> %s", len(written), out)
    return written


def write_report(cfg: DictConfig, aggs: dict, out: Path) -> list[Path]:
    """Write every report file of `aggs` into `out`; return their paths."""
    # the studies (matplotlib, scipy.stats) are imported only when there is something to draw
    from .studies import (baselines, choices, claims, conventions, explain, figures, readings,
                          scorecard)

    title = report_title(cfg, aggs)
    studies = {k: a for k, a in aggs.items() if k in readings.STUDIES}
    rivals = {k: a for k, a in aggs.items() if k in baselines.STUDIES}
    explained = {k: a for k, a in aggs.items() if k in explain.STUDIES}
    chosen = {k: a for k, a in aggs.items() if k not in studies and k not in rivals
              and k not in explained and a["summary"]["choice"].astype(bool).any()}
    aggs = {k: a for k, a in aggs.items()
            if k not in chosen and k not in studies and k not in rivals and k not in explained}
    declared = {k: a for k, a in aggs.items() if declares_claims(a)}
    rc, dpi = figures.RC, cfg.report.dpi
    written, sections = [], []
    js = cfg.report.joint_space_figure  # Fig. 2: stages in a joint space over one target axis
    stages = _stages_figure(aggs[js]) if js in aggs else None
    if stages is not None and figures.final_body(stages[0])[0].n != 1:
        stages = None
    with figures.plt.rc_context(rc):
        for name, agg in aggs.items():
            fig = figures.learning_curves(
                agg["curves"], agg["summary"], _title(name, agg), log_y=cfg.report.log_error_axis,
                paper_abs=agg["models"].get("paper", {}).get("final_abs_error"))
            paths = figures.save(fig, out / f"{name}_curves", dpi)
            written += paths
            sections.append((name, _title(name, agg), [paths[0].name], agg["summary"]))

        extra = []
        if stages is not None:
            fig = figures.joint_space_stages(
                *stages, "Fig. 2: inverse estimate of the 2-DOF arm in joint space "
                "(contours: equal hand height)")
            extra.append(("Fig. 2: stages of learning (joint space)",
                          figures.save(fig, out / f"{js}_stages", dpi)))
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
                              figures.save(fig, out / f"{name}_postures", dpi)))
    for _, paths in extra:
        written += paths

    summary = (pd.concat([a["summary"] for a in aggs.values()], ignore_index=True) if aggs
               else pd.DataFrame(columns=["figure", "condition"] + FINDINGS_COLUMNS))
    table_md = summary_markdown(summary)
    io.write_text(out / "summary.csv", summary.to_csv(index=False, float_format="%.6g"))
    io.write_text(out / "summary.md", table_md)
    written += [out / "summary.csv", out / "summary.md"]

    claim_rows = []
    for name, agg in declared.items():
        if (agg["summary"]["growth"] != "none").any():
            claim_rows += claims.growth_claims(name, agg["curves"], agg["summary"])
    judge_stages = stages is not None and js in declared
    if judge_stages:
        claim_rows += claims.stage_claims(js, *stages)
    card_md = ""
    if claim_rows:
        io.write_text(out / "claims.csv", pd.DataFrame(claim_rows).to_csv(index=False))
        written.append(out / "claims.csv")
        measures = scorecard.results(declared, dict(
            figure=js, spec=stages[0], trials=_trial_stages(aggs[js])) if judge_stages else None)
        cards = scorecard.cells(measures)
        io.write_text(out / "scorecard.csv", pd.DataFrame(measures).to_csv(
            index=False, float_format="%.6g"))
        with figures.plt.rc_context(rc):
            written += [out / "scorecard.csv"] + figures.save(scorecard.figure(
                cards, title.split(":")[0] + ": the paper's claims, 95 % intervals over trials"),
                out / "scorecard", dpi)
        card_md = scorecard.markdown(cards, measures)
    if aggs:
        curves = pd.concat([a["curves"] for a in aggs.values()], ignore_index=True)
        io.write_table(out / "curves.parquet", io.frame_to_table(curves))
        written.append(out / "curves.parquet")
    choice_table = choices.table(chosen)
    if len(choice_table):
        io.write_text(out / "choices.csv", choice_table.to_csv(index=False, float_format="%.6g"))
        io.write_text(out / "choices.md", choices.markdown(choice_table, chosen))
        written += [out / "choices.csv", out / "choices.md"]

    md = [f"# {title}", "",
          "Generated by `python -m pipeline.report` from `pipeline.aggregate`'s tables; "
          "`make reproduce` regenerates the committed report. Errors: mean over trials (± standard "
          "deviation); curves: mean with the inter-quartile band. A trial *failed to bootstrap* "
          f"when its final relative error exceeds {cfg.aggregate.fail_factor:g} times the median "
          "of its condition.", ""]
    if claim_rows:
        md += ["## Scorecard: the paper's claims, with their uncertainty", "",
               "![scorecard](scorecard.png)", "", card_md,
               "Each cell: the verdict of the measure that decides it, its value on the mean over "
               "trials and its 95 % interval (`scorecard.csv` holds every measure); "
               "pipeline/studies/scorecard.py says how.", ""]
        md += ["## The paper's claims, measured on the mean (the pre-set criteria)", "",
               claims.CRITERIA, "", claims.markdown(claim_rows)]
    if cfg.report.stamp_findings:
        stamp_findings(summary, claim_rows)
    if cfg.report.explain:
        rows = explain.rows({**aggs, **explained})
        if rows:
            io.write_text(out / "explanations.csv", pd.DataFrame(rows).to_csv(index=False))
            written.append(out / "explanations.csv")
            md += ["## Decisive experiments behind the explanations", "",
                   "Read from the aggregated experiments explain_* (conf/experiment/, "
                   "pipeline/studies/explain.py): what a cubic can reach when fitted directly "
                   "(the capacity bound), the 2-DOF arm learned with its extremes away from the "
                   "stretched arm, and the iCub continued at a smaller learning rate.", "",
                   "| figure | experiment | measured |", "|---|---|---|"]
            md += [f"| {r['figure']} | {r['experiment']} | {r['measured']} |" for r in rows]
            md += [""]
    md += [findings(summary, claim_rows)]  # the discussion of the committed run, if it is this
    for name, title, images, summ in sections:
        r0 = summ.iloc[0] if len(summ) else None
        md += [f"## {title}", ""]
        if r0 is not None:
            md += [f"Body `{r0['body']}`, {int(r0['epochs'])} epochs, "
                   f"{int(summ['n_trials'].max())} trials per condition.", ""]
        md += [f"![{name}]({img})" for img in images] + ["", summary_markdown(summ)]
    for title, paths in extra:
        md += [f"## {title}", "", f"![{paths[0].stem}]({paths[0].name})", ""]
    def study(name, table, fig):
        """A study's table (CSV) and figure; returns the figure's PNG name."""
        io.write_text(out / f"{name}.csv", table.to_csv(index=False, float_format="%.6g"))
        with figures.plt.rc_context(rc):
            paths = figures.save(fig, out / f"{name}_curves", dpi)
        written.extend([out / f"{name}.csv"] + paths)
        return paths[0].name

    read = {k: a for k, a in studies.items() if declares_claims(a)}
    reading_table = readings.table(read)
    if len(reading_table):
        reading_cards = readings.intervals(read)
        io.write_text(out / "readings_scorecard.csv", reading_cards.to_csv(
            index=False, float_format="%.6g"))
        written.append(out / "readings_scorecard.csv")
        png = study("readings", reading_table, readings.figure(
            studies, "Readings of the paper: absolute error of every condition (mean over "
            "trials)"))
        md += ["## Every reading of the paper against every claim", "",
               "Each row is a reading of the text (conf/experiment/readings_*.yaml, "
               "pipeline/studies/readings.py); each column a claim, checked as above.", "",
               f"![readings]({png})", "", readings.intervals_markdown(reading_cards),
               "The same, each verdict on the mean over trials (the pre-set criteria):", "",
               readings.markdown(reading_table)]
    rival_table = baselines.table(rivals)
    if len(rival_table):
        rival_claims = baselines.claims(rival_table)
        png = study("baselines", rival_table, baselines.figure(
            rivals, "Goal Babbling and its alternatives: error against reaching movements"))
        md += ["## Beyond the paper: Goal Babbling against its alternatives under growth", "",
               "The learners (gbmodel/learners/) at budgets of reaching movements, on "
               "the 5-DOF arm and the iCub, without growth, with the paper's linear growth and "
               "with an infant-like schedule (conf/experiment/baselines_*.yaml, "
               "pipeline/studies/baselines.py, docs/baselines.md). Errors at the end of each "
               "budget; the figure draws the held-out error; the largest jump is the "
               "final inverse's largest joint-space step between neighbouring points on lines "
               "through the target box (branch switching, lookup).", "",
               f"![baselines]({png})", "", baselines.markdown(rival_table, rival_claims)]
    convention_table = conventions.table(  # the paper's figures: reporting conventions
        aggs, conventions.read_trials(cfg.paths.aggregate, aggs), cfg.aggregate.fail_factor,
        OmegaConf.to_container(cfg.report.postures))
    if len(convention_table):
        io.write_text(out / "conventions.csv",
                      convention_table.to_csv(index=False, float_format="%.6g"))
        written.append(out / "conventions.csv")
        md += [conventions.markdown(convention_table)]
    if len(choice_table):
        text = (out / "choices.md").read_text().split("\n", 1)[1]
        md += ["## Choices the paper leaves open: measured effect of the alternatives", text]
    files = sorted(p.relative_to(out).as_posix() for p in written) + ["report.md"]
    md += ["## Files", "", "Every file of this report (all regenerated by `python -m pipeline.report`):",
           ""] + [f"- `{f}`" for f in files]
    io.write_text(out / "report.md", "\n".join(md) + "\n")
    written.append(out / "report.md")
    return written


FINDINGS = Path(__file__).parent / "studies" / "findings.md"
FINDINGS_NUMBERS = Path(__file__).parent / "studies" / "findings_numbers.csv"
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
    io.allow(FINDINGS_NUMBERS)  # a committed file of the source tree, wherever paths.root is
    io.write_text(FINDINGS_NUMBERS, findings_numbers(summary, claim_rows)
                  .to_csv(index=False, float_format="%.17g", na_rep="nan"))


def listed_files(report_md: Path) -> list[str]:
    """The files report.md lists in its 'Files' section (used by the tests and by CI checks)."""
    text = Path(report_md).read_text().split("## Files", 1)[-1]
    return [line.strip()[3:-1] for line in text.splitlines() if line.startswith("- `")]


def run(cfg: DictConfig) -> int:
    from .aggregate import names_a_figure

    report(cfg, names_a_figure(cli.hydra_run()[0]))
    return 0


@hydra.main(config_path="../conf", config_name="config", version_base="1.3")
def main(cfg: DictConfig) -> None:
    cli.finish(run, cfg)


if __name__ == "__main__":
    cli.main(main)
