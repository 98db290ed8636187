"""The scorecard as report.md shows it: its table (claims x figures, then every measure) and
its figure (scorecard.png); the verdicts are scorecard.py's."""
from __future__ import annotations

import textwrap

import numpy as np
import pandas as pd

from .claims import CLAIMS, DIVERGED
from .scorecard import (INCONCLUSIVE, MIN_VERDICT, NOT, NOT_A_VERDICT, REPRODUCED, TITLES,
                        UNCALIBRATED, _need, cell_text, criterion, first_cells, fmt, fmt_interval,
                        headline, headline_text)


def _order(cards: pd.DataFrame) -> tuple[list, list]:
    return [c.id for c in CLAIMS if c.id in set(cards["claim"])], sorted(set(cards["figure"]))


def markdown(cards: pd.DataFrame, results: list[dict], counted=None, readings=None,
             recommended: str = "", first: str = "") -> str:
    """The scorecard and every measure below it. counted: the headline's figures; readings:
    claim -> our reading (a column only where given); recommended, first: the other headlines."""
    from .choices import escape

    claims, figs = _order(cards)
    n = headline(cards, counted)
    where = "" if counted is None else f" on {', '.join(sorted(counted))}"
    lines = [f"The paper's claims{where}, each under its primary reading: **{headline_text(n)}** "
             "(t intervals of the mean over trials of a per-trial measure, at a level a "
             "resampling skew diagnostic sets, calibrated against an independent replicate set "
             "below; each claim under its primary reading of the paper, "
             "pipeline/studies/register.yaml, some made primary after the data, as its "
             "changelog says; diagnostics, marked, are shown and not counted; each cell's "
             "margin says how far its criterion would have to move to change it)."]
    lines += ["", first] if first else []
    lines += ["", recommended] if recommended else []
    if n[NOT_A_VERDICT]:
        lines += ["", f"**Not a verdict**: a cell on fewer than {MIN_VERDICT} trials per "
                  "condition (no skew diagnostic below that), or of a run at a reduced "
                  "scale (report.scale), shows its value and interval and decides nothing."]
    own = readings is not None
    lines += ["", "| claim of the paper | " + " | ".join(figs) + (" | our reading |" if own
                                                                  else " |"),
              "|---|" + "---|" * (len(figs) + own)]
    for claim in claims:
        row = cards[cards["claim"] == claim]
        by = {r["figure"]: escape(cell_text(r, "<br>")) for r in row.to_dict("records")}
        lines.append(f"| {escape(TITLES[claim])} | " + " | ".join(by.get(f, "—") for f in figs)
                     + (f" | {escape((readings or {}).get(claim, ''))} |" if own else " |"))
    lines += ["", "<details><summary>every measure under every reading, its interval and "
              "criterion</summary>", "",
              "| figure | claim | reading | measure | value | interval | criterion | trials "
              "| verdict | trials to decide |", "|---|---|---|---|---|---|---|---|---|---|"]
    for r in results:
        lines.append(f"| {r['figure']} | {escape(TITLES[r['claim']])} "
                     f"| {escape(r.get('reading') or 'primary')} | {escape(r['where'])} "
                     f"| {fmt(r['value'], r['unit'])} | {fmt_interval(r)} "
                     f"| {criterion(r)} | {r['trials']} | {r['verdict']}"
                     + (f" ({escape(r['note'])})" if r.get("note") else "") + f" | {_need(r) or ''} |")
    lines += ["", "</details>", ""]
    return "\n".join(lines)


def first_headline(results: list[dict], counted=None) -> str:
    cards, none = first_cells(results)
    if not len(cards):
        return ""
    n = headline(cards, counted)
    return ("The criteria as first fixed, before the first run's data (the readings marked "
            f"`first` in register.yaml, on the measures as they are now): **{headline_text(n)}**"
            + (f"; {', '.join(none)} had no criterion before the data and are not in this count"
               if none else "") + ".")


COLOURS = {REPRODUCED: "#b7e1b0", NOT: "#f4b6b0", INCONCLUSIVE: "#fbe3a0", DIVERGED: "#c9c3e6",
           NOT_A_VERDICT: "#e4e4e4"}


def _trials_strip(ax, x0: float, y: float, c: dict) -> None:
    """The worst measure's trials as dots across the cell, its bounds as ticks, its interval as
    a bar."""
    values = np.array([float(v) for v in str(c.get("per_trial") or "").split()])
    if len(values) < 2 or c["unit"] == "rate":
        return
    bounds = [b for b in (c.get("lo"), c.get("hi")) if b is not None and np.isfinite(b)]
    span = np.concatenate([values, bounds, [c["low"], c["high"]]])
    span = span[np.isfinite(span)]
    lo, hi = float(span.min()), float(span.max())
    pad = 0.05 * (hi - lo or 1.0)
    lo, hi = lo - pad, hi + pad
    def at(v):
        return x0 + 0.08 + 0.84 * (np.asarray(v, float) - lo) / (hi - lo)
    ax.plot([x0 + 0.08, x0 + 0.92], [y, y], color="0.55", lw=0.5)
    for b in bounds:
        ax.plot([at(b)] * 2, [y - 0.06, y + 0.06], color="black", lw=0.8)
    if np.isfinite(c["low"]) and np.isfinite(c["high"]):
        ax.plot([at(c["low"]), at(c["high"])], [y, y], color="black", lw=2.2, alpha=0.35,
                solid_capstyle="butt")
    ax.scatter(at(values), np.full(len(values), y), s=5, color="black", zorder=3, lw=0)


def figure(cards: pd.DataFrame, title: str):
    """scorecard.png: claims (rows) x figures (columns), cells coloured by verdict."""
    from .figures import plt, tight_layout

    claims, figs = _order(cards)
    fig, ax = plt.subplots(figsize=(2.9 * len(figs) + 2.6, 0.7 * len(claims) + 1.2))
    ax.set(xlim=(0, len(figs)), ylim=(len(claims), 0))
    ax.set_xticks(np.arange(len(figs)) + 0.5, figs)
    ax.set_yticks(np.arange(len(claims)) + 0.5, [textwrap.fill(TITLES[c], 34) for c in claims])
    ax.xaxis.tick_top()
    ax.tick_params(length=0)
    ax.grid(False)
    for i, claim in enumerate(claims):
        for j, f in enumerate(figs):
            hit = cards[(cards["claim"] == claim) & (cards["figure"] == f)]
            if not len(hit):
                ax.add_patch(plt.Rectangle((j, i), 1, 1, fc="#eeeeee", ec="white", lw=2))
                continue
            c = hit.iloc[0].to_dict()
            ax.add_patch(plt.Rectangle((j, i), 1, 1, fc=COLOURS[c["verdict"]], ec="white", lw=2))
            text = (f"{c['reproduced']} of {c['measures']} reproduced; " if c["measures"] > 1
                    else "") + f"worst: {c['where']}: {fmt(c['value'], c['unit'])} {fmt_interval(c)}"
            if c["verdict"] == INCONCLUSIVE and _need(c):
                text += f"; ~{_need(c)} trials would decide"
            label = c["verdict"] + (": not calibrated" if UNCALIBRATED in str(c.get("note"))
                                    else "")
            ax.text(j + 0.5, i + 0.2, label, ha="center", va="center", fontsize=8,
                    fontweight="bold")
            ax.text(j + 0.5, i + 0.5, textwrap.fill(text, 46), ha="center", va="center",
                    fontsize=6.5, linespacing=1.1)
            _trials_strip(ax, j, i + 0.84, c)
    for s in ax.spines.values():
        s.set_visible(False)
    handles = [plt.Rectangle((0, 0), 1, 1, fc=col) for col in COLOURS.values()]
    ax.legend(handles, list(COLOURS), loc="upper center", bbox_to_anchor=(0.5, -0.02), ncol=len(COLOURS),
              frameon=False, fontsize=8)
    fig.suptitle(title, fontsize=10)
    tight_layout(fig)
    return fig
