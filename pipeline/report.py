"""Stage 3, report: figures and tables from the aggregated data, tied together by report.md.

    python -m pipeline.report              # everything under paths.aggregate -> paths.report

From the aggregates only: each experiment's study section (studies/sections.py), report.md
listing every file (reproducible bytes, relative paths) and report.html. Only report.publish=true
writes the committed report (paths.published), with every paper experiment at full scale.
"""
from __future__ import annotations

import hashlib
import logging
import os
import shutil
from pathlib import Path

import hydra
import pyarrow as pa
from omegaconf import DictConfig, OmegaConf

from . import cli, html_report, io
from .aggregate import named_figures, names_a_figure
from .config import CONFIG_PATH, ConfigError, check_stamp
from .studies import sections, values
from .studies.sections import declares_claims

log = logging.getLogger("pipeline.report")
# the columns of an aggregate's curves.parquet the report reads (aggregate_stats.curve_stats)
_CURVES = pa.schema([(c, pa.null()) for c in [
    *[c for c in io.LABEL_COLUMNS if c != "trial"], "epoch", "samples", "size", "n_trials",
    *[f"{e}_{s}" for e in ("abs_error", "rel_error") for s in ("mean", "std", "q25", "q75")]]])


def load_aggregates(folder: Path, names=None) -> dict:
    """figure -> dict(curves, summary, trials, models, inputs) of `names` (None: every one), each
    figure's from one set (pipeline.io.set_of) even while aggregate replaces it."""
    out, folder = {}, Path(folder)
    for name in sorted(names if names is not None else aggregated(folder)):
        try:
            out[name] = _load_set(folder / io.safe_name("figure", name))
        except FileNotFoundError:  # aggregate switched sets and removed the old one meanwhile
            out[name] = _load_set(folder / name)
    return out


def _load_set(link: Path) -> dict:
    d = io.set_of(link)
    out = dict(models=io.read_json(d / "models.json", need=("figure", "conditions")),
               curves=io.read_table(d / "curves.parquet", schema=_CURVES).to_pandas(),
               summary=io.read_table(d / "summary.parquet").to_pandas(),
               trials=io.read_table(d / "trials.parquet", schema=io.CURVE).to_pandas(),
               inputs=io.read_json(d / "manifest.json").get("inputs"))
    if "choice" not in out["summary"]:
        raise io.DamagedFile(f"{d / 'summary.parquet'}: not an aggregate summary (no choice)")
    return out


def aggregated(folder: Path) -> list[str]:
    folder = Path(folder)  # a name with a dot: a temporary one, never a figure
    return sorted(p.name for p in folder.iterdir() if not p.name.startswith(".")
                  and (p / "summary.parquet").exists()) if folder.exists() else []


def selected(cfg: DictConfig, explicit: bool) -> list[str] | None:
    """The figures the command line names (aggregate.named_figures), or None: every one."""
    folder = Path(cfg.paths.aggregate)
    return named_figures(cfg, explicit, aggregated(folder), folder, "aggregated")


def inputs_digest(cfg: DictConfig, inputs: dict) -> str:
    """What a report is made of: each figure's aggregate digest (`inputs`), the report's resolved
    settings, the failure factor and the code that draws it (with plan.py: the provenance's
    estimated CPU is its cost model). The same digest, the same files."""
    here, code = Path(__file__).parent, hashlib.sha256()
    kinds = (".py", ".md", ".csv", ".yaml")
    for f in [here / "report.py", here / "io.py", here / "plan.py",
              *sorted(p for p in (here / "studies").iterdir() if p.suffix in kinds)]:
        code.update(f.name.encode() + b"\0" + f.read_bytes() + b"\0")
    body = dict(figures=inputs, code=code.hexdigest(),
                report=OmegaConf.to_container(cfg.report, resolve=True),
                fail_factor=cfg.aggregate.fail_factor)
    return hashlib.sha256(io.dump_json(body).encode()).hexdigest()[:20]


def _record_of(out: Path) -> Path:
    """A report folder's input digest: beside it (the folder holds what its report.md lists)."""
    return out.parent / f".{out.name}.inputs.json"


def up_to_date(out: Path, digest: str) -> bool:
    try:
        return io.read_json(_record_of(out)).get("inputs") == digest and all(
            (out / f).exists() for f in listed_files(out / "report.md"))
    except (OSError, ValueError):
        return False


def scale_mismatches(aggs: dict, experiments) -> list[str]:
    """A line per experiment whose figure does not hold exactly its full-scale plan's trials."""
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
    """A ConfigError unless every report.paper_experiments is at full scale."""
    bad = scale_mismatches(aggs, cfg.report.paper_experiments)
    if bad:
        raise ConfigError(
            f"report.publish=true: {bad[0]}; the committed report is written only by make "
            "reproduce at the paper's scale")


def report_title(cfg: DictConfig, aggs: dict) -> str:
    """"Reproduction of ..." only when every figure declaring the paper's claims is at full scale;
    otherwise what it is: a reduced scale (report.scale), a custom one, one's own experiment."""
    names = ", ".join(aggs)
    if cfg.report.scale:
        return f"{cfg.report.scale.capitalize()} run (not the paper's scale): {names}"
    declared = [k for k, a in aggs.items() if declares_claims(a)]
    if not declared:
        return f"Experiment {names}"
    experiments = [e for e in cfg.report.paper_experiments if e in declared]
    if len(experiments) == len(declared) and not scale_mismatches(aggs, experiments):
        return "Reproduction of Rolf, Steil & Gienger (2010): Goal Babbling on growing bodies"
    return f"Paper experiments at a custom scale (not the paper's): {names}"


def report(cfg: DictConfig, explicit: bool = False) -> list[Path]:
    """The paths written, unless made of the same inputs; `explicit` (figure= or experiment=
    named): into paths.report/<figure>/, replacing only that figure's earlier report."""
    check_stamp(cfg)  # report.stamp_findings: the publishing run only, before anything is written
    folder = Path(cfg.paths.aggregate)
    names = selected(cfg, explicit) or aggregated(folder)
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
    """The names of the figures' own reports (`report figure=NAME`) in `out` that `tmp` lacks,
    hard-linked into it with their records: a report never deletes one figure's report."""
    kept = []
    for sub in sorted(out.iterdir()) if out.is_dir() and not out.is_symlink() else ():
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
    """Every report file of `aggs` written into `out`: each study's section, then the files."""
    # the studies (matplotlib, scipy.stats) are imported only when there is something to draw
    from .progress import Steps
    from .studies import coverage, figures

    ctx = sections.Context(cfg, out, report_title(cfg, aggs), sections.group(aggs))
    paper = any(declares_claims(a) for a in aggs.values())
    md = [f"# {ctx.title}", "",
          "Generated by `python -m pipeline.report` from `pipeline.aggregate`'s tables"
          + ("; `make reproduce` (the paper) and `make studies` (everything) regenerate the "
             "committed report" if paper else "")
          + ". Errors: mean over trials (± standard "
          "deviation); curves: mean with the inter-quartile band. A trial *failed to bootstrap* "
          f"when its final relative error exceeds {cfg.aggregate.fail_factor:g} times the median "
          "of its condition.", ""]
    step = Steps("report", len(ctx.groups))  # a line per study's section: minutes, not silence
    with figures.plt.rc_context(figures.RC):
        md += sections.run(ctx, step)
    # the values the sections named as they computed them, the coverage table the scorecard
    # reads (values.csv), and the discussion rendered with them (the only part that names one)
    ctx.value("coverage.table", coverage.markdown(coverage.read_table()))
    vals = dict(sorted(ctx.values.items()))
    ctx.text(values.FILE, values.to_csv(vals))
    md = [values.rendered_part(part, vals) for part in md]
    files = sorted(p.relative_to(out).as_posix() for p in ctx.written) + ["report.md"]
    md += ["## Files", "", "Every file of this report (all regenerated by `python -m "
           "pipeline.report`):", ""] + [f"- `{f}`" for f in files]
    io.write_text(out / "report.md", "\n".join(md) + "\n")
    # report.html: report.md rendered, beside it and not in its list
    return ctx.written + [out / "report.md", html_report.write_html(out / "report.md")]


def listed_files(report_md: Path) -> list[str]:
    """The files report.md lists in its 'Files' section."""
    text = Path(report_md).read_text().split("## Files", 1)[-1]
    return [line.strip()[3:-1] for line in text.splitlines() if line.startswith("- `")]


def run(cfg: DictConfig) -> int:
    report(cfg, names_a_figure(cli.hydra_run()[0]))
    return 0


@hydra.main(config_path=CONFIG_PATH, config_name="config", version_base="1.3")
def main(cfg: DictConfig) -> None:
    cli.finish(run, cfg)


if __name__ == "__main__":
    cli.main(main)
