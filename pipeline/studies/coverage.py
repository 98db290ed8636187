"""A skew diagnostic: the coverage of the scorecard's intervals on samples resampled from a
measure's own values, per measure and trial count (the command that writes coverage.csv:
pipeline.tools.coverage). It resamples the same 20 values and asks whether t intervals cover
their own mean: it shows skew (an outlier that a t interval misses), not the variation between
independent runs. The calibration of the intervals is the replicate set's
(pipeline/studies/replicate.py); this table only sets the t level a skewed measure needs.

For every measure with at least FIT trials in a report (its per-trial values: measures.parquet,
or scorecard.csv's per_trial column in a report written before it), a model of its distribution
is fitted to those values, twice: the trials themselves (the plain bootstrap, which keeps a
skewed measure's outlier as it is) and the shrunk smoothed bootstrap (Silverman & Young 1987: a
value drawn from the trials plus Gaussian noise of Silverman's bandwidth h = 1.06 s N^(-1/5),
shrunk about the mean so that the model's mean and variance are the trials'). From each,
`draws` fresh sets of n trials are drawn per n in `trials`, each set's t interval at every level
of LEVELS is scored on whether it covers the model's mean (the trials' mean), and the lower of
the two coverages is kept. The table
holds, per measure and n, the coverage of the 95 % t interval and the smallest level whose
coverage is at least scorecard.MIN_COVERAGE (none: the interval is not calibrated at n, and such
a cell says "inconclusive: interval not calibrated"). Measures are not pooled: each has its own
row. The draws are seeded by the measure's name, so the same values give the same table.

The scorecard reads the table here (calibration): a measure's t level comes from fresh samples
of its own values (at least FIT trials) or from the table's rows of its measure at its trial
count; the table is an input of the report, written by the tool, never by the report.
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


def _seed(*key) -> int:
    return int.from_bytes(hashlib.sha256("|".join(map(str, key)).encode()).digest()[:8], "big")


def fresh(values, n: int, draws: int = DRAWS, seed: int = 0) -> dict:
    """level -> the fraction of `draws` fresh sets of n trials whose t interval at that level
    covers the model's mean, under the less favourable of two models of the values'
    distribution: the trials themselves (the plain bootstrap: a skewed measure's outlier kept
    as it is) and the shrunk smoothed bootstrap (Silverman's bandwidth, the trials' mean and
    variance kept)."""
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
    """(the smallest level whose coverage is >= MIN_COVERAGE, or None; its coverage, or the
    95 % one's where there is none)."""
    for lv in LEVELS:
        if np.isfinite(cov.get(lv, np.nan)) and cov[lv] >= MIN_COVERAGE:
            return lv, cov[lv]
    return None, cov.get(LEVELS[0], np.nan)


def row(figure: str, claim: str, where: str, kind: str, values, n: int,
        draws: int = DRAWS) -> dict:
    cov = fresh(values, n, draws, _seed(figure, claim, where, n))
    level, c = calibrated(cov)
    return dict(figure=figure, claim=claim, where=where, kind=kind, trials=n, draws=draws,
                t95=cov[LEVELS[0]], level=np.nan if level is None else level, coverage=c)


def per_trial_values(report: Path) -> pd.DataFrame:
    """One row per measure of a report's figures (figure, claim, where, kind, values): from
    measures.parquet (study "figures", the measures, not their controls), or from scorecard.csv's
    per_trial column (the primary reading's values) in a report written before it."""
    parquet = report / "measures.parquet"  # measures_table.NAME (which reads the scorecard)
    if parquet.exists():
        t = pd.read_parquet(parquet)
        t = t[(t["study"] == "figures") & (t["role"] == "value") & ~t["exact"]
              & ~t["diverged"]]
        rows = [dict(figure=f, claim=c, where=w, kind=g["kind"].iloc[0],
                     values=g.sort_values("trial")["value"].to_numpy())
                for (f, c, w), g in t.groupby(["figure", "claim", "where"], sort=False)]
        return pd.DataFrame(rows)
    sc = pd.read_csv(report / "scorecard.csv", keep_default_na=False)
    if "reading" in sc:
        sc = sc[sc["reading"].astype(str) == ""]
    rows = []
    for r in sc.to_dict("records"):
        if r["kind"] in ("", None) or not str(r["per_trial"]).strip():
            continue
        rows.append(dict(figure=r["figure"], claim=r.get("measure") or r["claim"],
                         where=r["where"], kind=r["kind"],
                         values=np.array([float(v) for v in str(r["per_trial"]).split()])))
    return pd.DataFrame(rows)


def table(values: pd.DataFrame, counts=COUNTS, draws: int = DRAWS) -> pd.DataFrame:
    """The coverage table: every measure with at least FIT trials, at every n of `counts`."""
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


# --- the t level of a measure, from fresh samples or this table (the scorecard's) ----------

_FRESH: dict = {}


def calibration(t, n: int, table: pd.DataFrame | None = None) -> tuple[float | None, str]:
    """(the t level to use, where its coverage comes from) for a measure on n trials, or (None,
    why) where no level is calibrated. A measure with at least FIT trials is calibrated
    on fresh samples of its own values; one with fewer takes the coverage table's rows of its
    measure and condition at the largest measured n <= its own (those of its own figure
    family, e.g. fig7_20trials for fig7, where there are any), the most demanding level of
    them; failing that, those of its claim's measure."""
    if t.calibrated is not None:  # measured when the report was written (measures.parquet)
        return t.calibrated
    measure = t.measure or t.claim
    if n >= FIT:
        key = (t.figure, measure, t.where, n, np.asarray(t.values, float).tobytes())
        if key not in _FRESH:
            _FRESH[key] = row(t.figure, measure, t.where, t.kind, t.values, n)
        r = _FRESH[key]
        level = r["level"] if np.isfinite(r["level"]) else None
        return level, f"fresh samples of its {n} trials"
    tab = current() if table is None else table
    if not len(tab):
        return None, "no coverage measured"
    return _from_table(tab, n, measure, t.where, str(t.figure))


_COVERAGE_READ: list = []  # [(the bytes of coverage.csv, the table parsed from them)]


def current() -> pd.DataFrame:
    """read_table() of TABLE for calibration's lookups (which only read it): parsed again only when
    the file's bytes change (read_csv took milliseconds, thousands of times per report)."""
    try:
        data = (str(TABLE), Path(TABLE).read_bytes())
    except FileNotFoundError:
        data = (str(TABLE), None)
    if not _COVERAGE_READ or _COVERAGE_READ[0][0] != data:
        _COVERAGE_READ[:] = [(data, read_table(TABLE))]
    return _COVERAGE_READ[0][1]


_LOOKUPS: dict = {}  # id(table) -> (table, {(n, measure, where, figure): calibration})


def _from_table(tab: pd.DataFrame, n: int, measure: str, where, figure: str):
    """calibration's answer from the coverage table `tab`, looked up once per table and
    (n, measure, where, figure): a report asks for the same few thousands of times (3,566 in a
    smoke report, each masking the table four times: a tenth of its CPU)."""
    memo = _LOOKUPS.get(id(tab))
    if memo is None or memo[0] is not tab:  # a new table (an id is reused only once freed)
        if len(_LOOKUPS) >= 8:
            _LOOKUPS.clear()
        claims = ({c: rows for c, rows in tab.groupby("claim", sort=False)}
                  if "claim" in tab else None)  # each claim's rows, in the table's order
        memo = _LOOKUPS[id(tab)] = (tab, {}, claims)
    key = (n, measure, where, figure)
    try:
        hash(key)
    except TypeError:  # a `where` that is not a plain value: looked up each time
        return _lookup(tab, n, measure, where, figure)
    if key not in memo[1]:
        memo[1][key] = _lookup(tab, n, measure, where, figure, memo[2])
    return memo[1][key]


def _lookup(tab: pd.DataFrame, n: int, measure: str, where, figure: str, claims=None):
    """claims: the rows of each claim of `tab` (groupby), else found here by masking."""
    if "claim" not in tab:  # a table per measure type only
        return None, "no coverage per measure"
    tab = tab[tab["claim"] == measure] if claims is None else claims.get(measure, tab.iloc[:0])
    tab = tab[tab["trials"] <= n]
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
    """The per-measure table as docs/scorecard.md shows it (the named value coverage.table,
    pipeline/studies/values.py): per measure,
    the 95 % t interval's coverage at each n, and the level used where it is below
    MIN_COVERAGE ("not calibrated" where no level reaches it)."""
    counts = sorted(int(n) for n in t["trials"].unique())
    lines = ["| figure | claim | measure | " + " | ".join(f"{n} trials" for n in counts) + " |",
             "|---|---|---|" + "---|" * len(counts)]
    for (f, c, w), g in t.groupby(["figure", "claim", "where"], sort=False):
        by = {int(r["trials"]): r for r in g.to_dict("records")}

        def cell(n):
            if n not in by:
                return ""
            r = by[n]
            text = f"{100 * r['t95']:.1f} %"
            if not np.isfinite(r["level"]):
                return text + " (not calibrated)"
            if r["level"] > LEVELS[0]:
                text += f" (t at {100 * r['level']:g} %: {100 * r['coverage']:.1f} %)"
            return text
        lines.append(f"| {f} | {c} | {w} | " + " | ".join(cell(n) for n in counts) + " |")
    return "\n".join(lines)
