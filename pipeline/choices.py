"""Short sweeps over the choices the paper leaves open: what each choice changes, measured.

    python -m pipeline.choices [--epochs 20000] [--seeds 3] [--workers 2] [--out DIR] [--cache DIR]

For every open choice (learning rate, initialisation, home posture, target grid, joint-limit
handling, the short reference of the non-proportional figure) it runs the chosen setting and its
alternatives on a body without growth and reports the final error, mean and std over seeds; for
the error formula and the evaluation targets it scores the final inverse estimates of the chosen
setting in the alternative ways. Writes choices.csv and choices.md into --out (the report folder).
The per-trial results are cached under --cache, keyed by the arguments, the variants and the
gbmodel code fingerprint: a rerun with nothing changed computes nothing.
Deterministic, with common random numbers: trial s of every variant draws from
SeedSequence(root, spawn_key=(s,)), so that variants differ by the choice, not by the draws.
"""
from __future__ import annotations

import argparse
import dataclasses
import os
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

import gbmodel  # noqa: E402
from gbmodel.bodies import _grid  # noqa: E402

from .config import REPO_ROOT, learner_settings  # noqa: E402
from .plan import code_fingerprint, stable_hash32  # noqa: E402

PAPER = {body: learner_settings(body) for body in gbmodel.BODIES}  # conf/learner/*.yaml
LONG = dict(start_size=1.0, end_size=1.0)


def _arm5_home(bend):
    return np.array([np.pi / 2 - 2 * bend] + [bend] * 4)


def _shrunk(targets, factor):
    centre = 0.5 * (targets.min(axis=0) + targets.max(axis=0))
    return centre + factor * (targets - centre)


def variants():
    """(body, choice, label, chosen, spec overrides, body overrides) of every run."""
    rows = []
    for body in ("arm5", "icub"):
        for lr in (0.5, 1.0, 1.5, 2.0):
            rows.append((body, "learning rate", f"eta = {lr}", lr == 1.0,
                         dict(learning_rate=lr), {}))
        for r0 in (0.0, 0.1, 0.3):
            rows.append((body, "initialisation", f"|g - home| <= {r0}", r0 == 0.1,
                         dict(init_range=r0), {}))
    rows += [
        ("arm5", "home posture", "bend 0.25 rad per joint", False, {},
         dict(home=_arm5_home(0.25))),
        ("arm5", "home posture", "bend 0.75 rad per joint", False, {},
         dict(home=_arm5_home(0.75))),
        ("arm5", "target grid", "wider: x -0.6..0.6, y 0.1..0.7 (13 x 7)", False, {},
         dict(targets=_grid(np.linspace(-0.6, 0.6, 13), np.linspace(0.1, 0.7, 7)))),
        ("arm5", "target grid", "coarser: 6 x 3 over the same box", False, {},
         dict(targets=_grid(np.linspace(-0.5, 0.5, 6), np.linspace(0.2, 0.7, 3)))),
        ("icub", "target grid", "smaller: the 4 x 4 x 4 grid shrunk to 2/3 about its centre",
         False, {}, dict(targets=_shrunk(gbmodel.make_body("icub").targets, 2 / 3))),
        ("icub", "joint limits", "ignored (no saturation)", False, {}, dict(saturates=False)),
        ("arm5", "non-proportional short reference", "non-proportional start body (0.5 m)", True,
         dict(pattern="nonproportional", start_size=0.5, end_size=0.5), {}),
        ("arm5", "non-proportional short reference", "proportionally halved body (0.5 m)", False,
         dict(pattern="proportional", start_size=0.5, end_size=0.5), {}),
        ("arm2", "Fig. 2 duration", "10,000 epochs", True, dict(epochs=10_000), {}),
        ("arm2", "Fig. 2 duration", "100,000 epochs", False, dict(epochs=100_000), {}),
    ]
    # how much the absolute error rises during growth depends on how fast the learner is
    for period in (100, 1000):
        for lr in (0.1, 0.3, 1.0):
            rows.append(("arm5", f"learning rate, growth T_G = {period}", f"eta = {lr}",
                         lr == 1.0, dict(learning_rate=lr, start_size=0.5, end_size=1.0,
                                         period=period), {}))
    return rows


def _run(job):
    """One trial of one variant; returns its final errors under several scorings."""
    body_name, spec_kw, body_kw, epochs, seed_seq = job
    body = dataclasses.replace(gbmodel.make_body(body_name), **body_kw)
    spec = gbmodel.TrialSpec(**{**PAPER[body_name], "epochs": epochs, **LONG, **spec_kw})
    res = gbmodel.run_trial(spec, np.random.default_rng(seed_seq), body=body)
    size = spec.end_size
    exps = gbmodel.exponents(body.n, spec.degree)

    def distances(targets):
        reached = body.forward(gbmodel.predict(res.M, targets, exps), size, spec.pattern)
        return np.linalg.norm(reached - targets, axis=-1)

    d = distances(body.target_set(size))
    grid = body.targets
    axes = [np.unique(grid[:, j]) for j in range(body.n)]
    centres = _grid(*[0.5 * (a[1:] + a[:-1]) for a in axes]) * size
    growing = res.epoch <= spec.period + 1 if spec.period else np.zeros(len(res.epoch), bool)
    return dict(final_abs_m=float(res.abs_error[-1]), mean_sq_m2=float(np.mean(d ** 2)),
                rms_m=float(np.sqrt(np.mean(d ** 2))), worst_m=float(d.max()),
                off_grid_abs_m=float(distances(centres).mean()),
                growth_abs_m=res.abs_error[growing].tolist())


def _rise_pct(curves: pd.Series) -> float:
    """Rise of the mean absolute error during growth above the lowest error before it, in %
    (the measure of pipeline.aggregate.growth_peak); NaN without growth."""
    if len(curves.iloc[0]) == 0:
        return np.nan
    mean = np.mean(np.stack(curves.to_numpy()), axis=0)
    rise = mean - np.minimum.accumulate(mean)
    i = int(np.argmax(rise))
    return 100.0 * rise[i] / (mean[i] - rise[i])


def _records(rows, results, seeds) -> pd.DataFrame:
    records = []
    for v, (body, choice, label, chosen, _, _) in enumerate(rows):
        for s in range(seeds):
            records.append(dict(body=body, choice=choice, variant=label, chosen=chosen, seed=s,
                                **results[v * seeds + s]))
    return pd.DataFrame(records)


def main(argv=None) -> pd.DataFrame:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--epochs", type=int, default=20_000)
    ap.add_argument("--seeds", type=int, default=3)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--root-seed", type=int, default=2010)
    ap.add_argument("--out", default=str(REPO_ROOT / "outputs" / "report"))
    ap.add_argument("--cache", default=str(REPO_ROOT / "outputs" / "cache" / "choices"))
    args = ap.parse_args(argv)
    if args.epochs < 1 or args.seeds < 1 or args.workers < 1:
        ap.error("--epochs, --seeds and --workers must be positive")

    rows = variants()
    key = stable_hash32([repr(rows), PAPER, args.epochs, args.seeds, args.root_seed,
                         code_fingerprint()])
    cached = Path(args.cache) / f"choices-{key:08x}.parquet"
    if cached.exists():
        raw = pd.read_parquet(cached)
    else:
        jobs = [(body, spec_kw, body_kw, args.epochs,
                 np.random.SeedSequence(args.root_seed, spawn_key=(s,)))
                for body, _, _, _, spec_kw, body_kw in rows for s in range(args.seeds)]
        with ProcessPoolExecutor(args.workers) as pool:
            results = list(pool.map(_run, jobs))
        raw = _records(rows, results, args.seeds)
        cached.parent.mkdir(parents=True, exist_ok=True)
        tmp = cached.with_suffix(".tmp")
        raw.to_parquet(tmp, index=False)
        tmp.replace(cached)
    table = (raw.groupby(["body", "choice", "variant", "chosen"], sort=False)
             .agg(final_abs_mm_mean=("final_abs_m", lambda x: 1e3 * x.mean()),
                  final_abs_mm_std=("final_abs_m", lambda x: 1e3 * x.std(ddof=1) if len(x) > 1 else 0.0),
                  rms_mm=("rms_m", lambda x: 1e3 * x.mean()),
                  mean_sq_mm2=("mean_sq_m2", lambda x: 1e6 * x.mean()),
                  worst_mm=("worst_m", lambda x: 1e3 * x.mean()),
                  off_grid_abs_mm=("off_grid_abs_m", lambda x: 1e3 * x.mean()),
                  growth_rise_pct=("growth_abs_m", _rise_pct),
                  trials=("seed", "size"))
             .reset_index())
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    for name, text in (("choices.csv", table.round(3).to_csv(index=False)),
                       ("choices.md", _markdown(table, args))):
        tmp = out / f"{name}.tmp"
        tmp.write_text(text)
        tmp.replace(out / name)
    print(table.round(2).to_string(index=False))
    return table


def _markdown(table: pd.DataFrame, args) -> str:
    lines = [
        "# Open choices: measured effect of the alternatives",
        "",
        f"Each row: {args.seeds} trials of {args.epochs:,} epochs at full size, no growth "
        "(paper settings otherwise; `python -m pipeline.choices`). Final error = mean Euclidean "
        "distance over the target grid (the chosen formula); the last three columns score the "
        "same final estimates as the RMS distance, as the mean squared distance printed in eq. 10 "
        "(mm^2), by the worst target, and over off-grid points (the centres of the grid cells). "
        "Rows with growth (0.5 -> 1.0 over T_G epochs) give the temporary rise of the mean "
        "absolute error during growth. * = chosen.",
        "",
        "| body | choice | variant | final error [mm] | RMS [mm] | mean squared [mm^2] "
        "| worst target [mm] | off-grid [mm] | rise during growth |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for r in table.itertuples():
        lines.append(
            f"| {r.body} | {r.choice} | {r.variant}{' *' if r.chosen else ''} "
            f"| {r.final_abs_mm_mean:.1f} ± {r.final_abs_mm_std:.1f} | {r.rms_mm:.1f} "
            f"| {r.mean_sq_mm2:.0f} | {r.worst_mm:.1f} | {r.off_grid_abs_mm:.1f} "
            f"| {'' if np.isnan(r.growth_rise_pct) else f'+{r.growth_rise_pct:.0f} %'} |")
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    main()
