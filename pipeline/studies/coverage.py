"""A skew diagnostic (docs/scorecard.md): the coverage of t intervals on sets of n trials drawn
from two models of a measure's values, the plain and the shrunk smoothed bootstrap (Silverman &
Young 1987), seeded by the measure's name; the lower coverage counts. It sets the t level a
skewed measure needs (the smallest of LEVELS covering MIN_COVERAGE); the calibration is
replicate.py's. coverage.csv is written by pipeline.tools.coverage, never by the report.
"""
from __future__ import annotations

import functools
import hashlib
import math
from pathlib import Path

import numpy as np
import pandas as pd
from scipy import stats

LEVELS = (0.95, 0.975, 0.99, 0.995, 0.999)  # the ladder of t levels a measure may need
MIN_COVERAGE = 0.90  # an interval is calibrated from here
FIT = 20  # a measure's model is fitted on at least this many trials
COUNTS = (3, 5, 10, 20)
DRAWS = 4000
TABLE = Path(__file__).parent / "coverage.csv"
COLUMNS = ["figure", "claim", "where", "kind", "trials", "draws", "t95", "level", "coverage"]


def fresh(values, n: int, draws: int = DRAWS, seed: int = 0) -> dict:
    """level -> the share of `draws` sets of n trials whose t interval covers the model's mean."""
    x = np.asarray(values, float)
    x = x[np.isfinite(x)]
    m, s0 = (float(x.mean()), float(x.std())) if len(x) else (np.nan, 0.0)
    if len(x) < 2 or s0 == 0 or n < 2:
        return {lv: (1.0 if s0 == 0 and len(x) and n >= 2 else np.nan) for lv in LEVELS}
    rng = np.random.default_rng(seed)
    h = 1.06 * float(x.std(ddof=1)) * len(x) ** -0.2
    plain = x[rng.integers(0, len(x), (draws, n))]
    smooth = m + (x[rng.integers(0, len(x), (draws, n))] - m
                  + h * rng.standard_normal((draws, n))) / math.sqrt(1 + h * h / (s0 * s0))
    out = {lv: 1.0 for lv in LEVELS}
    for y in (plain, smooth):
        mean = y.mean(axis=1)
        err = np.abs(mean - m)
        se = np.sqrt(((y - mean[:, None]) ** 2).sum(axis=1) / ((n - 1) * n))
        for lv in LEVELS:
            out[lv] = min(out[lv], float(np.mean(err <= _quantile(lv, n) * se)))
    return out


@functools.lru_cache(maxsize=None)
def _quantile(level: float, n: int) -> float:
    return float(stats.t.ppf(0.5 + level / 2, n - 1))


def calibrated(cov: dict) -> tuple[float | None, float]:
    for lv in LEVELS:
        if np.isfinite(cov.get(lv, np.nan)) and cov[lv] >= MIN_COVERAGE:
            return lv, cov[lv]
    return None, cov.get(LEVELS[0], np.nan)


def row(figure: str, claim: str, where: str, kind: str, values, n: int,
        draws: int = DRAWS) -> dict:
    key = "|".join(map(str, (figure, claim, where, n))).encode()
    cov = fresh(values, n, draws, int.from_bytes(hashlib.sha256(key).digest()[:8], "big"))
    level, c = calibrated(cov)
    return dict(figure=figure, claim=claim, where=where, kind=kind, trials=n, draws=draws,
                t95=cov[LEVELS[0]], level=np.nan if level is None else level, coverage=c)


def per_trial_values(report: Path) -> pd.DataFrame:
    """A report's measures (figure, claim, where, kind, values): measures.parquet's, or in a
    report written before it scorecard.csv's per_trial column (the primary reading's)."""
    if (report / "measures.parquet").exists():
        t = pd.read_parquet(report / "measures.parquet")
        t = t[(t["study"] == "figures") & (t["role"] == "value") & ~t["exact"] & ~t["diverged"]]
        return pd.DataFrame([dict(figure=f, claim=c, where=w, kind=g["kind"].iloc[0],
                                  values=g.sort_values("trial")["value"].to_numpy())
                             for (f, c, w), g in t.groupby(["figure", "claim", "where"],
                                                           sort=False)])
    sc = pd.read_csv(report / "scorecard.csv", keep_default_na=False)
    sc = sc[sc["reading"].astype(str) == ""] if "reading" in sc else sc
    return pd.DataFrame([dict(figure=r["figure"], claim=r.get("measure") or r["claim"],
                              where=r["where"], kind=r["kind"],
                              values=np.array([float(v) for v in str(r["per_trial"]).split()]))
                         for r in sc.to_dict("records")
                         if r["kind"] not in ("", None) and str(r["per_trial"]).strip()])


def table(values: pd.DataFrame, counts=COUNTS, draws: int = DRAWS) -> pd.DataFrame:
    rows = [row(r["figure"], r["claim"], r["where"], r["kind"], r["values"], n, draws)
            for r in values.to_dict("records") if len(r["values"]) >= FIT for n in counts]
    return pd.DataFrame(rows, columns=COLUMNS)


def read_table(path: Path = TABLE) -> pd.DataFrame:
    if not Path(path).exists():
        return pd.DataFrame(columns=COLUMNS)
    return pd.read_csv(path, keep_default_na=False, na_values=[""],
                       dtype={"figure": str, "claim": str, "where": str, "kind": str})


def to_csv(t: pd.DataFrame) -> str:
    return t.to_csv(index=False, float_format="%.4f")


_READ: list = []  # [((path, the bytes of coverage.csv), the table parsed from them)]
_FRESH: dict = {}  # the rows of the measures calibrated on fresh samples
_LOOKUPS: dict = {}  # id(table) -> (table, {(n, measure, where, figure): answer}, its claims)


def current() -> pd.DataFrame:
    data = (str(TABLE), TABLE.read_bytes() if TABLE.exists() else None)
    if not _READ or _READ[0][0] != data:
        _READ[:] = [(data, read_table(TABLE))]
    return _READ[0][1]


def calibration(t, n: int, table: pd.DataFrame | None = None) -> tuple[float | None, str]:
    """(the t level or None, why) of a measure on n trials: its stored one, else fresh samples of
    its values (FIT trials or more), else the table's most demanding level of its measure and
    condition (failing that, of its measure) at the largest n <= its own, its own figure
    family's rows where there are any (fig7_20trials for fig7)."""
    if t.calibrated is not None:
        return t.calibrated
    measure = t.measure or t.claim
    if n >= FIT:
        key = (t.figure, measure, t.where, n, np.asarray(t.values, float).tobytes())
        if key not in _FRESH:
            _FRESH[key] = row(t.figure, measure, t.where, t.kind, t.values, n)
        level = _FRESH[key]["level"]
        return (level if np.isfinite(level) else None), f"fresh samples of its {n} trials"
    tab = current() if table is None else table
    if not len(tab):
        return None, "no coverage measured"
    memo = _LOOKUPS.get(id(tab))
    if memo is None or memo[0] is not tab:  # a new table (an id is reused only once freed)
        if len(_LOOKUPS) >= 8:
            _LOOKUPS.clear()
        memo = _LOOKUPS[id(tab)] = (tab, {}, dict(iter(tab.groupby("claim", sort=False)))
                                    if "claim" in tab else None)
    key = (n, measure, t.where, str(t.figure))
    if key not in memo[1]:
        memo[1][key] = _lookup(memo[2], *key)
    return memo[1][key]


def _lookup(claims: dict | None, n: int, measure: str, where: str, figure: str):
    if claims is None:  # a table per measure type only
        return None, "no coverage per measure"
    if measure not in claims:
        return None, "no coverage measured for this measure"
    tab = claims[measure][claims[measure]["trials"] <= n]
    for rows in (tab[tab["where"] == where], tab):
        if not len(rows):
            continue
        rows = rows[rows["trials"] == rows["trials"].max()]
        own = rows[rows["figure"].astype(str).str.startswith(figure)]
        rows = own if len(own) else rows
        if rows["level"].isna().any():
            return None, f"not calibrated at {int(rows['trials'].iloc[0])} trials"
        return float(rows["level"].max()), f"coverage table at {int(rows['trials'].iloc[0])} trials"
    return None, "no coverage measured for this measure"


def markdown(t: pd.DataFrame) -> str:
    """The table as docs/scorecard.md shows it (the named value coverage.table)."""
    counts = sorted(int(n) for n in t["trials"].unique())
    lines = ["| figure | claim | measure | " + " | ".join(f"{n} trials" for n in counts) + " |",
             "|---|---|---|" + "---|" * len(counts)]

    def cell(r):
        text = f"{100 * r['t95']:.1f} %"
        if not np.isfinite(r["level"]):
            return text + " (not calibrated)"
        if r["level"] > LEVELS[0]:
            text += f" (t at {100 * r['level']:g} %: {100 * r['coverage']:.1f} %)"
        return text
    for (f, c, w), g in t.groupby(["figure", "claim", "where"], sort=False):
        by = {int(r["trials"]): r for r in g.to_dict("records")}
        lines.append(f"| {f} | {c} | {w} | "
                     + " | ".join(cell(by[n]) if n in by else "" for n in counts) + " |")
    return "\n".join(lines)
