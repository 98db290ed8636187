"""Decisive experiments behind the report's explanations, read from their aggregates.

The experiments are experiments of the plan (conf/experiment/explain_*.yaml), simulated and
cached like any other; this module only reads their final models and curves (and fits a cubic,
which trains nothing), so the report stage starts no trial:
- capacity: the best degree-3 polynomial inverse for a body's target grid, fitted directly to
  the forward kinematics (least squares on the reaching errors, started from a learned M): the
  error a cubic *can* reach, against what Goal Babbling reaches;
- boundary (Fig. 2, explain_fig2_boundary): the 2-DOF arm learned on heights +-1 m (the
  stretched arm, where w_eff -> 0 and disturbed examples only land inside) against the same arm
  learned on +-0.9 and +-0.8 m;
- continuation (iCub, explain_fig7_continuation): 100,000 epochs at the rate, then 1,000 more at
  the rate and at a tenth of it: a model still improving at a smaller rate is limited by the
  rate's noise.
"""
from __future__ import annotations

import numpy as np
from scipy.optimize import least_squares

from gbmodel.growth import factors

from .figures import final_body


def _errors(body, size, pattern, predict, M, xs):
    q = predict(M, xs)
    return np.linalg.norm(body.forward(q, factors(body, size, pattern)) - xs, axis=-1)


def best_cubic(spec: dict, M0) -> dict:
    """The degree-3 inverse fitted directly to the targets (scipy least squares from M0)."""
    body, size, pattern, predict = final_body(spec)
    xs = body.target_set(size)
    M0 = np.asarray(M0, float)

    def residuals(flat):
        q = predict(flat.reshape(M0.shape), xs)
        return (body.forward(q, factors(body, size, pattern)) - xs).ravel()

    fit = least_squares(residuals, M0.ravel(), method="trf", max_nfev=200 * M0.size)
    d = _errors(body, size, pattern, predict, fit.x.reshape(M0.shape), xs)
    learned = _errors(body, size, pattern, predict, M0, xs)
    return dict(M=fit.x.reshape(M0.shape), best_mean_mm=1e3 * d.mean(), best_worst_mm=1e3 * d.max(),
                learned_mean_mm=1e3 * learned.mean(), learned_worst_mm=1e3 * learned.max())


def _extremes(spec, M) -> float:
    body, size, pattern, predict = final_body(spec)
    d = _errors(body, size, pattern, predict, np.asarray(M, float), body.target_set(size))
    return 1e3 * float(max(d[0], d[-1]))


STUDIES = ("explain_fig2_boundary", "explain_fig7_continuation")


def _variants(agg: dict):
    """(variant label, condition's models entry, its curve) for each condition of an aggregate."""
    conds = agg["models"]["conditions"]
    for r in agg["summary"].itertuples():
        cu = agg["curves"][agg["curves"]["condition"] == r.condition].sort_values("epoch")
        yield r.variant or r.condition, conds[r.condition], cu


def boundary(agg: dict) -> list[dict]:
    """explain_fig2_boundary: for each target range, the error at the two extreme targets of
    Goal Babbling and of the best cubic for that range, mean over the trials."""
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
    """explain_fig7_continuation: the mean absolute error over trials before the rate step (the
    last evaluation at or before it) and at the end, at the same rate and at the smaller one."""
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


def rows(aggs: dict) -> list[dict]:
    """The explanation experiments that the aggregated figures allow (reads only)."""
    out = []
    fig2 = aggs.get("fig2", {}).get("models", {}).get("conditions", {})
    for cond in fig2.values():
        M = cond["trials"].get("0", {}).get("M")
        if M is None:
            continue
        c = best_cubic(cond["spec"], M)
        out.append(dict(figure="fig2", experiment="capacity: the best cubic for the 21 heights",
                        measured=f"mean {c['best_mean_mm']:.1f} mm, worst {c['best_worst_mm']:.1f} mm"
                                 f" (Goal Babbling, trial 0: mean {c['learned_mean_mm']:.1f} mm, "
                                 f"worst {c['learned_worst_mm']:.1f} mm)"))
        break
    if "explain_fig2_boundary" in aggs:
        b = boundary(aggs["explain_fig2_boundary"])
        if b:
            out.append(dict(figure="fig2", experiment="boundary (explain_fig2_boundary): learned "
                            f"on heights +-lim (21 targets, {b[0]['trials']} trials), error at "
                            "+-lim", measured="; ".join(
                                f"{r['label']}: Goal Babbling {r['learned_mm']:.1f} mm, best "
                                f"cubic {r['best_cubic_mm']:.1f} mm" for r in b)))
    fig7 = aggs.get("fig7", {}).get("models", {}).get("conditions", {})
    full = next((c for name, c in fig7.items() if name == "const1.0"), None)
    if full and full["trials"]:
        models = [t["M"] for t in full["trials"].values()]
        c = best_cubic(full["spec"], models[0])
        out.append(dict(figure="fig7", experiment="capacity: the best cubic for the 4 x 4 x 4 grid",
                        measured=f"mean {c['best_mean_mm']:.2f} mm, worst {c['best_worst_mm']:.1f} mm"
                                 f" (Goal Babbling, const1.0 trial 0: mean "
                                 f"{c['learned_mean_mm']:.1f} mm, worst {c['learned_worst_mm']:.1f} mm)"))
    k = continuation(aggs["explain_fig7_continuation"]) if "explain_fig7_continuation" in aggs \
        else None
    if k and k["later"] <= 0:
        out.append(dict(figure="fig7", experiment="continuation (explain_fig7_continuation)",
                        measured=f"the rate step at epoch {k['epoch']:,} lies beyond this run "
                                 f"({k['epoch'] + k['later']:,} epochs): nothing to compare"))
    elif k:
        out.append(dict(figure="fig7", experiment="continuation (explain_fig7_continuation): "
                        f"{k['later']:,} more epochs after epoch {k['epoch']:,}",
                        measured=f"{k['before_mm']:.2f} mm -> {k['same_mm']:.2f} mm at the same "
                                 f"rate, {k['smaller_mm']:.2f} mm at {k['factor']:g} x the rate "
                                 f"(mean over {k['trials']} trials)"))
    return out
