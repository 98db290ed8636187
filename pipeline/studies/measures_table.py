"""measures.parquet: every per-trial measure of a report, one row per (study, figure, reading,
claim, condition, role, trial), role "value" or "control", with what a criterion needs and the t
level the scorecard used (NaN: not calibrated), so that pipeline.tools.rescore judges them
again without fresh samples. An exact count is two rows (the failed trials, the total).
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
    from . import coverage

    rows = []
    for m in ms:
        level, why = np.nan, ""
        if not (m.exact or m.diverged):  # the t level the scorecard uses, stored for rescoring
            lv, why = m.calibrated or coverage.calibration(m, len(m.values))
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
            rows += [dict(meta, role=role, trial=i, value=float(v))
                     for i, v in enumerate(() if vals is None else vals)]
    return pd.DataFrame(rows, columns=COLUMNS)


def write(path: Path, frames: list[pd.DataFrame], scale: str = "") -> Path:
    from .. import io

    frames = [f for f in frames if len(f)]
    t = pd.concat(frames, ignore_index=True) if frames else pd.DataFrame(columns=COLUMNS)
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
        vals, ctrl = (g[g["role"] == role].sort_values("trial")["value"].to_numpy()
                      for role in ("value", "control"))
        skip = r["exact"] or r["diverged"]
        out.setdefault(key[:3], []).append(Measure(
            r["figure"], r["claim"], r["where"],
            np.array([]) if r["diverged"] else (vals.astype(int) if r["exact"] else vals),
            unit=r["unit"], kind=r["kind"], size=float(r["size"]), period=int(r["period"]),
            control=ctrl if len(ctrl) else None, exact=bool(r["exact"]),
            diverged=bool(r["diverged"]), points=r["points"], span=r["span"],
            calibrated=None if skip else
            (None if pd.isna(r["level"]) else float(r["level"]), r["calibration"])))
    return out


def values_frame(study: str, figure: str, where: str, claim: str, unit: str, values,
                 trials=None) -> pd.DataFrame:
    """The rows of one per-trial measure no register judges (published, not scored)."""
    values = np.asarray(values, float)
    trials = np.arange(len(values)) if trials is None else np.asarray(trials, int)
    return pd.DataFrame(dict(study=study, figure=figure, reading="", counted=False,
                             recommended=False, claim=claim, where=where, unit=unit, kind="",
                             size=1.0, period=0, exact=False, diverged=False, level=np.nan,
                             calibration="not judged", role="value", trial=trials.astype(int),
                             value=values, **WHERE_MEASURED), columns=COLUMNS)


def study_frames(baselines_aggs: dict, choices_aggs: dict) -> list[pd.DataFrame]:
    """The baselines' held-out errors and largest jumps, the choices' final errors, per trial."""
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
