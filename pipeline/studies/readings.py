"""The readings x claims study: the paper's claims judged on each reading of its text
(conf/experiment/readings_*.yaml: each figure's conditions under every reading that can change a
verdict), as a table per figure, the readings x figures matrix (README.md's readings.table) and
a figure; and the reading recommended per figure (the register's `recommended`, written from the
findings, checked against the verdicts by `contradictions`).
"""
from __future__ import annotations

from pathlib import Path

import pandas as pd

from . import claims, figures, scorecard
from .choices import escape
from .sections import Context, declares_claims, prose, reads, register
from .quoted import QUOTED_RATIOS, QUOTED_RISE
from .quoted import READINGS_SUMMARY as QUOTED
from .values import printed

SYMBOLS = {scorecard.REPRODUCED: "✓", scorecard.NOT: "✗", scorecard.INCONCLUSIVE: "?",
           claims.DIVERGED: "÷"}
SHORT = {"final": "final", "rise": "rise", "blend": "blend", "after": "after",
         "bootstrap": "boot"}  # column heads of the matrix (claims.CLAIMS' words in its legend)
FIGURE_CHOICES = ("default", "learning rate", "solver")  # the readings readings_curves shows


def split(agg: dict, frame: str = "curves") -> dict:
    """reading -> (agg[frame], summary), the conditions named as in the paper's figure."""
    def rename(f, names):
        f = f[f["condition"].isin(names)].copy()
        f["condition"] = f["condition"].map({n: n.split(" | ", 1)[-1] for n in names})
        return f
    s = agg["summary"]
    return {label: tuple(rename(f, s[s["variant"] == label]["condition"].tolist())
                         for f in (agg[frame], s)) for label in s["variant"].drop_duplicates()}


def readings_measures(read: dict) -> dict:
    """(figure, reading) -> the measures of the readings study (read: its aggregates)."""
    return {(fig, label): claims.measures(fig, trials, summary)
            for study, fig in reads("readings").items()
            if study in read and "trials" in read[study]
            for label, (trials, summary) in split(read[study], "trials").items()}


def intervals(aggs: dict, scale: str = "", measured: dict | None = None) -> pd.DataFrame:
    """The scorecard's cells per (figure, reading, claim) (scale: the run's reduced scale;
    measured: readings_measures(aggs), where the caller has it)."""
    rows = []
    for (_, label), ms in (readings_measures(aggs) if measured is None else measured).items():
        cards = scorecard.cells(scorecard.no_verdicts(scorecard.judged(ms), scale))
        rows += [dict(c, reading=label) for c in cards.to_dict("records")]
    return pd.DataFrame(rows)


def finals(aggs: dict) -> pd.DataFrame:
    """readings_summary.csv: per figure, reading and condition, trials and final errors."""
    rows = []
    for study, fig in reads("readings").items():
        if study not in aggs:
            continue
        for label, (_, sv) in split(aggs[study]).items():
            rows += [dict(figure=fig, reading=label, condition=r.condition, trials=r.n_trials,
                          final_abs_error_mean=r.final_abs_error_mean,
                          final_rel_error_mean=r.final_rel_error_mean)
                     for r in sv.itertuples()]
    return pd.DataFrame(rows)


def intervals_markdown(t: pd.DataFrame) -> str:
    """Per figure: rows = readings, columns = claims, cells = verdict, value and interval."""
    lines = []
    for fig, tf in t.groupby("figure", sort=False):
        cl = [c.id for c in claims.CLAIMS if c.id in set(tf["claim"])]
        lines += [f"### {fig}: verdicts with their 95 % intervals "
                  f"({int(tf[tf['claim'] != 'bootstrap']['trials'].max())} trials per condition "
                  "and reading)", "",
                  "| reading | " + " | ".join(escape(scorecard.TITLES[c]) for c in cl) + " |",
                  "|---|" + "---|" * len(cl)]
        for reading, tr in tf.groupby("reading", sort=False):
            cells = {r["claim"]: escape(scorecard.cell_text(r, "<br>"))
                     for r in tr.to_dict("records")}
            lines.append(f"| {escape(reading)} | " + " | ".join(cells.get(c, "")
                                                                for c in cl) + " |")
        lines.append("")
    return "\n".join(lines)


def table(t: pd.DataFrame) -> pd.DataFrame:
    """readings.csv: one row per (figure, reading, claim), the cells `t` of `intervals`."""
    if not len(t):
        return pd.DataFrame()
    return pd.DataFrame(dict(
        figure=t["figure"], reading=t["reading"], claim=t["claim"],
        diagnostic=t["diagnostic"], verdict=t["verdict"],
        measured=[scorecard.cell_text(r).replace("**", "") for r in t.to_dict("records")],
        trials=t["trials"]))


def matrix(cards: pd.DataFrame) -> pd.DataFrame:
    """readings_matrix.csv: per reading and figure its trials per condition ("n") and the verdict
    on each of the paper's claims, as text ("" where a reading did not run on a figure)."""
    paper = cards[~cards["diagnostic"].astype(bool)]
    figs = list(dict.fromkeys(paper["figure"]))
    ids = {f: [c.id for c in claims.CLAIMS if c.id in set(paper[paper["figure"] == f]["claim"])]
           for f in figs}
    rows = []
    for reading in dict.fromkeys(paper["reading"]):
        row = {"reading": reading}
        for f in figs:
            tr = paper[(paper["figure"] == f) & (paper["reading"] == reading)]
            n = tr[tr["claim"] != "bootstrap"]["trials"]
            row[f"{f} n"] = str(int(n.max())) if len(n) else ""
            verdicts = dict(zip(tr["claim"], tr["verdict"]))
            row.update({f"{f} {c}": verdicts.get(c, "") for c in ids[f]})
        rows.append(row)
    return pd.DataFrame(rows, dtype=str)


def read_matrix(path) -> pd.DataFrame:
    return pd.read_csv(path, dtype=str, keep_default_na=False)


def matrix_markdown(m: pd.DataFrame) -> str:
    """The matrix as a compact Markdown table (a symbol per verdict) with its legend."""
    cols = [c for c in m.columns if c != "reading"]

    def head(c):
        fig, what = c.split(" ", 1)
        return f"{fig} {SHORT.get(what, what)}"
    lines = ["| reading | " + " | ".join(head(c) for c in cols) + " |",
             "|---|" + ":-:|" * len(cols)]
    for r in m.to_dict("records"):
        lines.append(f"| {escape(r['reading'])} | " + " | ".join(
            r[c] if c.endswith(" n") else SYMBOLS.get(r[c], r[c]) for c in cols) + " |")
    used = [k for k in SHORT if any(c.endswith(" " + k) for c in cols)]
    lines += ["", " ".join(f"{s} {v}," for v, s in SYMBOLS.items()).rstrip(",")
              + "; n: trials per condition (blank: not run); columns: the paper's claims: "
              + "; ".join(f"{SHORT[k]}: {claims.BY_ID[k].words}" for k in used) + "."]
    return "\n".join(lines) + "\n"


def recommended(path: Path = claims.REGISTER) -> list[dict]:
    """The register's `recommended` (figure, reading, reproduces, why); a ValueError names a
    figure this study does not read, a claim not the paper's or a figure named twice."""
    recs = claims.read_register(path).get("recommended", [])
    for r in recs:
        if r["figure"] not in reads("readings").values():
            raise ValueError(f"{path}: no readings figure {r['figure']!r}")
        for c in r["reproduces"]:
            if c not in claims.BY_ID or claims.BY_ID[c].diagnostic:
                raise ValueError(f"{path}: {r['figure']}: {c!r} is not a claim of the paper")
    if len({r["figure"] for r in recs}) < len(recs):
        raise ValueError(f"{path}: more than one recommendation for a figure")
    return recs


def contradictions(cards: pd.DataFrame, recs: list[dict]) -> list[str]:
    """Where the verdicts of this run's figures contradict a recommendation: its reading did not
    run, or a claim it names as reproduced is not."""
    out = []
    for r in recs:
        f = cards[cards["figure"] == r["figure"]]
        if not len(f):
            continue
        mine = f[f["reading"] == r["reading"]]
        if not len(mine):
            out.append(f"{r['figure']}: the recommended reading \"{r['reading']}\" is not in "
                       "this run")
            continue
        verdicts = dict(zip(mine["claim"], mine["verdict"]))
        out += [f"{r['figure']}, \"{r['reading']}\": the recommendation names \"{c}\" as "
                f"reproduced, the data say {verdicts.get(c, 'not judged')}"
                for c in r["reproduces"] if verdicts.get(c) != scorecard.REPRODUCED]
    return out


def recommendations_markdown(cards: pd.DataFrame, recs: list[dict]) -> str:
    """The recommendations of the figures in this run, and every contradiction, loudly."""
    shown = [r for r in recs if r["figure"] in set(cards["figure"])]
    if not shown:
        return ""
    lines = [prose("readings.recommended"), "",
             "| figure | recommended reading | reproduces (as written) | reason |",
             "|---|---|---|---|"]
    lines += [f"| {r['figure']} | {escape(r['reading'])} | {', '.join(r['reproduces']) or '—'} "
              f"| {escape(r['why'])} |" for r in shown]
    lines.append("")
    lines += [f"- **recommendation contradicted by the data: {c}**"
              for c in contradictions(cards, recs)]
    return "\n".join(lines) + "\n"


def _figure_readings(per: dict) -> list:
    """The readings the curves figure shows: FIGURE_CHOICES' (all, if a run has none)."""
    every = list(dict.fromkeys(r for p in per.values() for r in p))

    def shown(r):
        return any(str(sv["choice"].iloc[0]).startswith(FIGURE_CHOICES)
                   for sv in (p[r][1] for p in per.values() if r in p)
                   if "choice" in sv and len(sv))
    keep = [r for r in every if shown(r)]
    return keep or every


def figure(aggs: dict, title: str):
    """The absolute error of every condition, a panel per figure (row) and reading (column)."""
    import textwrap

    figs = reads("readings")
    studies = [s for s in figs if s in aggs]
    per = {s: split(aggs[s]) for s in studies}
    readings = _figure_readings(per)
    fig, axes = figures.plt.subplots(len(studies), len(readings), squeeze=False,
                                     figsize=(2.7 * len(readings), 2.5 * len(studies) + 0.8),
                                     sharex=True)
    handles = {}
    for i, s in enumerate(studies):
        for j, reading in enumerate(readings):
            ax = axes[i, j]
            if reading not in per[s]:
                ax.set_visible(False)
                continue
            cv, sv = per[s][reading]
            styles = figures.condition_styles(sv)
            for row in sv.itertuples():
                cu = cv[cv["condition"] == row.condition].sort_values("epoch")
                label = figures.condition_label(row._asdict())
                (line,) = ax.plot(cu["epoch"], cu["abs_error_mean"], lw=1.0, label=label,
                                  **styles[row.condition])
                handles.setdefault(label, line)
            figures.mark_growth_end(ax, sv, styles)
            ax.set(xscale="log", yscale="log")
            ax.set_title(textwrap.fill(f"{figs[s]}: {reading}", 30), fontsize=8)
            if j == 0:
                ax.set_ylabel("absolute error [m]")
            if i == len(studies) - 1:
                ax.set_xlabel("epoch")
    handles["end of growth (T_G)"] = figures.growth_end_handle()
    fig.suptitle(title)
    figures.legend_below(fig, list(handles.values()), 2.5 * len(studies) + 0.8, max_cols=7)
    return fig


def _name_values(ctx: Context, cards: pd.DataFrame, summary: pd.DataFrame) -> None:
    """The numbers of this study the pages quote (quoted.py), the matrix and the recommended
    reading's headline."""
    ctx.quote(summary, ("figure", "reading", "condition"), QUOTED)
    paper = ctx.shared.get("paper values", {})  # summary.csv's, named by the figures' section
    for name, (fig, reading, cond) in QUOTED_RATIOS.items():
        row = summary[(summary["figure"] == fig) & (summary["reading"] == reading)
                      & (summary["condition"] == cond)]
        if len(row) and (fig, cond) in paper:
            ctx.value(name, printed(row["final_abs_error_mean"].iloc[0]) / paper[fig, cond])
    for name, (fig, reading, claim) in QUOTED_RISE.items():
        c = cards[(cards["figure"] == fig) & (cards["reading"] == reading)
                  & (cards["claim"] == claim)]
        if len(c):
            ctx.value(name, float(f"{100 * c['value'].iloc[0]:+.0f}"))
    ctx.value("readings.table", matrix_markdown(matrix(cards)).rstrip("\n"))
    mine = scorecard.recommended_cells(cards, recommended())
    if len(mine):
        ctx.value("headline.recommended", scorecard.headline_text(scorecard.headline(mine)))


def claimed(ctx: Context) -> dict:
    """The readings study's aggregates that declare the paper's claims."""
    return {k: a for k, a in ctx.of("readings").items() if declares_claims(a)}


def shared_measures(ctx: Context) -> dict:
    """readings_measures(claimed(ctx)), once per report."""
    return ctx.once("readings measures", lambda: readings_measures(claimed(ctx)))


def shared_cards(ctx: Context, scale: str = "") -> pd.DataFrame:
    """intervals of shared_measures at `scale`, once per report and scale."""
    return ctx.once(("readings cards", scale), lambda: intervals({}, scale, shared_measures(ctx)))


@register("readings", 30)
def section(ctx: Context) -> list[str]:
    read = claimed(ctx)
    cards = shared_cards(ctx, ctx.cfg.report.scale)  # at the run's scale, for every file
    reading_table = table(cards)
    if not len(reading_table):
        return []
    ctx.text("readings_scorecard.csv", cards.to_csv(index=False, float_format="%.6g"))
    ctx.text("readings.csv", reading_table.to_csv(index=False, float_format="%.6g"))
    summary = finals(read)
    ctx.text("readings_summary.csv", summary.to_csv(index=False, float_format="%.6g"))
    m = ctx.text("readings_matrix.csv", matrix(cards).to_csv(index=False))
    _name_values(ctx, cards, summary)
    png = ctx.save(figure(ctx.of("readings"), "Readings of the paper (the default, the rates, the "
                          "solver): absolute error of every condition (mean over trials)"),
                   "readings_curves")[0].name
    return ["## Every reading of the paper against every claim", "",
            prose("readings.section"), "",
            matrix_markdown(read_matrix(m)), recommendations_markdown(cards, recommended()),
            f"![readings]({png})", "", intervals_markdown(cards)]

