"""Rescore a report under a register of criteria, without running a trial.

    python -m pipeline.tools.rescore [REPORT_DIR] [--register FILE]

Judges REPORT_DIR/measures.parquet (default outputs/report) under every reading of a register
(default pipeline/studies/register.yaml) as the scorecard does: the two headlines and every cell
whose verdict differs from the report's claims.csv. The measures themselves (smoothing, windows)
are fixed when the trials are measured. Exit 2 with one line on bad input.
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import pandas as pd

from ..config import REPO_ROOT
from ..studies import claims, measures_table, scorecard
from . import fail


def rescore(report: Path, register) -> dict:
    """{"default": headline, "counted", "cells": the figures' primary cells, "recommended":
    headline or None, "recommended_on", "unmeasured": readings the report has no measure for,
    "changed": (figure, claim, before, after)}. register: a file, or claims.load_register's."""
    t = measures_table.read(report / measures_table.NAME)
    reg = register if isinstance(register, list) else claims.load_register(register)
    groups = measures_table.measures(t)
    fig_ms = [m for (study, _, _), ms in groups.items() if study == "figures" for m in ms]
    counted = sorted(set(t.loc[(t["study"] == "figures") & t["counted"], "figure"]))
    scale = str(t["scale"].iloc[0]) if len(t) else ""

    def cells(ms):
        res = scorecard.no_verdicts(scorecard.judged(ms, register=reg), scale)
        return scorecard.cells(res, reg) if res else pd.DataFrame()
    cards = cells(fig_ms)
    # a reading measured where the report has no measure (a report made before its points were
    # scored) judges nothing: named, not dropped without a word
    served = {c: m for m, cs in claims.SERVES.items() for c in cs}  # rise_none: rise's measure
    places = {(m.claim, m.points, m.span) for m in fig_ms}
    have = {c for c, _, _ in places}
    unmeasured = [f"{c.id}: {r.id}" for c in reg for r in c.readings
                  if served.get(c.id, c.id) in have
                  and (served.get(c.id, c.id), r.params.get("points", "grid"),
                       r.params.get("span", "end")) not in places]
    rec = [(fig, reading) for (study, reading, fig) in groups
           if study == "readings" and t.loc[(t["study"] == "readings") & (t["figure"] == fig)
                                            & (t["reading"] == reading), "recommended"].any()]
    changed = []
    if (report / "claims.csv").exists() and len(cards):
        old = pd.read_csv(report / "claims.csv", keep_default_na=False)
        was = dict(zip(zip(old["figure"], old["claim"]), old["verdict"]))
        changed = [dict(figure=r["figure"], claim=r["claim"],
                        before=was.get((r["figure"], r["claim"]), "not judged"),
                        after=r["verdict"]) for r in cards.to_dict("records")
                   if was.get((r["figure"], r["claim"])) != r["verdict"]]
    return dict(default=scorecard.headline(cards, counted) if len(cards) else None,
                counted=counted, cells=cards, recommended=scorecard.headline(pd.concat(
                    [cells(groups[("readings", reading, fig)]) for fig, reading in rec]))
                if rec else None, recommended_on=rec, unmeasured=unmeasured, changed=changed)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(prog="python -m pipeline.tools.rescore",
                                description=__doc__.split("\n\n")[0])
    p.add_argument("report", nargs="?", type=Path, default=REPO_ROOT / "outputs" / "report")
    p.add_argument("--register", type=Path, default=claims.REGISTER)
    a = p.parse_args(argv)
    if not (a.report / measures_table.NAME).exists():
        return fail(f"{a.report}: no {measures_table.NAME} (a report written before it has none: "
                    "regenerate the report)")
    start = time.perf_counter()
    try:  # the register first: its schema checked before any of it is used (one line)
        register = claims.load_register(a.register)
    except ValueError as e:
        return fail(e)
    try:
        out = rescore(a.report, register)
    except (OSError, ValueError, KeyError, TypeError) as e:
        return fail(f"{a.report}: {e}")
    if out["default"] is not None:
        print(f"default reading on {', '.join(out['counted'])}: "
              f"{scorecard.headline_text(out['default'])}")
    if out["recommended"] is not None:
        on = "; ".join(f"{r} on {f}" for f, r in out["recommended_on"])
        print(f"recommended reading ({on}): {scorecard.headline_text(out['recommended'])}")
    if out["unmeasured"]:
        print(f"note: {a.report} has no measures where these readings measure the error, so "
              f"they judge nothing (regenerate the report): {'; '.join(out['unmeasured'])}")
    for c in out["changed"]:
        print(f"changed: {c['figure']} {c['claim']}: {c['before']} -> {c['after']}")
    if not out["changed"]:
        print("no cell changed against the report's claims.csv")
    print(f"({time.perf_counter() - start:.1f} s, no trial run)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
