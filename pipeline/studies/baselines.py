"""Beyond the paper: Goal Babbling against its alternatives under growth (the experiments
baselines_arm5|icub, variants "<learner>, <budget>, <growth>"), judged on the held-out error: final
errors with t intervals, curves, exploration compared between learners that fit alike (p_beats),
"void after growth", smoothness, and the paper's other arguments answered with numbers."""
from __future__ import annotations

import numpy as np
import pandas as pd
from scipy import stats
from scipy.optimize import brentq

from . import figures
from ..measures import finals
from .choices import escape
from .sections import Context, of_study, prose, register

GB, GB_PROGRESS = "Goal Babbling", "Goal Babbling (goals by progress)"
GB_LSTSQ = "Goal Babbling (least squares)"  # learner.solver=lstsq: fits M like motor babbling
ONLINE, ONLINE_PROGRESS = "online Goal Babbling", "online Goal Babbling (goals by progress)"
MB, MB_WIDE = "motor babbling", "motor babbling over the whole joint range"
MEMORY, MEMORY_ALL = "example memory", "example memory keeping everything"
LEARNERS = (GB, GB_PROGRESS, GB_LSTSQ, ONLINE, ONLINE_PROGRESS, MB, MB_WIDE, MEMORY, MEMORY_ALL)
GROWTHS = ("no growth", "linear", "infant")
FACTOR = 1.5  # "fails" / "degrades": an error this many times the comparison's, fixed beforehand
# a final inverse whose largest joint-space step between neighbouring targets (1/200 of the box
# apart) exceeds this is discontinuous: a smooth inverse sweeping a joint range of pi over the box
# moves pi/200 = 0.016 per step, so 0.1 is six such steps at once (fixed beforehand)
JUMP = 0.1
SAME_SOLVER = (MB, MB_WIDE)  # fitted by least squares, as Goal Babbling (least squares)
STYLE = {GB_LSTSQ: "--"}  # the figure's line style where not solid
# why two rows can be identical to the last bit (common random numbers: a condition's random
# stream depends on the body and the growth pattern, start, end and period, not on the schedule)
IDENTICAL = {
    MB: "its fit uses the examples of the last 10 epochs only, all drawn after growth ended "
        "(growth takes the first half of the budget), around home, from the same random numbers "
        "under both schedules: the same examples, the same fit",
    MB_WIDE: "as motor babbling around home: the last 10 epochs' examples, after growth, with "
             "the same random numbers",
}


def cell(variant: str, growth: str) -> dict:
    """learner, budget and growth ("no growth" for a summary's growth "none") of a variant."""
    learner, budget, schedule = variant.rsplit(", ", 2)
    return dict(learner=learner, budget=budget,
                growth="no growth" if growth == "none" else schedule)


def interval(mean: float, std: float, n: int) -> tuple[float, float]:
    """95 % Student's t interval of a mean over n trials (NaN with fewer than 2)."""
    if n < 2 or not np.isfinite(std):
        return np.nan, np.nan
    h = stats.t.ppf(0.975, n - 1) * std / np.sqrt(n)
    return float(mean - h), float(mean + h)


def p_beats(a, b) -> tuple[float, float, float]:
    """(P, lo, hi): P(A < B) over all n m pairs of trials (ties count half: Mann-Whitney U /
    (n m)) and its 95 % interval by Newcombe's method 5 (Statist. Med. 25: 559-573, 2006): {theta
    : (theta - P)^2 <= z^2 V(theta)}, Hanley and McNeil's V(theta) = theta (1 - theta) / (n m) [1 +
    (N - 1)(1 - theta) / (2 - theta) + (N - 1) theta / (1 + theta)], N = (n + m) / 2. At 5 trials
    a learner it stays in [0, 1] and keeps an interval at P = 1 (a bootstrap collapses to [1, 1],
    a Wald interval leaves [0, 1]). NaN where either learner has no finite trial."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    a, b = a[np.isfinite(a)], b[np.isfinite(b)]
    n, m = len(a), len(b)
    if not n or not m:
        return np.nan, np.nan, np.nan
    d = a[:, None] - b[None, :]
    p = float(((d < 0) + 0.5 * (d == 0)).mean())
    z2, k = stats.norm.ppf(0.975) ** 2, (n + m) / 2 - 1

    def w(x):  # V(x) n m / (x (1 - x))
        return (1 + k * (1 - x) / (2 - x) + k * x / (1 + x)) / (n * m)

    def far(q):  # the limit away from q in {0, 1}: (x - q)^2 = z^2 V(x), divided by |x - q|
        return lambda x: abs(x - q) - z2 * (1 - abs(x - q)) * w(x)

    if p == 1.0:
        return p, brentq(far(1.0), 0.0, 1.0), 1.0
    if p == 0.0:
        return p, 0.0, brentq(far(0.0), 0.0, 1.0)

    def f(x):
        return (x - p) ** 2 - z2 * x * (1 - x) * w(x)

    return p, brentq(f, 0.0, p), brentq(f, p, 1.0)


def per_trial(aggs: dict) -> pd.DataFrame:
    """One row per finished trial: its final held-out error [mm] and largest jump (NaN: none)."""
    rows = []
    for study in of_study("baselines"):
        agg = aggs.get(study, {})
        if "trials" not in agg or not len(agg["trials"]):
            continue
        labels = agg["summary"].set_index("condition")
        models = agg.get("models", {}).get("conditions", {})
        for r in finals(agg["trials"]).itertuples():
            c = labels.loc[r.condition]
            model = models.get(r.condition, {}).get("trials", {}).get(str(r.trial), {})
            rows.append(dict(body=c.body, **cell(c.variant, c.growth),
                             trial=int(r.trial), heldout_mm=1e3 * r.heldout_abs_error,
                             largest_jump=float(model.get("largest_jump", np.nan))))
    return pd.DataFrame(rows, columns=["body", "learner", "budget", "growth", "trial",
                                       "heldout_mm", "largest_jump"])


def _rows(t: pd.DataFrame, body, learner, growth, budget) -> pd.DataFrame:
    return t[(t.body == body) & (t.learner == learner) & (t.growth == growth)
             & (t.budget == budget)]


def _errors(pt: pd.DataFrame, *cell) -> np.ndarray:
    return _rows(pt, *cell)["heldout_mm"].to_numpy(float)


def same_solver(pt: pd.DataFrame) -> pd.DataFrame:
    """Goal Babbling (least squares) against each motor babbling (the same fit: a comparison of
    exploration) wherever both ran: medians over trials and P(GB_LSTSQ < rival) (p_beats)."""
    rows = []
    for (body, budget, growth), g in pt.groupby(["body", "budget", "growth"], sort=False):
        a = _errors(g, body, GB_LSTSQ, growth, budget)
        for rival in SAME_SOLVER:
            b = _errors(g, body, rival, growth, budget)
            if not len(a) or not len(b):
                continue
            p, lo, hi = p_beats(a, b)
            rows.append(dict(body=body, budget=budget, growth=growth, rival=rival,
                             gb_median_mm=float(np.median(a)), rival_median_mm=float(np.median(b)),
                             gb_trials=len(a), rival_trials=len(b), p=p, p_lo=lo, p_hi=hi,
                             verdict="not measured" if not np.isfinite(p) else
                             f"{GB_LSTSQ} lower" if lo > 0.5 else f"{rival} lower" if hi < 0.5
                             else "no difference measured"))
    cols = ["body", "budget", "growth", "rival", "gb_median_mm", "rival_median_mm", "gb_trials",
            "rival_trials", "p", "p_lo", "p_hi", "verdict"]
    return pd.DataFrame(rows, columns=cols)


VOID, CONTROL = (prose(f"baselines.{k}", factor=FACTOR) for k in ("void", "control"))


def void_after_growth(pt: pd.DataFrame) -> list[dict]:
    """"Void after growth" on the memory keeping everything (pre-growth examples: it can fail),
    the 10-epoch memory as its control: grown trials against no-growth ones."""
    out = []
    cells = [(body, budget, learner, argument, g) for body in dict.fromkeys(pt["body"])
             for budget in dict.fromkeys(pt.loc[pt.body == body, "budget"])
             for learner, argument in ((MEMORY_ALL, VOID), (MEMORY, CONTROL))
             for g in ("linear", "infant")]
    for body, budget, learner, argument, g in cells:
        fixed, grown = (_errors(pt, body, learner, x, budget) for x in ("no growth", g))
        if not len(fixed) or not len(grown):
            continue
        p, lo, hi = p_beats(fixed, grown)
        ratio = np.median(grown) / np.median(fixed)
        if learner == MEMORY_ALL:
            answer = ("no" if ratio <= FACTOR else "yes" if lo > 0.5 else "inconclusive: the "
                      "medians differ, but the interval of P reaches 1/2 (overlapping or too few "
                      "trials)")
        else:
            answer = ("yes (it does not degrade)" if ratio <= FACTOR
                      else "no: the control degrades, so the setup is in question")
        out.append(dict(body=body, budget=budget, argument=argument,
                        measured=f"{g}: median {np.median(grown):.1f} mm against "
                                 f"{np.median(fixed):.1f} mm without growth ({ratio:.2f}x; "
                                 f"{len(grown)} and {len(fixed)} trials); P(no growth < {g}) = "
                                 f"{p:.2f} [{lo:.2f}, {hi:.2f}]", answer=answer))
    return out


# what a learner's inverse is, for the sentence on its smoothness
KIND = {**dict.fromkeys((GB, GB_PROGRESS, ONLINE, ONLINE_PROGRESS),
                        "a polynomial fitted by gradient steps"),
        **dict.fromkeys((GB_LSTSQ, MB, MB_WIDE), "a polynomial fitted by least squares"),
        **dict.fromkeys((MEMORY, MEMORY_ALL), "a lookup of stored examples")}


def smoothness(t: pd.DataFrame) -> list[str]:
    """Per learner, what its final inverse's largest jump (the table's column) means for a robot."""
    out = []
    for learner in LEARNERS:
        rows = t[t.learner == learner]
        j = rows["largest_jump"].dropna()
        if not len(j):
            continue
        where = f"({KIND[learner]}; {len(j)} rows, budgets {', '.join(dict.fromkeys(rows.budget))})"
        out.append(prose("baselines.jumps" if j.max() > JUMP else "baselines.smooth",
                         learner=learner, where=where, most=j.max(), least=j.min(), jump=JUMP))
    return out


def table(aggs: dict) -> pd.DataFrame:
    """One row per (body, learner, budget, growth): final errors on the grid and held out."""
    rows = []
    for study in (s for s in of_study("baselines") if s in aggs):
        for r in aggs[study]["summary"].itertuples():
            lo, hi = interval(r.final_heldout_abs_error_mean, r.final_heldout_abs_error_std,
                              r.n_trials)
            rows.append(dict(body=r.body, **cell(r.variant, r.growth), samples=r.final_samples,
                             trials=r.n_trials, diverged=r.n_diverged,
                             grid_mm=1e3 * r.final_abs_error_mean,
                             heldout_mm=1e3 * r.final_heldout_abs_error_mean,
                             heldout_std_mm=1e3 * r.final_heldout_abs_error_std,
                             heldout_lo_mm=1e3 * lo, heldout_hi_mm=1e3 * hi,
                             final_rel_mm=1e3 * r.final_rel_error_mean,
                             largest_jump=r.largest_jump_mean, condition=r.condition,
                             growth_period=r.growth_period, figure=study))
    return pd.DataFrame(rows)


def budgets(t: pd.DataFrame, body: str) -> list[str]:
    """The body's budgets, smallest first."""
    return list(t[t.body == body].groupby("budget")["samples"].max().sort_values().index)


def _row(t, *cell):
    sel = _rows(t, *cell)
    return sel.iloc[0] if len(sel) else None


def _err(t, *cell) -> float:
    r = _row(t, *cell)
    return float(r.heldout_mm) if r is not None else np.nan


def _mm(t, *cell) -> str:
    r = _row(t, *cell)
    if r is None:
        return "not run"
    ci = f" [{r.heldout_lo_mm:.1f}, {r.heldout_hi_mm:.1f}]" if np.isfinite(r.heldout_lo_mm) else ""
    return f"{r.heldout_mm:.1f}{ci} mm"


def _answer(holds: bool, *numbers) -> str:
    return "not measured" if not np.all(np.isfinite(numbers)) else "yes" if holds else "no"


def _compare(a, b) -> str:
    """a against b by their 95 % intervals: lower, higher, or no difference measured."""
    if a is None or b is None or not np.isfinite([a.heldout_mm, b.heldout_mm]).all():
        return "not measured"
    if a.heldout_hi_mm < b.heldout_lo_mm:
        return "yes"
    if a.heldout_lo_mm > b.heldout_hi_mm:
        return "no (worse)"
    return "no difference measured"


def claims(t: pd.DataFrame, pt: pd.DataFrame | None = None) -> list[dict]:
    """The paper's arguments about the alternatives (sec. 1-2), answered with held-out numbers;
    pt: per_trial's frame, for the void test."""
    out, bodies = [], list(dict.fromkeys(t["body"]))
    cells = [(body, budget) for body in bodies for budget in budgets(t, body)]
    for body, budget in cells:
        mb, gb = (_err(t, body, x, "no growth", budget) for x in (MB_WIDE, GB_LSTSQ))
        if not np.isfinite(mb) or not np.isfinite(gb):
            continue
        out.append(dict(body=body, budget=budget,
                        argument=prose("baselines.redundancy", factor=FACTOR),
                        measured=f"motor babbling {_mm(t, body, MB_WIDE, 'no growth', budget)}"
                                 f" (around home {_mm(t, body, MB, 'no growth', budget)}), "
                                 f"{GB_LSTSQ} {_mm(t, body, GB_LSTSQ, 'no growth', budget)}",
                        answer=_answer(mb > FACTOR * gb, mb, gb)))
    if len(bodies) == 2:
        def both(b, x):
            return [_err(t, b, MB_WIDE, "no growth", x), _err(t, b, GB_LSTSQ, "no growth", x)]
        # each body's smallest budget where both learners ran without growth
        first = {b: next((x for x in budgets(t, b) if np.isfinite(both(b, x)).all()), None)
                 for b in bodies}
        ratios = {b: both(b, first[b])[0] / both(b, first[b])[1] if first[b] else np.nan
                  for b in bodies}
        out.append(dict(body=" and ".join(bodies), budget=", ".join(map(str, first.values())),
                        argument=prose("baselines.joints", gb=GB_LSTSQ),
                        measured=", ".join(f"{b}: {r:.2f}x" for b, r in ratios.items()),
                        answer=_answer(ratios[bodies[1]] > ratios[bodies[0]], *ratios.values())))
    out += void_after_growth(pt if pt is not None else per_trial({}))
    for (body, budget), learner in ((c, x) for c in cells for x in (GB, GB_LSTSQ)):
        fixed = _err(t, body, learner, "no growth", budget)
        grown = {g: _err(t, body, learner, g, budget) for g in ("linear", "infant")}
        grown = {g: v for g, v in grown.items() if np.isfinite(v)}
        if not np.isfinite(fixed) or not grown:
            continue
        out.append(dict(body=body, budget=budget,
                        argument=prose("baselines.keeps", learner=learner, factor=FACTOR),
                        measured=f"no growth {_mm(t, body, learner, 'no growth', budget)}; "
                                 + ", ".join(f"{g} {_mm(t, body, learner, g, budget)} "
                                             f"({v / fixed:.2f}x)" for g, v in grown.items()),
                        answer=_answer(max(grown.values()) <= FACTOR * fixed, fixed,
                                       *grown.values())))
    for (body, budget), (base, progress) in ((c, x) for c in cells for x in (
            (GB, GB_PROGRESS), (ONLINE, ONLINE_PROGRESS))):
        pairs = {g: (_row(t, body, progress, g, budget), _row(t, body, base, g, budget))
                 for g in GROWTHS}
        if all(p is None for p, _ in pairs.values()):
            continue
        out.append(dict(body=body, budget=budget, argument=prose("baselines.progress", base=base),
                        measured="; ".join(f"{g}: {_mm(t, body, progress, g, budget)} against "
                                           f"{_mm(t, body, base, g, budget)}" for g in GROWTHS),
                        answer=", ".join(f"{g} {_compare(*pairs[g])}" for g in GROWTHS)))
    return out


def identical_rows(t: pd.DataFrame) -> list[str]:
    """Notes on rows whose held-out error is identical after linear and infant growth."""
    notes = []
    for (body, learner, budget), g in t.groupby(["body", "learner", "budget"], sort=False):
        v = g.set_index("growth")["heldout_mm"]
        if {"linear", "infant"} <= set(v.index) and v["linear"] == v["infant"]:
            short = g.set_index("growth")["growth_period"]["linear"] <= 1
            why = ("growth lasts a single epoch at this scale: both schedules are the same body"
                   if short else IDENTICAL.get(learner, "not expected: a finding to look into"))
            notes.append(f"- {body}, {learner}, {budget}: linear and infant growth give the same "
                         f"{v['linear']:.4f} mm; {why}.")
    return notes


def same_solver_summary(ss: pd.DataFrame) -> list[str]:
    """Sentences generated from the same-solver comparisons, one per body and rival."""
    out = []
    for (body, rival), g in ss.groupby(["body", "rival"], sort=False):
        won = g[g.verdict == f"{GB_LSTSQ} lower"]
        lost = g[g.verdict == f"{rival} lower"]
        out.append(f"- {body}, against {rival} (budgets {', '.join(dict.fromkeys(g.budget))}; "
                   f"{len(g)} comparisons over budgets and growths): {GB_LSTSQ} ends lower in "
                   f"{len(won)}, {rival} in {len(lost)}, no difference measured in "
                   f"{len(g) - len(won) - len(lost)}; P ranges {g.p.min():.2f} to "
                   f"{g.p.max():.2f}.")
    return out


def markdown(t: pd.DataFrame, claim_rows: list[dict], pt: pd.DataFrame | None = None) -> str:
    lines = [prose("baselines.intro"), "", "| body | budget | learner | growth | samples | trials "
             "| held-out error [mm] (95 % interval) | grid error [mm] | final rel. error "
             "[mm/size] | largest jump [command units] |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    order = {k: i for i, k in enumerate(LEARNERS)}
    t = t.assign(_l=t.learner.map(order), _g=t.growth.map({g: i for i, g in enumerate(GROWTHS)}),
                 _b=t.samples.groupby([t.body, t.budget]).transform("max"))
    for r in t.sort_values(["body", "_b", "_l", "_g"], kind="stable").itertuples():
        held = f"{r.heldout_mm:.1f} ± {r.heldout_std_mm:.1f}"
        if np.isfinite(r.heldout_lo_mm):
            held += f" [{r.heldout_lo_mm:.1f}, {r.heldout_hi_mm:.1f}]"
        if r.diverged:
            held += f" ({r.diverged} diverged)"
        lines.append(f"| {r.body} | {r.budget} | {r.learner} | {r.growth} | {r.samples:,} "
                     f"| {r.trials} | {held} | {r.grid_mm:.1f} | {r.final_rel_mm:.1f} "
                     f"| {r.largest_jump:.3g} |")
    ss = same_solver(pt if pt is not None else per_trial({}))
    if len(ss):
        lines += ["", prose("baselines.same_solver", gb=GB_LSTSQ), "", f"| body | budget | growth | against "
                  f"| median {GB_LSTSQ} [mm] | median rival [mm] | trials | P [95 % interval] "
                  "| lower |", "|---|---|---|---|---|---|---|---|---|"]
        lines += [f"| {r.body} | {r.budget} | {r.growth} | {r.rival} | {r.gb_median_mm:.1f} "
                  f"| {r.rival_median_mm:.1f} | {r.gb_trials} and {r.rival_trials} "
                  f"| {r.p:.2f} [{r.p_lo:.2f}, {r.p_hi:.2f}] | {r.verdict} |"
                  for r in ss.itertuples()]
        lines += [""] + same_solver_summary(ss)
    smooth = smoothness(t)
    if smooth:
        lines += ["", "Smoothness of the final inverse (the table's largest jump, the mean over "
                  "trials, over every budget and growth a learner ran):", ""] + smooth
    lines += ["", "| body | budget | the argument | measured (held-out) | holds? |",
              "|---|---|---|---|---|"]
    lines += [f"| {c['body']} | {c['budget']} | {escape(c['argument'])} "
              f"| {escape(c['measured'])} | {c['answer']} |" for c in claim_rows]
    notes = identical_rows(t)
    if notes:
        lines += ["", "Identical rows:", ""] + notes
    return "\n".join(lines) + "\n"


def figure(aggs: dict, title: str):
    """Mean held-out error against samples: one panel per body and growth, a line per learner at
    its largest budget (every learner on the same axis)."""
    studies = [s for s in of_study("baselines") if s in aggs]
    fig, axes = figures.plt.subplots(len(studies), 3, squeeze=False, sharey="row",
                                     figsize=(9.0, 2.8 * len(studies)))
    colors = dict(zip(LEARNERS, figures.plt.get_cmap("tab10")(np.arange(len(LEARNERS)))))
    for i, s in enumerate(studies):
        summ, curves = aggs[s]["summary"], aggs[s]["curves"]
        largest = summ.assign(learner=[cell(v, "")["learner"] for v in summ["variant"]]) \
            .groupby("learner")["final_samples"].transform("max")
        for r, top in zip(summ.itertuples(), largest):
            if r.final_samples != top:
                continue
            learner, _, growth = cell(r.variant, r.growth).values()
            ax = axes[i, GROWTHS.index(growth)]
            cu = curves[curves["condition"] == r.condition].sort_values("samples")
            ax.plot(cu["samples"], cu["heldout_abs_error_mean"], color=colors.get(learner),
                    lw=1.2, ls=STYLE.get(learner, "-"), label=learner)
        for j, g in enumerate(GROWTHS):
            axes[i, j].set(xscale="log", yscale="log", title=f"{summ['body'].iloc[0]}, {g}",
                           xlabel="samples (reaching movements)")
        axes[i, 0].set_ylabel("held-out error [m]")
    handles = {}
    for ax in axes.flat:  # one entry per learner, whichever panels it is drawn in
        for h, label in zip(*ax.get_legend_handles_labels()):
            handles.setdefault(label, h)
    fig.suptitle(title)
    figures.legend_below(fig, list(handles.values()), 2.8 * len(studies), max_cols=3)
    return fig


@register("baselines", 40)
def section(ctx: Context) -> list[str]:
    rivals = ctx.of("baselines")
    rival_table = table(rivals)
    if not len(rival_table):
        return []
    trials = per_trial(rivals)
    rival_claims = claims(rival_table, trials)
    ss = same_solver(trials)
    ctx.text("baselines_same_solver.csv", ss.to_csv(index=False, float_format="%.6g"))
    ctx.text("baselines.csv", rival_table.to_csv(index=False, float_format="%.6g"))
    ctx.quote(ss, ("body", "budget", "growth", "rival"), QUOTED_SAME_SOLVER)
    ctx.quote(rival_table, ("body", "learner", "budget", "growth"), QUOTED)
    png = ctx.save(figure(rivals, "Goal Babbling and its alternatives: error against reaching "
                          "movements"), "baselines_curves")[0].name
    return ["## Beyond the paper: Goal Babbling against its alternatives under growth", "",
            prose("baselines.section"), "",
            f"![baselines]({png})", "", markdown(rival_table, rival_claims, trials)]


# the numbers the pages quote (docs/baselines.md, findings.md): name -> the row's body, learner
# (rival), budget, growth and column
QUOTED = {'baselines.arm5.goal_babbling.4.24m.linear.grid_mm':
          ('arm5', 'Goal Babbling', '4.24M', 'linear', 'grid_mm')}
QUOTED_SAME_SOLVER = {
    'baselines_same_solver.icub.6.02m.infant.motor_babbling_over_the.p_lo':
        ('icub', '6.02M', 'infant', 'motor babbling over the whole joint range', 'p_lo'),
    'baselines_same_solver.arm5.1.06m.no_growth.motor_babbling.gb_median_mm':
        ('arm5', '1.06M', 'no growth', 'motor babbling', 'gb_median_mm'),
    'baselines_same_solver.arm5.1.06m.no_growth.motor_babbling.rival_median_mm':
        ('arm5', '1.06M', 'no growth', 'motor babbling', 'rival_median_mm'),
    'baselines_same_solver.icub.1.505m.no_growth.motor_babbling.gb_median_mm':
        ('icub', '1.505M', 'no growth', 'motor babbling', 'gb_median_mm'),
    'baselines_same_solver.icub.1.505m.no_growth.motor_babbling.rival_median_mm':
        ('icub', '1.505M', 'no growth', 'motor babbling', 'rival_median_mm'),
}
