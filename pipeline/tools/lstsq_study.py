"""The measurements of learner.solver=lstsq on the paper's bodies (docs/bodies.md, "The exact
solver"): one figure's conditions on the committed seeds, each trial's final error, the trials
stuck far above their condition's median, and where the inverse commands a joint past its limit.

    python -m pipeline.tools.lstsq_study fig7 --epochs 2000 --trials 20
    python -m pipeline.tools.lstsq_study fig5 --epochs 10000 --trials 5 --only const0.5
    python -m pipeline.tools.lstsq_study arm2 --epochs 1000 --trials 3    # the 2-DOF arm
    python -m pipeline.tools.lstsq_study fig7 --epochs 2000 -- learner.ridge=0.1   # any override

The seeds are the committed report's: the draws come in blocks of gbmodel.trial.DRAW_BLOCK =
1,000 epochs, so a run of a multiple of 1,000 epochs is the first epochs of the committed trials
(a shorter one draws its one block at its own length). One process, the trials in turn.
"""
from __future__ import annotations

import argparse
import sys
import time

import numpy as np

import gbmodel
from gbmodel.learners import goal_babbling as gb
from pipeline.config import compose
from pipeline.plan import plan


def at_targets(M1, M2, spec, size) -> tuple[float, float]:
    """At the targets of size `size`: the share at which g2 commands a joint past its limit (0
    without limits), and the mean of |g2(x*) - g1(x*)| (command units: the redundancy resolution
    wandering shows here, while the hand's error may stay put)."""
    body, (_, params) = spec.make_body(), spec.make_learner()
    x = body.target_set(size)
    past = (np.abs(gb.predict(M2, params, body, x)) > 1.0).any(axis=1).mean() \
        if body.normalized and body.saturates else 0.0
    moved = gb.predict_model(M2, params, body, x) - gb.predict_model(M1, params, body, x)
    return float(past), float(np.linalg.norm(moved, axis=1).mean())


def run(figure: str, epochs: int, trials: int, overrides: list[str], only=(), curve=False):
    base = [f"body={figure}", "growth=none", "conditions.references=[1.0]"] \
        if figure in ("arm2", "arm5", "icub") else [f"experiment={figure}"]
    cfg = compose([*base, "learner.solver=lstsq", f"learner.epochs={epochs}",
                   f"trials.count={trials}", *overrides])
    rows: dict[str, list] = {}
    t0, mark = time.process_time(), min(1000, epochs)
    for t in plan(cfg):
        if only and t["growth_label"] not in only:
            continue
        spec = gbmodel.TrialSpec.from_dict({**t["spec"], "snapshots": [mark]})
        r = gbmodel.run_trial(spec, np.random.default_rng(np.random.SeedSequence(**t["seed"])))
        sat, moved = at_targets(r.snapshots[mark], r.M, spec, r.size[-1])
        rows.setdefault(t["growth_label"], []).append(
            (r.abs_error[-1], r.heldout_abs_error[-1], sat, r.epoch, r.abs_error, moved))
    cpu = time.process_time() - t0
    out = {}
    for label, rs in rows.items():
        err, held, sat, _, curves, moved = (np.array([r[i] for r in rs]) for i in range(6))
        med, m = float(np.median(err)), np.median(curves, axis=0)
        out[label] = dict(median=med, worst_ratio=float(err.max() / med),
                          stuck=int((err > 3 * med).sum()), heldout_median=float(np.median(held)),
                          heldout_max=float(held.max()), saturated_max=float(sat.max()),
                          end_over_best=float(med / m.min()), moved=float(np.median(moved)))
        print(f"{label:>10}: n={len(rs)} median {1e3 * med:.2f} mm, worst/median "
              f"{err.max() / med:.2f}, >3x median {out[label]['stuck']}, end/best "
              f"{out[label]['end_over_best']:.2f}, held out median {1e3 * np.median(held):.2f} "
              f"max {1e3 * held.max():.2f} mm, past a limit max {100 * sat.max():.0f} % of "
              f"targets, postures moved since epoch {mark} {np.median(moved):.3f}", flush=True)
        if curve:
            ep = rs[0][3]
            pts = [i for i, e in enumerate(ep) if e in (10, 100, 1000, 2000, 5000, 10000, 20000,
                                                       50000, 100000) or i == len(m) - 1]
            print("            median curve: " + ", ".join(f"{ep[i]}: {1e3 * m[i]:.2f}"
                                                           for i in pts))
    refs = [v["median"] for k, v in out.items() if k.startswith("const1")]
    grown = {k: v["median"] / refs[0] for k, v in out.items()
             if refs and not k.startswith("const")}
    if grown:
        print("grown / const1.0: " + ", ".join(f"{k} {v:.2f}" for k, v in grown.items()))
    print(f"CPU {cpu:.0f} s", flush=True)
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("figure", help="fig4 | fig5 | fig7 | arm2 | arm5 | icub (constant size)")
    ap.add_argument("--epochs", type=int, default=2000)
    ap.add_argument("--trials", type=int, default=20)
    ap.add_argument("--only", nargs="*", default=(), help="condition labels (const0.5, TG100)")
    ap.add_argument("--curve", action="store_true", help="print the median curve")
    ap.add_argument("overrides", nargs="*", help="config overrides (after --)")
    a = ap.parse_args(argv)
    run(a.figure, a.epochs, a.trials, a.overrides, a.only, a.curve)
    return 0


if __name__ == "__main__":
    sys.exit(main())
