"""The scorecard (docs/scorecard.md): each measure's mean over trials, its t interval at the
level the skew diagnostic sets (coverage.py; a control: Welch's interval of the difference) and
its verdict: reproduced (within the criterion), not reproduced (outside), inconclusive
(straddling a bound, no level calibrated, fewer than min_trials), not a verdict (fewer than
MIN_VERDICT trials, a reduced scale); a cell (claim x figure) the first verdict in ORDER of its
measures, showing the worst of them and k of n reproduced; the scorecard as report.md shows it
(its table, claims x figures, then every measure) and its figure (scorecard.png)."""
from __future__ import annotations

import math
import textwrap

import numpy as np
import pandas as pd
from scipy import stats

from . import coverage
from .claims import BY_ID, CLAIMS, DIVERGED, Test, judge, stage_measures  # noqa: F401
from .claims import measures as claims_measures
from .sections import prose

LEVEL = 0.95  # the nominal level where the coverage allows it (coverage.LEVELS[0])
MIN_VERDICT = min(coverage.COUNTS)  # fewer trials: "not a verdict" (no skew diagnostic)
MAX_DECIDE = 1000  # "trials to decide" beyond this is no estimate: not shown
TITLES = {c.id: c.words + (" (diagnostic)" if c.diagnostic else "") for c in CLAIMS}
REPRODUCED, NOT, INCONCLUSIVE = "reproduced", "not reproduced", "inconclusive"
NOT_A_VERDICT = "not a verdict"
UNCALIBRATED = "interval not calibrated"
ORDER = (DIVERGED, NOT_A_VERDICT, NOT, INCONCLUSIVE, REPRODUCED)  # a cell's: the first present


def interval(values: np.ndarray, level: float = LEVEL) -> tuple[float, float, float]:
    v = np.asarray(values, float)
    point = float(v.mean()) if len(v) else np.nan
    if len(v) < 2:
        return point, np.nan, np.nan
    half = float(stats.t.ppf(0.5 + level / 2, len(v) - 1) * v.std(ddof=1) / math.sqrt(len(v)))
    return point, point - half, point + half


def difference(values: np.ndarray, control: np.ndarray,
               level: float = LEVEL) -> tuple[float, float, float]:
    a, b = np.asarray(values, float), np.asarray(control, float)
    point = float(a.mean() - b.mean()) if len(a) and len(b) else np.nan
    if len(a) < 2 or len(b) < 2:
        return point, np.nan, np.nan
    va, vb = a.var(ddof=1) / len(a), b.var(ddof=1) / len(b)
    se = math.sqrt(va + vb)
    if se == 0:
        return point, point, point
    df = (va + vb) ** 2 / (va ** 2 / (len(a) - 1) + vb ** 2 / (len(b) - 1))
    half = float(stats.t.ppf(0.5 + level / 2, df) * se)
    return point, point - half, point + half


def verdict(low: float, high: float, lo: float, hi: float) -> str:
    if not (np.isfinite(low) and np.isfinite(high)):
        return INCONCLUSIVE
    if lo <= low and high <= hi:
        return REPRODUCED
    return NOT if high < lo or low > hi else INCONCLUSIVE


def flip(low: float, high: float, lo: float, hi: float, v: str) -> tuple[float, float]:
    """(bound, where it flips): the bound nearest to changing the verdict and the value it would
    have to move to (reproduced: the interval's nearer end; not reproduced: the end facing it;
    inconclusive: past the end nearer to it). (NaN, NaN) without an interval."""
    if v not in (REPRODUCED, NOT, INCONCLUSIVE) or not (np.isfinite(low) and np.isfinite(high)):
        return np.nan, np.nan
    moves = []
    for b, end in ((lo, low), (hi, high)):
        if not np.isfinite(b):
            continue
        if v == REPRODUCED:
            moves.append((b, end))
        elif v == NOT and (high < b if b == lo else low > b):
            moves.append((b, high if b == lo else low))
        elif v == INCONCLUSIVE and low <= b <= high:
            moves.append((b, min((low, high), key=lambda e: abs(e - b))))
    return min(moves, key=lambda m: abs(m[1] - m[0])) if moves else (np.nan, np.nan)


def trials_to_decide(point: float, low: float, high: float, lo: float, hi: float,
                     n: int) -> int | None:
    """Trials per condition at which an interval of the observed spread (its half-width on the
    side of the bound it straddles shrinking as 1 / sqrt(n)) would clear that bound; None when
    undefined or beyond MAX_DECIDE."""
    if not (np.isfinite(low) and np.isfinite(high)):
        return None
    bounds = [b for b in (lo, hi) if np.isfinite(b) and low <= b <= high]
    if not bounds:
        return None
    b = min(bounds, key=lambda b: abs(point - b))
    gap = abs(point - b)
    half = (point - low) if b <= point else (high - point)
    if gap == 0 or half <= 0:
        return None
    need = max(n + 1, math.ceil(n * (half / gap) ** 2))
    return need if need <= MAX_DECIDE else None


def run_test(t: Test, table: pd.DataFrame | None = None) -> dict:
    """A judged measure's row of scorecard.csv."""
    base = dict(figure=t.figure, claim=t.claim, diagnostic=bool(t.diagnostic), where=t.where,
                reading=t.reading, primary=not t.reading, measure=t.measure or t.claim,
                lo=t.lo, hi=t.hi, unit=t.unit, kind=t.kind)
    if t.diverged:  # nothing to measure: the cell says so
        return dict(base, value=np.nan, low=np.nan, high=np.nan, trials=0, verdict=DIVERGED,
                    level=np.nan, note="", control_value=np.nan, trials_to_decide=None,
                    per_trial="", bound=np.nan, flips_at=np.nan)
    note, level, control_value = "", np.nan, np.nan
    if t.exact:  # a count: the verdict is exact, the interval is the failure rate's
        k, n = (int(v) for v in t.values)
        ci = stats.binomtest(k, n).proportion_ci(LEVEL) if n else None
        point, low, high = (k / n if n else np.nan, ci.low if ci else np.nan,
                            ci.high if ci else np.nan)
        v, need, per_trial = (REPRODUCED if k == 0 else NOT), None, ""
    else:
        n = len(t.values)
        lv, why = coverage.calibration(t, n, table)
        level = LEVEL if lv is None else lv
        if t.control is not None and len(t.control):
            point, low, high = difference(t.values, t.control, level)
            control_value = float(np.mean(t.control))
        else:
            point, low, high = interval(t.values, level)
        v = verdict(low, high, t.lo, t.hi)
        if n < MIN_VERDICT:
            v, note = NOT_A_VERDICT, f"{n} trials; a verdict needs {MIN_VERDICT}"
        elif lv is None:
            v, note = INCONCLUSIVE, f"{UNCALIBRATED} ({why})"
        elif n < t.min_trials:
            v = INCONCLUSIVE
        need = (trials_to_decide(point, low, high, t.lo, t.hi, n)
                if v == INCONCLUSIVE and not note else None)
        per_trial = " ".join(f"{x:.6g}" for x in t.values)
    bound, flips_at = flip(low, high, t.lo, t.hi, v) if not t.exact else (np.nan, np.nan)
    return dict(base, value=point, low=low, high=high, trials=n, verdict=v, level=level,
                note=note, control_value=control_value, trials_to_decide=need,
                per_trial=per_trial, bound=bound, flips_at=flips_at)


def no_verdicts(results: list[dict], scale: str) -> list[dict]:
    """The results of a run at a reduced scale (report.scale, e.g. "smoke"; "": the paper's),
    every verdict but "diverged" "not a verdict"."""
    return [r if r["verdict"] == DIVERGED or not scale else
            dict(r, verdict=NOT_A_VERDICT, note=f"a {scale} run, not the paper's scale",
                 trials_to_decide=None) for r in results]


def fmt(value: float, unit: str) -> str:
    if not np.isfinite(value):
        return "n/a"
    return {"%": f"{100 * value:+.0f} %", "rate": f"{100 * value:.0f} %",
            "m": f"{1000 * value:.1f} mm", "rad": f"{value:.2f} rad"}.get(unit, f"{value:.2f}x")


def fmt_interval(r: dict) -> str:
    if r.get("verdict") == DIVERGED:
        return "(every trial diverged)"
    if not (np.isfinite(r["low"]) and np.isfinite(r["high"])):
        return "no interval (1 trial)" if r["trials"] < 2 else "n/a"
    if r["unit"] == "rate":
        return f"(failure rate 95 % interval {fmt(r['low'], 'rate')} ... {fmt(r['high'], 'rate')})"
    level = r.get("level", LEVEL)
    at = (f" at {100 * level:g} %" if level is not None and np.isfinite(level)
          and abs(level - LEVEL) > 1e-9 else "")
    return f"[{fmt(r['low'], r['unit'])}, {fmt(r['high'], r['unit'])}]{at}"


def fmt_measure(r: dict) -> str:
    """The value and its interval; a controlled reading's as a difference from the control."""
    text = f"{fmt(r['value'], r['unit'])} {fmt_interval(r)}"
    cv = r.get("control_value")
    if cv is not None and np.isfinite(cv):
        text = f"{text} over the constant full-size body ({fmt(cv, r['unit'])})"
    return text


def criterion(r: dict) -> str:
    if r["claim"] == "bootstrap":
        return "no failed trial"
    lo, hi = r["lo"], r["hi"]
    if np.isfinite(lo) and np.isfinite(hi):
        return f"{fmt(lo, r['unit'])} ... {fmt(hi, r['unit'])}"
    return (f"> {fmt(lo, r['unit'])}" if np.isfinite(lo) else f"< {fmt(hi, r['unit'])}")


def all_cells(results: list[dict]) -> pd.DataFrame:
    """One cell per (claim, figure, reading) ("": the primary) in the results' order, showing
    the measure of the cell's verdict whose point lies least inside its criterion (relative to
    the bound's size)."""
    df = pd.DataFrame(results)
    df["reading"] = df["reading"].fillna("") if "reading" in df else ""

    def rel(d, b):
        return d / np.maximum(np.abs(b.where(np.isfinite(b), 1.0)), 1e-2)
    margin = np.minimum(rel(df["value"] - df["lo"], df["lo"]),
                        rel(df["hi"] - df["value"], df["hi"])).fillna(-np.inf).to_numpy()
    verdicts = df["verdict"].to_numpy()
    groups: dict = {}  # (claim, figure, reading) -> row positions, as groupby(sort=False) has them
    for i, key in enumerate(zip(df["claim"], df["figure"], df["reading"])):
        if not any(pd.isna(k) for k in key):
            groups.setdefault(key, []).append(i)
    out = []
    for (claim, figure, reading), rows in groups.items():
        vs = [verdicts[i] for i in rows]
        v = next(x for x in ORDER if x in vs)
        pick = df.iloc[min((i for i in rows if verdicts[i] == v), key=lambda i: margin[i])]
        need = pick["trials_to_decide"]
        out.append(dict(
            claim=claim, figure=figure, reading=reading, diagnostic=bool(pick["diagnostic"]),
            verdict=v, where=pick["where"], value=pick["value"], low=pick["low"],
            high=pick["high"], unit=pick["unit"], trials=int(pick["trials"]),
            trials_to_decide=None if need is None or pd.isna(need) else int(need),
            reproduced=vs.count(REPRODUCED), measures=len(rows), per_trial=pick["per_trial"],
            lo=pick["lo"], hi=pick["hi"], level=pick["level"], note=pick["note"] or "",
            **{k: pick[k] for k in ("control_value", "bound", "flips_at")}))
    return pd.DataFrame(out)


def cells(results: list[dict], register=None) -> pd.DataFrame:
    """One cell per (claim, figure) under the primary reading, with `others`: the cells of the
    other readings whose verdict differs, and those the register (`register`: claims, default
    this one's) always shows, "; "-joined."""
    by_id = BY_ID if register is None else {c.id: c for c in register}
    every = all_cells(results)
    if not len(every):
        return every
    primary = every[every["reading"] == ""].copy()
    others = {k: g.to_dict("records")  # each (claim, figure)'s, grouped once, in table order
              for k, g in every[every["reading"] != ""].groupby(["claim", "figure"], sort=False)}
    notes = []
    for r in primary.to_dict("records"):
        shown = {rd.id for rd in by_id[r["claim"]].readings if rd.always_shown}
        notes.append("; ".join(f"{x['reading']}: {x['verdict']} (worst: {x['where']}: "
                               f"{fmt_measure(x)})" for x in others.get((r["claim"], r["figure"]), [])
                               if x["verdict"] != r["verdict"] or x["reading"] in shown))
    primary["others"] = notes
    return primary.drop(columns="reading").reset_index(drop=True)


def _need(r: dict) -> int | None:
    # pandas turns a column with gaps into floats
    n = r.get("trials_to_decide")
    return None if n is None or pd.isna(n) else int(n)


def cell_text(c, newline: str = " ") -> str:
    """A cell's text (its lines joined by `newline`)."""
    r = dict(c)
    note = r.get("note") or ""
    text = f"**{r['verdict']}" + (f": {UNCALIBRATED}" if UNCALIBRATED in note else "") + "**"
    if r.get("measures", 1) > 1 and r["verdict"] != NOT_A_VERDICT:
        text += f" ({r['reproduced']} of {r['measures']} reproduced)"
    text += f"{newline}worst: {r['where']}: {fmt_measure(r)}"
    if r["verdict"] == NOT_A_VERDICT and note:
        text += f" ({note})"
    if r["verdict"] == INCONCLUSIVE and _need(r):
        text += f"{newline}~{_need(r)} trials would decide"
    if np.isfinite(r.get("flips_at", np.nan)):
        b, to, unit = r["bound"], r["flips_at"], r["unit"]
        by = f"{100 * (to - b):+.1f} points" if unit == "%" else (
            f"{to - b:+.2f}x" if unit == "x" else fmt(to - b, unit))
        text += f"{newline}margin: its bound {fmt(b, unit)} at {fmt(to, unit)} ({by}) would change it"
    if r.get("others"):
        text += f"{newline}other readings: {r['others']}"
    if r.get("replicate") is True:
        text += f"{newline}calibration fails against the replicate set (calibration.csv)"
    return text


def first_cells(results: list[dict], register=None) -> tuple[pd.DataFrame, list[str]]:
    """The cells under each claim's reading marked `first` (fixed before the first run's data),
    and the paper's claims that have none."""
    claims = CLAIMS if register is None else register
    first = {c.id: ("" if r.primary else r.id) for c in claims for r in c.readings if r.first}
    every = all_cells(results)
    if not len(every):
        return every, []
    keep = [first.get(c) == rd for c, rd in zip(every["claim"], every["reading"])]
    none = [c.id for c in claims if c.id not in first and not c.diagnostic]
    return every[keep].reset_index(drop=True), none


def headline(cards: pd.DataFrame, counted=None) -> dict:
    """Cells per verdict over the paper's claims (no diagnostics) on the `counted` figures."""
    c = cards[~cards["diagnostic"].astype(bool)]
    if counted is not None:
        c = c[c["figure"].isin(counted)]
    return {v: int((c["verdict"] == v).sum())
            for v in (REPRODUCED, NOT, INCONCLUSIVE, DIVERGED, NOT_A_VERDICT)}


def headline_text(n: dict) -> str:
    if n[NOT_A_VERDICT] and not (n[REPRODUCED] or n[NOT] or n[INCONCLUSIVE]):
        return f"no verdict ({n[NOT_A_VERDICT]} cells measured, none decided)"
    text = f"{n[REPRODUCED]} reproduced, {n[NOT]} not reproduced, {n[INCONCLUSIVE]} inconclusive"
    text += f", {n[DIVERGED]} diverged" if n[DIVERGED] else ""
    return text + (f", {n[NOT_A_VERDICT]} not a verdict" if n[NOT_A_VERDICT] else "")


def claims_table(cards: pd.DataFrame, register=None) -> pd.DataFrame:
    """claims.csv."""
    by_id = BY_ID if register is None else {c.id: c for c in register}
    return pd.DataFrame([dict(
        figure=r["figure"], claim=r["claim"], words=c.words, diagnostic=c.diagnostic,
        criterion=c.criterion, measure=c.measure, verdict=r["verdict"],
        reproduced=r["reproduced"], measures=r["measures"], worst=r["where"],
        measured=fmt_measure(r), trials=r["trials"], other_readings=r.get("others", ""))
        for r, c in ((r, by_id[r["claim"]]) for r in cards.to_dict("records"))])


def figure_measures(aggs: dict, stages: dict | None = None) -> list:
    """Every measure of the growth figures in `aggs` and of Fig. 2's `stages` (figure, spec, Ms)."""
    ms = [m for name, agg in aggs.items() if (agg["summary"]["growth"] != "none").any()
          for m in claims_measures(name, agg["trials"], agg["summary"])]
    return ms + (stage_measures(stages["figure"], stages["spec"], stages["trials"])
                 if stages else [])


def judged(ms: list, table: pd.DataFrame | None = None, register=None) -> list[dict]:
    """Every measure's t level found once (m.calibrated, the same for a measure and its
    multiples), then judged under every reading of `register` (default: this one's)."""
    table = coverage.current() if table is None else table  # one table: its look-ups are kept
    for m in ms:
        if m.calibrated is None and not (m.exact or m.diverged):
            m.calibrated = coverage.calibration(m, len(m.values), table)
    return [run_test(t, table) for t in judge(ms, register)]


def results(aggs: dict, stages: dict | None = None, table: pd.DataFrame | None = None) -> list[dict]:
    return judged(figure_measures(aggs, stages), table)


def recommended_cells(cards: pd.DataFrame, recs: list[dict]) -> pd.DataFrame:
    """The readings study's cells of each figure's recommended reading (`recs`)."""
    keep = [cards[(cards["figure"] == x["figure"]) & (cards["reading"] == x["reading"])]
            for x in recs if len(cards)]
    keep = [k for k in keep if len(k)]
    return pd.concat(keep) if keep else pd.DataFrame()


def recommended_headline(cards: pd.DataFrame, recs: list[dict]) -> str:
    """The recommended readings' headline over the readings study's cells ("" without them)."""
    mine = recommended_cells(cards, recs)
    if not len(mine):
        return ""
    readings = "; ".join(f"{r} on {f}" for f, r in dict.fromkeys(zip(mine["figure"],
                                                                     mine["reading"])))
    n = int(mine[mine["claim"] != "bootstrap"]["trials"].max())
    return prose("scorecard.recommended", readings=readings, n=n,
                 headline=headline_text(headline(mine)))


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
    lines = [prose("scorecard.headline", where=where, headline=headline_text(n))]
    lines += ["", first] if first else []
    lines += ["", recommended] if recommended else []
    if n[NOT_A_VERDICT]:
        lines += ["", prose("scorecard.not_a_verdict", n=MIN_VERDICT)]
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
    return prose("scorecard.first", headline=headline_text(n), none=(
        f"; {', '.join(none)} had no criterion before the data and are not in this count"
        if none else ""))


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
