"""Decisive experiments behind the report's explanations, run by the report stage.

Each function takes aggregated results (final models of the paper's figures) and returns rows
(what, measured) that report.md prints; nothing here is prose about a particular run:
- capacity: the best degree-3 polynomial inverse for a body's target grid, fitted directly to
  the forward kinematics (least squares on the reaching errors, started from a learned M): the
  error a cubic *can* reach, against what Goal Babbling reaches;
- boundary (Fig. 2): the 2-DOF arm learned on heights +-1 m (the stretched arm, where w_eff -> 0
  and disturbed examples only land inside) against the same arm learned on +-0.9 m;
- continuation (iCub): the learned models continued for 1,000 epochs at the learning rate and
  at a tenth of it: a model still improving at a smaller rate is limited by the rate's noise.
"""
from __future__ import annotations

import numpy as np
from scipy.optimize import least_squares

import gbmodel
from gbmodel.learners import goal_babbling as gb

from .figures import final_body


def _errors(body, size, pattern, exps, M, xs):
    q = gbmodel.predict(M, xs, exps)
    return np.linalg.norm(body.forward(q, size, pattern) - xs, axis=-1)


def best_cubic(spec: dict, M0) -> dict:
    """The degree-3 inverse fitted directly to the targets (scipy least squares from M0)."""
    body, size, pattern, exps = final_body(spec)
    xs = body.target_set(size)
    M0 = np.asarray(M0, float)

    def residuals(flat):
        q = gbmodel.predict(flat.reshape(M0.shape), xs, exps)
        return (body.forward(q, size, pattern) - xs).ravel()

    fit = least_squares(residuals, M0.ravel(), method="trf", max_nfev=200 * M0.size)
    d = _errors(body, size, pattern, exps, fit.x.reshape(M0.shape), xs)
    learned = _errors(body, size, pattern, exps, M0, xs)
    return dict(M=fit.x.reshape(M0.shape), best_mean_mm=1e3 * d.mean(), best_worst_mm=1e3 * d.max(),
                learned_mean_mm=1e3 * learned.mean(), learned_worst_mm=1e3 * learned.max())


def _extremes(spec, M) -> float:
    body, size, pattern, exps = final_body(spec)
    d = _errors(body, size, pattern, exps, np.asarray(M, float), body.target_set(size))
    return 1e3 * float(max(d[0], d[-1]))


def boundary(spec: dict, limits=(1.0, 0.9, 0.8), seeds=(0, 1, 2)) -> list[dict]:
    """Fig. 2's arm learned on heights -lim ... +lim (21 targets) for each limit: the error at
    the two extreme targets, of Goal Babbling and of the best cubic for that grid (mean over
    seeds). If the learner's excess over the best cubic vanishes away from the stretched arm, the
    miss is Goal Babbling at the workspace boundary, not what a cubic can represent."""
    out = []
    for lim in limits:
        s = dict(spec, body=dict(spec["body"], grid=dict(lo=[-lim], hi=[lim], num=[21])),
                 snapshots=[])
        learned, best = [], []
        for seed in seeds:
            M = gbmodel.run_trial(gbmodel.TrialSpec.from_dict(s), np.random.default_rng(seed)).M
            learned.append(_extremes(s, M))
            best.append(_extremes(s, best_cubic(s, M)["M"]))
        out.append(dict(limit_m=lim, learned_mm=float(np.mean(learned)),
                        best_cubic_mm=float(np.mean(best))))
    return out


def continuation(spec: dict, models: list, epochs: int = 1000, factor: float = 0.1,
                 seed: int = 0) -> dict:
    """Continue each learned model for `epochs` epochs at full size, at its learning rate and
    at `factor` times it (the same draws); mean error before and after."""
    s = gbmodel.TrialSpec.from_dict(spec)
    body, growth = s.make_body(), s.make_growth()
    learner, params = s.make_learner()
    size = growth.end_size
    sizes = np.full(epochs, size)
    later = np.arange(1, epochs + 1)  # the epochs after the trial's last
    scales = growth.scales(body, sizes)
    out = {"before_mm": [], "same_mm": [], "smaller_mm": []}
    for i, M in enumerate(models):
        M = np.asarray(M, float)
        rng = np.random.default_rng([seed, i])
        draws = learner.draw(params, body, epochs, rng)
        for key, p in (("same_mm", params),
                       ("smaller_mm", gb.Params(**{**params.__dict__,
                                                   "learning_rate": params.learning_rate * factor}))):
            M1 = learner.train(M, p, body, sizes, scales, draws, s.epochs + later)
            out[key].append(1e3 * gbmodel.evaluation.evaluate(learner, M1, p, body, size,
                                                              scales[-1]))
        out["before_mm"].append(1e3 * gbmodel.evaluation.evaluate(learner, M, params, body, size,
                                                                   scales[-1]))
    return {k: float(np.mean(v)) for k, v in out.items()} | {"factor": factor, "epochs": epochs,
                                                             "trials": len(models)}


def rows(aggs: dict) -> list[dict]:
    """The explanation experiments that the aggregated figures allow."""
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
        b = boundary(cond["spec"])
        out.append(dict(figure="fig2", experiment="boundary: learned on heights +-lim "
                                                  "(21 targets, 3 seeds), error at +-lim",
                        measured="; ".join(f"+-{r['limit_m']:g} m: Goal Babbling "
                                           f"{r['learned_mm']:.1f} mm, best cubic "
                                           f"{r['best_cubic_mm']:.1f} mm" for r in b)))
        break
    fig7 = aggs.get("fig7", {}).get("models", {}).get("conditions", {})
    full = next((c for name, c in fig7.items() if name == "const1.0"), None)
    if full and full["trials"]:
        models = [t["M"] for t in full["trials"].values()]
        c = best_cubic(full["spec"], models[0])
        out.append(dict(figure="fig7", experiment="capacity: the best cubic for the 4 x 4 x 4 grid",
                        measured=f"mean {c['best_mean_mm']:.2f} mm, worst {c['best_worst_mm']:.1f} mm"
                                 f" (Goal Babbling, const1.0 trial 0: mean "
                                 f"{c['learned_mean_mm']:.1f} mm, worst {c['learned_worst_mm']:.1f} mm)"))
        k = continuation(full["spec"], models)
        out.append(dict(figure="fig7", experiment=f"continuation: the const1.0 models, "
                                                  f"{k['epochs']:,} more epochs",
                        measured=f"{k['before_mm']:.2f} mm -> {k['same_mm']:.2f} mm at the same "
                                 f"rate, {k['smaller_mm']:.2f} mm at {k['factor']:g} x the rate "
                                 f"(mean over {k['trials']} trials)"))
    return out
