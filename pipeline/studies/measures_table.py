"""measures.parquet: every per-trial measure of every study of a report, in one compact table.

One row per (study, figure, reading of the study, claim, condition, role, trial): the measure's
value on that trial before any criterion (claims.Measure), with what a criterion needs to judge
it (unit, kind, the condition's size and T_G, whether it is an exact count). role "value" is
the measure, "control" the same measure on the constant full-size reference's trials over the
same epochs. An exact count (the bootstrap claim) is two rows, trial 0 the failed trials and
trial 1 the total. `counted` marks the figures the headline counts, and `recommended` the
readings-study rows of the reading recommended for their figure.
`python -m pipeline.tools.rescore` rebuilds the Measures from it and judges them under a register.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from .claims import Measure

NAME = "measures.parquet"
COLUMNS = ["study", "figure", "reading", "counted", "recommended", "claim", "where", "unit",
           "kind", "size", "period", "exact", "diverged", "role", "trial", "value"]


def frame(ms: list[Measure], study: str, reading: str = "", counted: bool = False,
          recommended: bool = False) -> pd.DataFrame:
    """The rows of a list of Measures of one study (and one of its readings)."""
    rows = []
    for m in ms:
        meta = dict(study=study, figure=m.figure, reading=reading, counted=counted,
                    recommended=recommended, claim=m.claim, where=m.where, unit=m.unit,
                    kind=m.kind, size=float(m.size), period=int(m.period),
                    exact=bool(m.exact), diverged=bool(m.diverged))
        if m.diverged:
            rows.append(dict(meta, role="value", trial=-1, value=np.nan))
            continue
        for role, vals in (("value", m.values), ("control", m.control)):
            if vals is None:
                continue
            rows += [dict(meta, role=role, trial=i, value=float(v)) for i, v in enumerate(vals)]
    return pd.DataFrame(rows, columns=COLUMNS)


def write(path: Path, frames: list[pd.DataFrame]) -> Path:
    from .. import io

    t = pd.concat([f for f in frames if len(f)], ignore_index=True) if any(
        len(f) for f in frames) else pd.DataFrame(columns=COLUMNS)
    t = t.astype(dict(trial="int32", period="int32", value="float64", size="float64"))
    io.write_table(Path(path), io.frame_to_table(t))
    return Path(path)


def read(path: Path) -> pd.DataFrame:
    t = pd.read_parquet(path)
    missing = [c for c in COLUMNS if c not in t]
    if missing:
        raise ValueError(f"{path}: not a measures table (no column {missing[0]!r})")
    t["reading"] = t["reading"].fillna("")
    return t


def measures(t: pd.DataFrame) -> dict:
    """(study, reading, figure) -> [Measure], in the table's order."""
    out: dict = {}
    for key, g in t.groupby(["study", "reading", "figure", "claim", "where"], sort=False):
        r = g.iloc[0]
        vals = g[g["role"] == "value"].sort_values("trial")["value"].to_numpy()
        ctrl = g[g["role"] == "control"].sort_values("trial")["value"].to_numpy()
        m = Measure(r["figure"], r["claim"], r["where"],
                    np.array([]) if r["diverged"] else
                    (vals.astype(int) if r["exact"] else vals),
                    unit=r["unit"], kind=r["kind"], size=float(r["size"]),
                    period=int(r["period"]), control=ctrl if len(ctrl) else None,
                    exact=bool(r["exact"]), diverged=bool(r["diverged"]))
        out.setdefault(key[:3], []).append(m)
    return out
