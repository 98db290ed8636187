"""The target set's extent (explain_extent_icub|arm5, read by explain.py): the paper never gives
the iCub's target set, and an absolute error scales with it. Variants x0.5 ... x1.5 of the body's
grid (same centre and points, same seeds): per variant the final errors on the grid, path targets
and uniform points (t intervals), their ratio to x1 per trial, and the exponent k of error ~
extent^k per point set."""
from __future__ import annotations

import re

import numpy as np

from .. import measures
from . import claims, scorecard
from .sections import prose

FIGURE = {"extent": "fig7", "extent_arm5": "fig4"}  # explanation (declares.explains) -> figure
WORDS = {"grid": "grid", "path": "path targets", "uniform": "uniform points"}  # as the texts say
POINTS = {WORDS[p]: col for p, col in claims.POINTS.items()}  # where it is averaged -> column
TOLERANCE = 0.2  # k within this of 1: "in proportion"; of 0: "does not change"


def factor(label: str) -> float:
    """The extent factor a variant's label starts with: "x0.5 ..." -> 0.5."""
    m = re.match(r"x(\d+(?:\.\d+)?)(?!\S)", str(label).strip())
    if not m:
        raise ValueError(f"extent variant {label!r}: its label must start with x<factor> (x0.5)")
    return float(m.group(1))


def ci(values) -> dict:
    """The mean of `values`, its 95 % t interval and their count."""
    point, low, high = scorecard.interval(np.asarray(values, float))
    return dict(value=point, low=low, high=high, trials=len(values))


def extent(agg: dict) -> dict | None:
    """Per variant (by factor) the final errors [mm] and their ratios to x1, and k per point
    set; None without x1 and another variant with trials."""
    fin = measures.finals(agg["trials"])
    per = {factor(r.variant or r.condition): fin[fin["condition"] == r.condition]
           .set_index("trial").sort_index() for r in agg["summary"].itertuples()}
    per = {f: t for f, t in sorted(per.items()) if len(t)}
    if 1.0 not in per or len(per) < 2:
        return None
    base, variants = per[1.0], []
    for f, t in per.items():
        same = t.index.intersection(base.index)
        variants.append(dict(factor=f, trials=len(t), epoch=int(t["epoch"].max()), **{
            name: dict(ci(1e3 * t[col].dropna()),
                       ratio=ci((t.loc[same, col] / base.loc[same, col]).dropna()))
            for name, col in POINTS.items()}))
    k = {}
    for name in POINTS:
        fx = np.array([(v["factor"], v[name]["value"]) for v in variants if v[name]["value"] > 0])
        k[name] = float(np.polyfit(*np.log(fx).T, 1)[0]) if len(fx) >= 2 else np.nan
    paper = agg["models"].get("paper", {}).get("final_abs_error")
    return dict(variants=variants, k=k, paper_mm=1e3 * paper if paper else np.nan)


def lowest(e: dict, name: str) -> float | None:
    """The extent where the mean final error is lowest, if strictly inside the range (no power
    of the extent describes such means); else None."""
    i = int(np.argmin([x[name]["value"] for x in e["variants"]]))
    return e["variants"][i]["factor"] if 0 < i < len(e["variants"]) - 1 else None


def scaling(k: float, low: float | None = None) -> str:
    """How the final error follows the extent, as k (or lowest(): `low`) says."""
    if low is not None:
        return f"does not rise with the extent: it is lowest at x{low:g}"
    if not np.isfinite(k):
        return "has no exponent (fewer than two extents measured)"
    k = round(k, 2) + 0.0  # as printed, never -0.00
    if abs(k - 1) <= TOLERANCE:
        return f"scales about in proportion with the extent (k = {k:.2f})"
    if abs(k) <= TOLERANCE:
        return f"does not change with the extent (k = {k:.2f})"
    return (f"scales as the extent to the power k = {k:.2f}" if k > 0
            else f"falls as the extent grows (k = {k:.2f})")


def _iv(r: dict, f: str = ".2f") -> str:
    return f"{r['value']:{f}} [{r['low']:{f}}, {r['high']:{f}}]"


def spread(e: dict, name: str) -> float:
    """The mean final error at the largest extent over that at the smallest."""
    return e["variants"][-1][name]["value"] / e["variants"][0][name]["value"]


def measured(e: dict) -> str:
    """The row's `measured`: the numbers per point set and what k says."""
    v0 = e["variants"][0]
    parts = [f"{name}: " + ", ".join(
        f"x{v['factor']:g} {_iv(v[name])}" + ("" if v["factor"] == 1 else
                                              f" ({_iv(v[name]['ratio'])} of x1)")
        for v in e["variants"]) + f"; the final error {scaling(e['k'][name], lowest(e, name))}"
        for name in POINTS]
    return (f"final error at epoch {v0['epoch']:,} in mm (mean over {v0['trials']} trials, 95 % "
            "t interval; the ratio to x1 per trial on the same seeds): " + "; ".join(parts) + ".")


def row(explains: str, experiment: str, e: dict) -> dict:
    return dict(figure=FIGURE[explains], experiment=f"target-set extent ({experiment}): the "
                "body's grid at " + ", ".join(f"x{v['factor']:g}" for v in e["variants"])
                + " of its extent (same centre and points, same seeds)", measured=measured(e))


NAMED = {"fig7": ("explanations.fig7.extent.path.k", "explanations.fig7.extent.path.spread",
                  "explanations.fig7.extent.path.ratio_x0.5"),
         "fig4": ("explanations.fig4.extent.path.k", "explanations.fig4.extent.path.spread",
                  "explanations.fig4.extent.path.ratio_x0.5")}


def named(explains: str, e: dict) -> dict:
    """The numbers the pages quote, as printed: on the path targets, k, the spread and the
    smallest extent's ratio to x1."""
    k, spread_, ratio = NAMED[FIGURE[explains]]
    v0, name = e["variants"][0], "path targets"
    out = {k: e["k"][name], spread_: spread(e, name)}
    if v0["factor"] == 0.5:  # the name says the extent it is at
        out[ratio] = v0[name]["ratio"]["value"]
    return {n: float(f"{x:.2f}") for n, x in out.items() if np.isfinite(x)}


def claim(experiment: str, figure: str, e: dict) -> str:
    """The report's sentence beside the paper's absolute error: how far the extent moves it."""
    lo, hi, mm = e["variants"][0]["factor"], e["variants"][-1]["factor"], e["paper_mm"]
    paper = ("its absolute error" if not np.isfinite(mm) else f"{mm / 10:g} cm" if mm % 10 == 0
             else f"{mm:g} mm")
    low = lowest(e, "path targets")
    if low is not None:
        at = ", ".join(f"x{v['factor']:g} {v['path targets']['value']:.1f} mm"
                       for v in e["variants"])
        return prose("extent.not_a_scale", fig=figure[3:], paper=paper, at=at,
                     experiment=experiment, low=low)
    by = ", ".join(f"{spread(e, name):.2f} x on the {name}" for name in POINTS)
    return prose("extent.scale", fig=figure[3:], paper=paper, lo=lo, hi=hi, by=by,
                 experiment=experiment)
