"""The report's discussion: pipeline/studies/findings.md, hand-written about the committed run,
shown only when the run's numbers are those it was written against (findings_numbers.csv)."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from .. import io

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
    """findings.md if these are its run's numbers (every verdict the same, every number within
    TOLERANCE); else a note that it is left out."""
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
    """Record the numbers findings.md was written against (after rereading it)."""
    io.write_text(FINDINGS_NUMBERS, findings_numbers(summary, claim_rows)
                  .to_csv(index=False, float_format="%.17g", na_rep="nan"))


