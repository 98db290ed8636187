"""Stage 3, report: figures and tables from the aggregated data, tied together by report.md.

    python -m pipeline.report              # everything under paths.aggregate -> paths.report

Writes under paths.report (all bytes reproducible, no timestamps, only relative paths):
    <figure>_<condition>.gif   the body growing and reaching, frame by frame (report.animate)
    <figure>_curves.png/.pdf   (a) absolute and (b) relative error against epochs (Fig. 4, 5, 7)
    fig2_stages.png/.pdf       the inverse estimate of arm2 in joint space at successive stages
    fig3_postures.png/.pdf     target grid vs reached grid with postures, 5-DOF arm (Fig. 3)
    fig6_postures.png/.pdf     the same for the iCub (Fig. 6)
    models/<figure>.json       every condition's trained models (pipeline.models.load reads them)
    summary.csv, summary.md    per condition: final errors (held out: also in % of the body's
                               reach), peak during growth, failures, paper
    scorecard.png, scorecard.csv  each claim of the paper on each figure: the verdict of its 95 %
                               interval over trials (pipeline/studies/scorecard.py)
    claims.csv                 each claim of the paper, what was measured, and the verdict on the
                               mean (the pre-set criteria)
    readings.csv, readings_scorecard.csv, readings_matrix.csv, readings_summary.csv,
    readings_curves.png        the readings x claims study (and each reading's final errors)
    explanations.csv           the decisive experiments explain_*, read from their aggregates
    calibration.csv            the scorecard's intervals against a replicate set (replicate_*)
    choices.csv, choices.md    the open choices (experiments choices_*): each variant's effect
    conventions.csv            the reporting conventions: each alternative's effect, measured
    values.csv                 the named values the pages quote (named by the sections where
                               computed; python -m pipeline.tools.render writes them into pages)
    curves.parquet             the aggregated learning curves of every figure, in one table
    report.md                  the above, and the list of every file this stage writes
    report.html                report.md rendered (pipeline/html_report.py; not in its list),
                               and paths.out/index.html, every report under paths.out
The paper's claims are checked only on the experiments that declare them (`paper.claims: true`
in conf/experiment/*.yaml); any other figure is reported by its curves, summary and postures, under
a title that names it. It reads only the aggregate stage's output, never the cache, and runs no
trial. It writes into paths.report; only
`report.publish=true` (make reproduce, make studies) writes the committed report, paths.published, and only
when every paper experiment is aggregated at its full scale.
"""
from __future__ import annotations

import hashlib
import json
import logging
from pathlib import Path

import hydra
import pyarrow as pa
from omegaconf import DictConfig, OmegaConf

from . import cli, html_report, io
from .aggregate import named_figures
from .config import CONFIG_PATH, ConfigError, check_stamp
from .studies import sections, values
from .studies.sections import declares_claims

log = logging.getLogger("pipeline.report")


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


# the columns of an aggregate's curves.parquet the report reads (pipeline.aggregate_stats.curve_stats)
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
    return named_figures(cfg, explicit, aggregated(folder), folder, "aggregated")


def inputs_digest(cfg: DictConfig, inputs: dict) -> str:
    """What a report is made of: each figure's aggregate digest (`inputs`: figure -> the digest
    in its manifest), the report's settings (resolved: the paper's experiments as their files
    declare them), the failure factor, whether it publishes, and the code that draws it (studies
    included, with the discussion and its numbers, and the register of criteria the verdicts come
    from). The same digest, the same files: nothing to redo."""
    here = Path(__file__).parent
    files = [here / "report.py", here / "io.py",
             *sorted(p for p in (here / "studies").iterdir()
                     if p.suffix in (".py", ".md", ".csv", ".yaml"))]
    code = hashlib.sha256()
    for f in files:
        code.update(f.name.encode() + b"\0" + f.read_bytes() + b"\0")
    body = dict(figures=inputs, code=code.hexdigest(),
                report=OmegaConf.to_container(cfg.report, resolve=True),
                fail_factor=cfg.aggregate.fail_factor)
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


def report(cfg: DictConfig, explicit: bool = False) -> list[Path]:
    """Write every report file, unless the report is already made of the same inputs; return
    the paths written. explicit: the command line named a figure (figure= / experiment=); its
    report goes to paths.report/<figure>/, so that it replaces only that figure's earlier one."""
    check_stamp(cfg)  # report.stamp_findings: the publishing run only, before anything is written
    names, folder = selected(cfg, explicit), Path(cfg.paths.aggregate)
    names = names if names is not None else aggregated(folder)
    if not names:
        raise FileNotFoundError(f"nothing aggregated under {cfg.paths.aggregate}: "
                                "run pipeline.simulate and pipeline.aggregate first")
    out = Path(cfg.paths.published if cfg.report.publish else cfg.paths.report)
    if explicit and not cfg.report.publish:  # one figure's report beside any other's
        out = out / io.safe_name("figure", names[0])
    digest = inputs_digest(cfg, {n: io.read_json(io.set_of(folder / io.safe_name("figure", n))
                                                 / "manifest.json").get("inputs") for n in names})
    if up_to_date(out, digest) and not cfg.report.stamp_findings:
        log.info("report: up to date (the same aggregates, settings and code) -> %s", out)
        if not (out / "report.html").exists():  # a report made before report.html was
            return [html_report.write_html(out / "report.md")]
        return []
    log.info("report: %d figure(s) into %s, each study's section in turn", len(names), out)
    aggs = load_aggregates(folder, names)
    if cfg.report.publish:
        check_published_scale(cfg, aggs)
    before = set(listed_files(out / "report.md")) if (out / "report.md").exists() else set()
    _record_of(out).unlink(missing_ok=True)
    with io.new_dir(out) as tmp:  # the folder is replaced as one set: no file of an older report
        written = [out / p.relative_to(tmp) for p in write_report(cfg, aggs, tmp)]
        kept = keep_figure_reports(out, tmp)  # ... but every figure's own report beside it stays
    io.write_json(_record_of(out), dict(inputs=digest))  # last: the files are all there
    html_report.write_index(Path(cfg.paths.out))  # outputs/index.html: every report under it
    log.info("report: %d files -> %s%s", len(written), out,
             f" (the figure reports beside it kept: {', '.join(kept)})" if kept else "")
    lost = sorted(before - {p.relative_to(out).as_posix() for p in written})
    if lost:  # a narrower run replaced a wider report: say what went, never silently
        log.warning("report: %d files of the earlier report in %s are not in this one (%s%s); "
                    "a run of the experiments that made them brings them back (make studies: "
                    "the studies beyond the paper)", len(lost), out, ", ".join(lost[:4]),
                    ", ..." if len(lost) > 4 else "")
    return written


def keep_figure_reports(out: Path, tmp: Path) -> list[str]:
    """Carry every figure's own report (`report figure=NAME`: a folder of `out` with its
    report.md, and its input record `.NAME.inputs.json`) that the new report in `tmp` does not
    write itself from `out` into `tmp`, as hard links (never a copy's bytes, never through a
    link): a report of every figure, whatever its settings, never deletes one figure's report.
    Returns their names."""
    import os
    import shutil

    kept = []
    if not out.is_dir() or out.is_symlink():
        return kept
    for sub in sorted(out.iterdir()):
        if (sub.name.startswith(".") or sub.is_symlink() or not sub.is_dir()
                or not (sub / "report.md").is_file() or (tmp / sub.name).exists()):
            continue
        shutil.copytree(sub, tmp / sub.name, symlinks=True, copy_function=os.link)
        record = _record_of(sub)
        if record.is_file() and not record.is_symlink():
            os.link(record, _record_of(tmp / sub.name))
        kept.append(sub.name)
    return kept


def write_report(cfg: DictConfig, aggs: dict, out: Path) -> list[Path]:
    """Write every report file of `aggs` into `out`; return their paths: each experiment's
    study section (pipeline/studies/sections.py) in its place, then the list of files."""
    # the studies (matplotlib, scipy.stats) are imported only when there is something to draw
    from .studies import figures

    ctx = sections.Context(cfg, out, report_title(cfg, aggs), sections.group(aggs))
    paper = any(declares_claims(a) for a in aggs.values())
    md = [f"# {ctx.title}", "",
          "Generated by `python -m pipeline.report` from `pipeline.aggregate`'s tables"
          + ("; `make reproduce` (the paper) and `make studies` (everything) regenerate the committed report" if paper else "")
          + ". Errors: mean over trials (± standard "
          "deviation); curves: mean with the inter-quartile band. A trial *failed to bootstrap* "
          f"when its final relative error exceeds {cfg.aggregate.fail_factor:g} times the median "
          "of its condition.", ""]
    from .progress import Steps

    step = Steps("report", len(ctx.groups))  # a line per study's section: minutes, not silence
    with figures.plt.rc_context(figures.RC):
        md += sections.run(ctx, step)
    # the values the sections named as they computed them, and the coverage table the scorecard
    # reads (values.csv), and the discussion rendered with them (the only part of report.md that
    # references a name)
    from .studies import coverage

    ctx.value("coverage.table", coverage.markdown(coverage.read_table()))
    vals = dict(sorted(ctx.values.items()))
    ctx.text(values.FILE, values.to_csv(vals))
    md = [values.rendered_part(part, vals) for part in md]
    files = sorted(p.relative_to(out).as_posix() for p in ctx.written) + ["report.md"]
    md += ["## Files", "", "Every file of this report (all regenerated by `python -m pipeline.report`):",
           ""] + [f"- `{f}`" for f in files]
    io.write_text(out / "report.md", "\n".join(md) + "\n")
    # report.html: report.md rendered (pipeline/html_report.py), beside it and not in its list
    return ctx.written + [out / "report.md", html_report.write_html(out / "report.md")]


def listed_files(report_md: Path) -> list[str]:
    """The files report.md lists in its 'Files' section (used by the tests and by CI checks)."""
    text = Path(report_md).read_text().split("## Files", 1)[-1]
    return [line.strip()[3:-1] for line in text.splitlines() if line.startswith("- `")]


def run(cfg: DictConfig) -> int:
    from .aggregate import names_a_figure

    report(cfg, names_a_figure(cli.hydra_run()[0]))
    return 0


@hydra.main(config_path=CONFIG_PATH, config_name="config", version_base="1.3")
def main(cfg: DictConfig) -> None:
    cli.finish(run, cfg)


if __name__ == "__main__":
    cli.main(main)
