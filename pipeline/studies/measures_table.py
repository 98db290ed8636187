"""measures.parquet: every per-trial measure of every study of a report, in one compact table.

One row per (study, figure, reading of the study, claim, condition, role, trial): the measure's
value on that trial before any criterion (claims.Measure), with what a criterion needs to judge
it (unit, kind, the condition's size and T_G, whether it is an exact count). role "value" is
the measure, "control" the same measure on the constant full-size reference's trials over the
same epochs. level and calibration: the t level the scorecard used for the measure (NaN: not
calibrated) and where its coverage came from, so that rescoring draws no fresh samples. An exact
count (the bootstrap claim) is two rows, trial 0 the failed trials and
trial 1 the total. `scale` is the run's reduced scale (report.scale; "" at the paper's).
`counted` marks the figures the headline counts, and `recommended` the
readings-study rows of the reading recommended for their figure. Study "replicate": a replicate
set's measures, under the figure it replicates (pipeline/studies/replicate.py).
`python -m pipeline.tools.rescore` rebuilds the Measures from it and judges them under a register.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from .claims import Measure

NAME = "measures.parquet"
COLUMNS = ["study", "figure", "reading", "counted", "recommended", "claim", "where", "unit",
           "kind", "size", "period", "exact", "diverged", "level", "calibration", "role",
           "trial", "value", "scale", "points", "span"]
WHERE_MEASURED = dict(points="grid", span="end")  # a table written before these columns: as then


def frame(ms: list[Measure], study: str, reading: str = "", counted: bool = False,
          recommended: bool = False) -> pd.DataFrame:
    """The rows of a list of Measures of one study (and one of its readings)."""
    from . import coverage
    from .claims import Test

    rows = []
    for m in ms:
        level, why = np.nan, ""
        if not (m.exact or m.diverged):  # the t level the scorecard uses, stored for rescoring
            lv, why = m.calibrated or coverage.calibration(
                Test(m.figure, m.claim, m.where, m.values, kind=m.kind, measure=m.claim),
                len(m.values))
            level = np.nan if lv is None else lv
        meta = dict(study=study, figure=m.figure, reading=reading, counted=counted,
                    recommended=recommended, claim=m.claim, where=m.where, unit=m.unit,
                    kind=m.kind, size=float(m.size), period=int(m.period),
                    exact=bool(m.exact), diverged=bool(m.diverged), level=level,
                    calibration=why, points=m.points, span=m.span)
        if m.diverged:
            rows.append(dict(meta, role="value", trial=-1, value=np.nan))
            continue
        for role, vals in (("value", m.values), ("control", m.control)):
            if vals is None:
                continue
            rows += [dict(meta, role=role, trial=i, value=float(v)) for i, v in enumerate(vals)]
    return pd.DataFrame(rows, columns=COLUMNS)


def write(path: Path, frames: list[pd.DataFrame], scale: str = "") -> Path:
    """The table of `frames`; scale: the run's reduced scale (report.scale, "" at the paper's),
    under which no cell is a verdict, rescored or not."""
    from .. import io

    t = pd.concat([f for f in frames if len(f)], ignore_index=True) if any(
        len(f) for f in frames) else pd.DataFrame(columns=COLUMNS)
    t["scale"] = str(scale or "")
    t = t.astype(dict(trial="int32", period="int32", value="float64", size="float64"))
    io.write_table(Path(path), io.frame_to_table(t))
    return Path(path)


def read(path: Path) -> pd.DataFrame:
    t = pd.read_parquet(path)
    for column, value in WHERE_MEASURED.items():
        if column not in t:
            t[column] = value
    missing = [c for c in COLUMNS if c not in t]
    if missing:
        raise ValueError(f"{path}: not a measures table (no column {missing[0]!r})")
    t["reading"] = t["reading"].fillna("")
    t["scale"] = t["scale"].fillna("")
    return t


def measures(t: pd.DataFrame) -> dict:
    """(study, reading, figure) -> [Measure], in the table's order."""
    out: dict = {}
    for key, g in t.groupby(["study", "reading", "figure", "claim", "where", "points", "span"],
                            sort=False):
        r = g.iloc[0]
        vals = g[g["role"] == "value"].sort_values("trial")["value"].to_numpy()
        ctrl = g[g["role"] == "control"].sort_values("trial")["value"].to_numpy()
        m = Measure(r["figure"], r["claim"], r["where"],
                    np.array([]) if r["diverged"] else
                    (vals.astype(int) if r["exact"] else vals),
                    unit=r["unit"], kind=r["kind"], size=float(r["size"]),
                    period=int(r["period"]), control=ctrl if len(ctrl) else None,
                    exact=bool(r["exact"]), diverged=bool(r["diverged"]),
                    calibrated=None if r["exact"] or r["diverged"] else
                    (None if pd.isna(r["level"]) else float(r["level"]), r["calibration"]),
                    points=r["points"], span=r["span"])
        out.setdefault(key[:3], []).append(m)
    return out


def values_frame(study: str, figure: str, where: str, claim: str, unit: str, values,
                 trials=None) -> pd.DataFrame:
    """The rows of one per-trial measure of a study no register judges (the baselines' held-out
    errors, the choices' final errors): published, not scored."""
    values = np.asarray(values, float)
    trials = np.arange(len(values)) if trials is None else np.asarray(trials, int)
    return pd.DataFrame([dict(study=study, figure=figure, reading="", counted=False,
                              recommended=False, claim=claim, where=where, unit=unit, kind="",
                              size=1.0, period=0, exact=False, diverged=False, level=np.nan,
                              calibration="not judged", role="value",
                              trial=int(t), value=float(v), **WHERE_MEASURED)
                         for t, v in zip(trials, values)],
                        columns=COLUMNS)


def study_frames(baselines_aggs: dict, choices_aggs: dict) -> list[pd.DataFrame]:
    """Every per-trial measure of the baselines study (held-out error, largest jump) and of the
    choices study (final absolute error, per variant)."""
    from . import baselines
    from .claims import per_trial

    frames = []
    pt = baselines.per_trial(baselines_aggs) if baselines_aggs else pd.DataFrame()
    if len(pt):
        for (body, learner, budget, growth), g in pt.groupby(
                ["body", "learner", "budget", "growth"], sort=False):
            where = f"{learner}, {budget}, {growth}"
            g = g.sort_values("trial")
            frames += [values_frame("baselines", body, where, "held-out error", "m",
                                    g["heldout_mm"] / 1e3, g["trial"]),
                       values_frame("baselines", body, where, "largest jump", "rad",
                                    g["largest_jump"], g["trial"])]
    for figure, agg in choices_aggs.items():
        if "trials" not in agg or not len(agg["trials"]):
            continue
        for r in agg["summary"].itertuples():
            if r.n_trials == 0:
                continue
            _, v = per_trial(agg["trials"], r.condition, "abs_error")
            frames.append(values_frame("choices", figure, f"{r.choice}: {r.variant}",
                                       "final error", "m", v[:, -1]))
    return frames
