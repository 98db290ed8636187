"""The readings x claims study: which readings of the paper's text reproduce which claim.

The runs are experiments (conf/experiment/readings_fig4|fig5|fig7.yaml): each paper figure's
conditions under every reading that can change a verdict, as variants with common random
numbers. This module checks the paper's claims (pipeline.studies.claims) on each reading separately and
lays them out as one table (rows: readings, columns: claims) and one figure. It also holds the
rule that fixes the plain step's rate before the run (`weight_sum`).
"""
from __future__ import annotations

import numpy as np
import pandas as pd

import gbmodel
from gbmodel.learners import goal_babbling as gb
from gbmodel.learners.goal_babbling import reference

from . import claims, figures, scorecard
from .choices import escape
from .sections import Context, declares_claims, register

STUDIES = {"readings_fig4": "fig4", "readings_fig5": "fig5", "readings_fig7": "fig7"}


def weight_sum(body: str, params: dict, seeds=(0, 1, 2), epochs: int = 20_000,
               probe: int = 50) -> float:
    """W of the plain step's rule (gbmodel.learners.goal_babbling.weight_sum; arm5 W = 1142,
    iCub W = 1791, arm2 W = 1931 when the rates were fixed)."""
    return gb.weight_sum({"name": body}, params, seeds, epochs, probe)


def split(agg: dict) -> dict:
    """reading -> (curves, summary) with the conditions named as in the paper's figure."""
    out = {}
    s, c = agg["summary"], agg["curves"]
    for label in s["variant"].drop_duplicates():
        sv = s[s["variant"] == label].copy()
        names = sv["condition"].tolist()
        rename = {n: n.split(" | ", 1)[1] for n in names}
        sv["condition"] = sv["condition"].map(rename)
        cv = c[c["condition"].isin(names)].copy()
        cv["condition"] = cv["condition"].map(rename)
        out[label] = (cv, sv)
    return out


def _rename(frame: pd.DataFrame, names: list) -> pd.DataFrame:
    f = frame[frame["condition"].isin(names)].copy()
    f["condition"] = f["condition"].map({n: n.split(" | ", 1)[-1] for n in names})
    return f


def intervals(aggs: dict) -> pd.DataFrame:
    """One row per (figure, reading, claim): the scorecard's verdict with its 95 % interval over
    the reading's trials (pipeline/studies/scorecard.py), the measure that decides it."""
    rows = []
    for study, fig in STUDIES.items():
        if study not in aggs or "trials" not in aggs[study]:
            continue
        s = aggs[study]["summary"]
        for label in s["variant"].drop_duplicates():
            names = s[s["variant"] == label]["condition"].tolist()
            tests = claims.tests(fig, _rename(aggs[study]["trials"], names), _rename(s, names))
            table = scorecard.coverage_table()
            cards = scorecard.cells([scorecard.run_test(t, table) for t in tests])
            rows += [dict(c, reading=label) for c in cards.to_dict("records")]
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


def table(aggs: dict) -> pd.DataFrame:
    """readings.csv: one row per (figure, reading, claim), the cells of `intervals`."""
    t = intervals(aggs)
    if not len(t):
        return pd.DataFrame()
    return pd.DataFrame(dict(
        figure=t["figure"], reading=t["reading"], claim=t["claim"],
        diagnostic=t["diagnostic"], verdict=t["verdict"],
        measured=[scorecard.cell_text(r).replace("**", "") for r in t.to_dict("records")],
        trials=t["trials"]))


def figure(aggs: dict, title: str):
    """The key curves side by side: absolute error of every condition, one panel per figure and
    reading (rows: figures, columns: readings), the end of growth marked, one legend below."""
    import textwrap

    studies = [s for s in STUDIES if s in aggs]
    per = {s: split(aggs[s]) for s in studies}
    readings = list(dict.fromkeys(r for s in studies for r in per[s]))
    fig, axes = figures.plt.subplots(len(studies), len(readings), squeeze=False,
                                     figsize=(2.7 * len(readings), 2.5 * len(studies) + 1.4),
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
            ax.set_title(textwrap.fill(f"{STUDIES[s]}: {reading}", 30), fontsize=8)
            if j == 0:
                ax.set_ylabel("absolute error [m]")
            if i == len(studies) - 1:
                ax.set_xlabel("epoch")
    handles["end of growth (T_G)"] = figures.growth_end_handle()
    fig.legend(handles=list(handles.values()), labels=list(handles), loc="lower center",
               ncol=min(len(handles), 7), frameon=False)
    fig.suptitle(title)
    fig.tight_layout(rect=(0, 0.6 / (2.5 * len(studies) + 1.4), 1, 1))
    return fig


@register("readings", 30)
def section(ctx: Context) -> list[str]:
    studies = ctx.of("readings")
    read = {k: a for k, a in studies.items() if declares_claims(a)}
    reading_table = table(read)
    if not len(reading_table):
        return []
    cards = intervals(read)
    ctx.text("readings_scorecard.csv", cards.to_csv(index=False, float_format="%.6g"))
    ctx.text("readings.csv", reading_table.to_csv(index=False, float_format="%.6g"))
    png = ctx.save(figure(studies, "Readings of the paper: absolute error of every condition "
                          "(mean over trials)"), "readings_curves")[0].name
    return ["## Every reading of the paper against every claim", "",
            "Each row is a reading of the text (conf/experiment/readings_*.yaml, "
            "pipeline/studies/readings.py); each column a claim, checked as above.", "",
            f"![readings]({png})", "", intervals_markdown(cards)]
