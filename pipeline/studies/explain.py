"""The experiments behind the report's explanations (explain_*, readings_fig4), read from their
aggregates (no trial is run): the capacity bound (capacity.py), Fig. 2's boundary, the iCub's
continuation at a smaller rate, the half-size arm under steps that take the size out, the rise
during growth per rate and solver, and the target set's extent (explain_extent.py)."""
from __future__ import annotations

import numpy as np
import pandas as pd

from . import claims, explain_extent
from .capacity import _extremes, best_cubic
from .choices import escape
from .sections import Context, declared, prose, register


def explained() -> dict[str, str]:
    """explanation -> the experiment whose file declares it (declares.explains)."""
    return {e.declares.explains: n for n, e in declared().items() if e.declares.explains}


def _variants(agg: dict):
    """(variant label, models entry, curve) per condition."""
    conds = agg["models"]["conditions"]
    for r in agg["summary"].itertuples():
        cu = agg["curves"][agg["curves"]["condition"] == r.condition].sort_values("epoch")
        yield r.variant or r.condition, conds[r.condition], cu


def boundary(agg: dict) -> list[dict]:
    """Per target range: the error at the extreme targets, learned and best cubic (trial mean)."""
    out = []
    for label, cond, _ in _variants(agg):
        spec = cond["spec"]
        ms = [t["M"] for _, t in sorted(cond["trials"].items(), key=lambda kv: int(kv[0]))]
        if not ms:
            continue
        out.append(dict(label=label, trials=len(ms),
                        learned_mm=float(np.mean([_extremes(spec, M) for M in ms])),
                        best_cubic_mm=float(np.mean([_extremes(spec, best_cubic(spec, M)["M"])
                                                     for M in ms]))))
    return out


def continuation(agg: dict) -> dict | None:
    """The mean error before the rate step and at the end, at the same rate and the smaller."""
    parts = {label: (cond, cu) for label, cond, cu in _variants(agg)}
    step = next(((c["spec"]["learner"], cu) for c, cu in parts.values()
                 if c["spec"]["learner"].get("rate_schedule") == "step"), None)
    same = next((cu for c, cu in parts.values()
                 if c["spec"]["learner"].get("rate_schedule") == "constant"), None)
    if step is None or same is None or not len(same):
        return None
    learner, smaller = step
    at = learner["rate_step_epoch"]
    before = same[same["epoch"] <= at]
    return dict(epoch=at, later=int(same["epoch"].iloc[-1]) - at,
                factor=learner["rate_step_factor"], trials=int(same["n_trials"].iloc[-1]),
                before_mm=1e3 * float(before["abs_error_mean"].iloc[-1]) if len(before) else np.nan,
                same_mm=1e3 * float(same["abs_error_mean"].iloc[-1]),
                smaller_mm=1e3 * float(smaller["abs_error_mean"].iloc[-1]))


HALF_EPOCHS = (100, 1_000, 10_000)  # where the half-size over full-size ratio is read


def _pivot(trials: pd.DataFrame, condition: str, column: str) -> pd.DataFrame:
    c = trials[trials["condition"] == condition]
    return c.pivot(index="trial", columns="epoch", values=column).sort_index(axis=1)


def _learner(agg: dict, condition: str) -> dict:
    return agg["models"]["conditions"][condition]["spec"]["learner"]


def _rate0(agg: dict) -> float | None:
    """The chosen (default) condition's learning rate, if the summary marks one."""
    s = agg["summary"]
    default = s[s["chosen"].astype(bool)] if "chosen" in s else s.iloc[:0]
    return _learner(agg, default["condition"].iloc[0])["learning_rate"] if len(default) else None


def half_size(agg: dict) -> list[dict]:
    """Per variant: half-size over full-size relative error, trials paired by index, at
    HALF_EPOCHS (t interval), and the last epoch the half-size mean curve lies above."""
    s, out, rate0 = agg["summary"], [], _rate0(agg)
    for label, g in s.groupby("variant", sort=False):
        refs = g[g["growth"] == "none"].sort_values("end_size")
        if len(refs) != 2 or refs["n_trials"].min() == 0:
            continue
        half, full = refs["condition"]
        learner = _learner(agg, full)
        kind = ("lstsq" if learner.get("solver") == "lstsq" else "default"
                if bool(g["chosen"].iloc[0]) else "rate")
        a, b = (_pivot(agg["trials"], c, "rel_error") for c in (half, full))
        common = a.index.intersection(b.index)
        ratio = (a.loc[common] / b.loc[common]).dropna(axis=1)
        at = {}
        for e in HALF_EPOCHS:
            before = ratio.columns[ratio.columns <= e]
            if len(before) and e <= ratio.columns[-1]:
                at[e] = dict(explain_extent.ci(ratio[before[-1]].to_numpy()), epoch=int(before[-1]))
        mean = (a.mean() / b.mean()).dropna()
        above = mean.index[mean.to_numpy() > 1]
        out.append(dict(label=label, kind=kind, rate=(learner["learning_rate"] / rate0
                                                       if rate0 else np.nan),
                        at=at, last_above=int(above[-1]) if len(above) else None,
                        end=int(mean.index[-1]), trials=len(common)))
    return out


def _slower(v: dict) -> bool:
    """The ratio's interval lies above 1 at some epoch."""
    return any(r["low"] > 1 for r in v["at"].values())


def half_size_text(found: list[dict]) -> str:
    parts = []
    for v in found:
        name = "least squares" if v["kind"] == "lstsq" else f"plain step at {v['rate']:.2g} / W"
        at = (", ".join(f"epoch {e:,} {r['value']:.2f} [{r['low']:.2f}, {r['high']:.2f}]"
                        for e, r in v["at"].items())
              or f"the run ends before epoch {HALF_EPOCHS[0]:,}")
        last = (f"still above at the last epoch ({v['end']:,})" if v["last_above"] == v["end"]
                else f"above until epoch {v['last_above']:,}" if v["last_above"]
                else "never above")
        parts.append(f"{name}: {at}; {last}")
    text = ("half-size over full-size error per unit size (mean over "
            f"{found[0]['trials']} paired trials, 95 % t interval): " + "; ".join(parts)
            + ". ")
    by = {v["kind"]: v for v in found}
    d, ls = by.get("default"), by.get("lstsq")
    rate = next((v for v in found if v["kind"] == "rate"), None)
    if d is None or not d["at"]:
        return text
    if not _slower(d):
        return text + prose("explain.half_size.not_slower")
    if ls is not None and not _slower(ls) and rate is not None and not _slower(rate):
        return text + prose("explain.half_size.step")
    late = rate is not None and _slower(rate) and list(rate["at"].values())[-1]["low"] <= 1
    if ls is not None and not _slower(ls) and late:
        return text + prose("explain.half_size.late", epoch=rate["last_above"])
    if ls is not None and not _slower(ls):
        return text + prose("explain.half_size.features")
    if ls is not None:
        return text + prose("explain.half_size.remains")
    return text


def rises(agg: dict) -> list[dict]:
    """Per T_G under the default, rate and solver readings: the rise during growth (claims.rise,
    t interval) and the reading's rate as a multiple of the default's."""
    s, out, rate0 = agg["summary"], [], _rate0(agg)
    if "choice" not in s:
        return []
    for r in s[(s["growth"] != "none") & (s["n_trials"] > 0)].itertuples():
        if not (r.chosen or str(r.choice).startswith(("learning rate", "solver"))):
            continue
        learner = _learner(agg, r.condition)
        ep, g = claims.per_trial(agg["trials"], r.condition, "abs_error")
        out.append(dict(reading=r.variant, T_G=int(r.growth_period),
                        solver=learner.get("solver", "gradient"),
                        rate=learner["learning_rate"] / rate0 if rate0 else np.nan,
                        **explain_extent.ci(claims.rise(g[:, ep <= r.growth_period + 1]))))
    return out


def _pct(r: dict) -> str:
    return f"{100 * r['value']:+.0f} % [{100 * r['low']:+.0f}, {100 * r['high']:+.0f}]"


def rises_markdown(found: list[dict]) -> str:
    t = pd.DataFrame(found)
    periods = sorted(t["T_G"].unique())
    lines = ["| reading | " + " | ".join(f"T_G = {p:,}" for p in periods) + " |",
             "|---|" + "---|" * len(periods)]
    for reading, g in t.groupby("reading", sort=False):
        by = {r["T_G"]: r for r in g.to_dict("records")}
        lines.append(f"| {escape(reading)} ({by[g['T_G'].iloc[0]]['trials']} trials) | " + " | ".join(
            _pct(by[p]) if p in by else "" for p in periods) + " |")
    return "\n".join(lines) + "\n"


def rises_text(found: list[dict]) -> str:
    """The rise at the two longest T_G per reading, against the claim's bound."""
    t = pd.DataFrame(found)
    periods = sorted(t["T_G"].unique())[-2:]
    bound = claims.RISE

    def state(r):
        return ("above" if r["low"] > bound else "below" if r["high"] < bound
                else "not distinguishable from")
    parts, above_long = [], {}
    grad = t[t["solver"] != "lstsq"].sort_values("rate")
    for _, g in pd.concat([grad, t[t["solver"] == "lstsq"]]).groupby("reading", sort=False):
        by = {r["T_G"]: r for r in g.to_dict("records")}
        r0 = g.iloc[0]
        name = "least squares" if r0["solver"] == "lstsq" else f"{r0['rate']:.2g} / W"
        parts.append(f"{name}: " + ", ".join(f"T_G = {p:,} {_pct(by[p])}" for p in periods
                                             if p in by))
        if r0["solver"] != "lstsq" and periods[-1] in by:
            above_long[r0["rate"]] = state(by[periods[-1]])
    text = (f"rise during growth (mean over trials, 95 % t interval; the claim's bound "
            f"+{bound:.0%}): " + "; ".join(parts) + ". ")
    if len(above_long) >= 2:
        rates = sorted(above_long)
        text += (f"At T_G = {periods[-1]:,} the rise is " + ", ".join(
            f"{above_long[r]} the bound at {r:.2g} / W" for r in rates) + ".")
        if above_long[rates[-1]] == "above" and above_long[rates[0]] == "below":
            text += (f" The rise at T_G = {periods[-1]:,} falls below the bound as the rate "
                     "falls.")
    return text


def rows(aggs: dict, named: dict | None = None) -> list[dict]:
    """The explanations' rows; `named` gets the numbers the pages quote, as printed."""
    by, named = explained(), {} if named is None else named
    out = []
    fig2 = aggs.get("fig2", {}).get("models", {}).get("conditions", {})
    M, cond = next(((c["trials"]["0"]["M"], c) for c in fig2.values()
                    if c["trials"].get("0", {}).get("M") is not None), (None, None))
    if M is not None:
        out.append(_capacity(named, "fig2", "the 21 heights", cond["spec"], M, "", ".1f",
                             "explanations.fig2.capacity.best_worst_mm", "best_worst_mm"))
    if by.get("boundary") in aggs:
        b = boundary(aggs[by["boundary"]])
        named.update({name: float(f"{r['learned_mm']:.1f}") for r in b for lim, name in (
            ("+-0.9 m", "explanations.fig2.boundary.0.9m.learned_mm"),
            ("+-0.8 m", "explanations.fig2.boundary.0.8m.learned_mm")) if r["label"].startswith(lim)})
        if b:
            out.append(dict(figure="fig2", experiment=f"boundary ({by['boundary']}): learned "
                            f"on heights +-lim (21 targets, {b[0]['trials']} trials), error at "
                            "+-lim", measured="; ".join(
                                f"{r['label']}: Goal Babbling {r['learned_mm']:.1f} mm, best "
                                f"cubic {r['best_cubic_mm']:.1f} mm" for r in b)))
    full = aggs.get("fig7", {}).get("models", {}).get("conditions", {}).get("const1.0")
    if full and full["trials"]:
        out.append(_capacity(named, "fig7", "the 4 x 4 x 4 grid", full["spec"],
                             next(iter(full["trials"].values()))["M"], "const1.0 ", ".2f",
                             "explanations.fig7.capacity.best_mean_mm", "best_mean_mm"))
    k = continuation(aggs[by["continuation"]]) if by.get("continuation") in aggs else None
    if k and k["later"] <= 0:
        out.append(dict(figure="fig7", experiment=f"continuation ({by['continuation']})",
                        measured=f"the rate step at epoch {k['epoch']:,} lies beyond this run "
                                 f"({k['epoch'] + k['later']:,} epochs): nothing to compare"))
    elif k:
        named.update({name: float(f"{k[m]:.2f}") for name, m in (
            ("explanations.fig7.continuation.before_mm", "before_mm"),
            ("explanations.fig7.continuation.same_mm", "same_mm"),
            ("explanations.fig7.continuation.smaller_mm", "smaller_mm"))})
        out.append(dict(figure="fig7", experiment=f"continuation ({by['continuation']}): "
                        f"{k['later']:,} more epochs after epoch {k['epoch']:,}",
                        measured=f"{k['before_mm']:.2f} mm -> {k['same_mm']:.2f} mm at the same "
                                 f"rate, {k['smaller_mm']:.2f} mm at {k['factor']:g} x the rate "
                                 f"(mean over {k['trials']} trials)"))
    h = half_size(aggs[by["half_size"]]) if by.get("half_size") in aggs else []
    named.update(_half_size_named(h))
    if h:
        out.append(dict(figure="fig4", experiment=f"half size ({by['half_size']}): the "
                        "half-size arm against the full-size one, per variant",
                        measured=half_size_text(h)))
    r = rises(aggs[by["rise"]]) if by.get("rise") in aggs else []
    if r:
        out.append(dict(figure="fig4", experiment=f"rise ({by['rise']}): the temporary rise "
                        "during growth per T_G, rate and solver", measured=rises_text(r)))
    for explains, name, e in _extents(aggs):
        named.update(explain_extent.named(explains, e))
        out.append(explain_extent.row(explains, name, e))
    return out


def _capacity(named: dict, figure: str, grid: str, spec: dict, M, which: str, f: str,
              name: str, key: str) -> dict:
    """The capacity row: the best cubic for the figure's grid against Goal Babbling's M; `named`
    gets its `key` as `name`."""
    c = best_cubic(spec, M)
    named[name] = float(f"{c[key]:{f}}")
    return dict(figure=figure, experiment=f"capacity: the best cubic for {grid}",
                measured=f"mean {c['best_mean_mm']:{f}} mm, worst {c['best_worst_mm']:.1f} mm"
                         f" (Goal Babbling, {which}trial 0: mean {c['learned_mean_mm']:.1f} mm, "
                         f"worst {c['learned_worst_mm']:.1f} mm)")


def _extents(aggs: dict):
    by = explained()
    for explains in explain_extent.FIGURE:
        e = explain_extent.extent(aggs[by[explains]]) if by.get(explains) in aggs else None
        if e:
            yield explains, by[explains], e


def _half_size_named(found: list[dict]) -> dict:
    """The half-size numbers the pages quote, as half_size_text prints them."""
    by, out = {v["kind"]: v for v in found}, {}
    for kind, name in (("default", "explanations.fig4.half_size.default.1000.ratio"),
                       ("lstsq", "explanations.fig4.half_size.lstsq.1000.ratio")):
        if 1_000 in by.get(kind, {}).get("at", {}):
            out[name] = float(f"{by[kind]['at'][1_000]['value']:.2f}")
    rate = next((v for v in found if v["kind"] == "rate"), {})
    if rate.get("last_above"):
        out["explanations.fig4.half_size.rate.last_above_epoch"] = float(rate["last_above"])
    return out


@register("explain", 20)
def section(ctx: Context) -> list[str]:
    if not ctx.cfg.report.explain:
        return []
    aggs = {**ctx.of("figures"), **ctx.of("explain"), **ctx.of("readings")}
    named = {}
    found = rows(aggs, named)
    if not found:
        return []
    ctx.text("explanations.csv", pd.DataFrame(found).to_csv(index=False))
    for name, x in named.items():
        ctx.value(name, x)
    md = (["## Decisive experiments behind the explanations", "",
           prose("explain.section"), "",
           "| figure | experiment | measured |", "|---|---|---|"]
          + [f"| {r['figure']} | {escape(r['experiment'])} | {escape(r['measured'])} |"
             for r in found] + [""])
    md += [explain_extent.claim(name, explain_extent.FIGURE[x], e) + "\n"
           for x, name, e in _extents(aggs)]
    rise = explained().get("rise")
    r = rises(aggs[rise]) if rise in aggs else []
    if r:
        ctx.text("explain_rise.csv", pd.DataFrame(r).to_csv(index=False, float_format="%.6g"))
        ctx.quote(pd.DataFrame(r), ("reading", "T_G"), QUOTED_RISE)
        md += [f"The temporary rise during growth on Fig. 4 ({rise}, explain_rise.csv; "
               "the scorecard's measure, mean over trials with its 95 % t interval):", "",
               rises_markdown(r)]
    return md


DEFAULT = "this project's default (plain step, exact R, one batch step, grid)"
# the rises the pages quote: name -> the row's reading and T_G, its column and scale
QUOTED_RISE = {
    'explain_rise.eta_0.1_w.1000.value_pct': ('eta = 0.1 / W', 1000, 'value', 100),
    'explain_rise.this_project_s_default.1000.value_pct': (DEFAULT, 1000, 'value', 100),
    'explain_rise.this_project_s_default.10000.value_pct': (DEFAULT, 10000, 'value', 100),
    'explain_rise.this_project_s_default.10000.low_pct': (DEFAULT, 10000, 'low', 100),
    'explain_rise.this_project_s_default.10000.high_pct': (DEFAULT, 10000, 'high', 100),
    'explain_rise.eta_0.1_w.10000.value_pct': ('eta = 0.1 / W', 10000, 'value', 100),
    'explain_rise.least_squares_solver_lstsq.1000.value_pct':
        ('least squares (solver=lstsq)', 1000, 'value', 100),
    'explain_rise.least_squares_solver_lstsq.10000.value_pct':
        ('least squares (solver=lstsq)', 10000, 'value', 100),
}
