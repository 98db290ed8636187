"""Benchmarks of the pipeline at scale (`make scale`; docs/scale.md): sweeps of short arm5 trials
(ten conditions) from nothing, each stage timed as the command a user types (simulate, cached,
aggregate, cached, after one trial changed), wall, CPU, peak memory and files; cold reports
against another checkout; the cached stages.

    python -m pipeline.tools.scale                           # 1,000 and 10,000 trials
    python -m pipeline.tools.scale --sizes 100000            # the large one (about an hour)
    python -m pipeline.tools.scale --baseline /tmp/base      # the same, beside another checkout
    python -m pipeline.tools.scale --sizes 1000 --baseline /tmp/base --sweeps 5  # paired ratios
    python -m pipeline.tools.scale --sampled 100000          # 100,000 planned, 1,000 run
    python -m pipeline.tools.scale report --baseline /tmp/base [--rounds 3] [--profile full]
                                          [--experiments E1,E2] [--aggregates this|own]
    python -m pipeline.tools.scale stages [--profile full] [--repeats 3]
"""
from __future__ import annotations

import argparse
import filecmp
import json
import os
import shutil
import statistics
import sys
import tempfile
import time
from pathlib import Path

from pipeline import io

from . import REPO, child, fail, interleaved, timed

CONDITIONS = 10  # growth periods 1 ... 10: trials.count = size / CONDITIONS
STAGES = ("simulate", "simulate_cached", "aggregate", "aggregate_cached", "aggregate_one")
SMOKE_STAGES = ("simulate", "aggregate", "report")  # make smoke's commands
SMOKE_TARGET_S, ONE_TRIAL_TARGET_S = 8.0, 2.0  # CPU seconds (issue 43)


def overrides(root: Path, size: int, epochs: int, workers: int | None) -> list[str]:
    periods = ",".join(str(p) for p in range(1, CONDITIONS + 1))
    return [f"paths.root={root}", "figure=scale", "body=arm5", f"learner.epochs={epochs}",
            f"conditions.periods=[{periods}]", f"trials.count={size // CONDITIONS}",
            *([f"workers={workers}"] if workers else [])]


def run_command(code: Path, stage: str, args: list[str]) -> tuple[dict, int, bytes]:
    """`python -m pipeline.<stage> args` in checkout `code`: (times, exit status, stderr)."""
    wall, cpu, mb, rc, err = timed([sys.executable, "-m", f"pipeline.{stage}", *args], code,
                                   dict(os.environ, PYTHONPATH=str(code)))
    return dict(wall_s=round(wall, 3), cpu_s=round(cpu, 3), peak_mb=round(mb, 1)), rc, err


def run_stage(code: Path, stage: str, args: list[str]) -> dict:
    """run_command's times; RuntimeError with its stderr when it exits other than 0 or 1."""
    out, rc, err = run_command(code, stage, args)
    if rc not in (0, 1):
        raise RuntimeError(f"{stage} in {code} exited {rc}: {err.decode(errors='replace')[-2000:]}")
    return out


def smoke_once(code: Path, experiments: str, profile: str = "smoke") -> dict:
    """make smoke's three commands (make reproduce's: profile full) in checkout `code`."""
    args = [f"experiments=[{experiments}]", f"profile={profile}"]
    out = {stage: run_stage(code, stage, args) for stage in SMOKE_STAGES}
    return dict(out, cpu_s=round(sum(out[s]["cpu_s"] for s in SMOKE_STAGES), 3))


def median_of(runs: list[dict]) -> dict:
    """Each number's median over `runs`, and every run's CPU seconds (runs_cpu_s)."""
    out = {k: round(statistics.median(r[k] for r in runs), 3) for k in runs[0]
           if isinstance(runs[0][k], (int, float))}
    return dict(out, runs_cpu_s=[r["cpu_s"] for r in runs])


def cached_smoke(codes: list[Path], experiments: str, repeat: int,
                 profile: str = "smoke") -> list[dict]:
    """A fully cached make smoke in each checkout: brought up to date (unmeasured), then `repeat`
    runs, the checkouts alternating; per checkout each stage's median and the median total."""
    for code in codes:
        smoke_once(code, experiments, profile)
    runs = interleaved(range(len(codes)), repeat, lambda i, _: smoke_once(
        codes[i], experiments, profile), flip=False)
    return [dict({s: median_of([r[s] for r in rs]) for s in SMOKE_STAGES}, code=str(codes[i]),
                 **median_of(rs)) for i, rs in runs.items()]


def headline(results: list[dict], smokes: list[dict]) -> list[str]:
    """The start-up numbers against their targets, per checkout."""
    def median(r: dict) -> str:
        runs = r.get("runs_cpu_s", [])
        return (f" (median of {len(runs)}: {', '.join(f'{c:.2f}' for c in runs)})"
                if len(runs) > 1 else "")
    lines = [f"cached make smoke ({r['code'][-28:]}): {r['cpu_s']:.2f} s CPU ("
             + ", ".join(f"{s} {r[s]['cpu_s']:.2f}" for s in SMOKE_STAGES)
             + f"){median(r)}; target at most {SMOKE_TARGET_S:g} s" for r in smokes]
    lines += [f"{r['size']:,} trials, {stage} ({r['code'][-28:]}): CPU "
              f"{r[stage]['cpu_ratio']:.3f}x the baseline's (the median of the paired sweeps')"
              for r in results for stage in STAGES if "cpu_ratio" in r.get(stage, {})]
    return lines + [f"aggregate after one changed trial of {r['size']:,} ({r['code'][-28:]}): "
                    f"{r['aggregate_one']['cpu_s']:.2f} s CPU{median(r['aggregate_one'])}; "
                    f"target at most {ONE_TRIAL_TARGET_S:g} s"
                    for r in results if r["size"] == 10_000 and "sampled" not in r]


def change_one_trial(cache: Path) -> str:
    """Give one finished trial other content (its largest jump, by a tiny amount) and seal its
    sidecar again: what a recomputed trial with other results looks like to aggregate."""
    side = min((cache / "trials").rglob("*.json"))
    record = io.read_json(side)
    record["largest_jump"] = record["largest_jump"] * (1 + 1e-12) + 1e-300
    io.write_json(side, io.seal(record))
    return side.stem


def files_mb(folder: Path, digits: int) -> tuple[int, float]:
    """The files under `folder` and their MB."""
    sizes = [p.stat().st_size for p in folder.rglob("*") if p.is_file()]
    return len(sizes), round(sum(sizes) / 2**20, digits)


def prepare(code: Path, size: int, epochs: int, workers: int) -> tuple[dict, Path]:
    """Every stage of a sweep but aggregate_one in a new temporary root: (results, the root)."""
    root = Path(tempfile.mkdtemp(prefix=f"scale-{size}-"))
    try:
        args, agg = overrides(root, size, epochs, workers), overrides(root, size, epochs, None)
        out = dict(code=str(code), size=size, simulate=run_stage(code, "simulate", args))
        trials = root / "outputs" / "cache" / "trials"
        out["files"], out["cache_mb"] = files_mb(trials, 1)
        out["simulate_cached"] = run_stage(code, "simulate", args)
        out["aggregate"] = run_stage(code, "aggregate", agg)
        out["aggregate_cached"] = run_stage(code, "aggregate", agg)
    except BaseException:
        shutil.rmtree(root, ignore_errors=True)
        raise
    return out, root


def changed_once(code: Path, root: Path, size: int, epochs: int) -> dict:
    """aggregate after one trial of the sweep in `root` changed (change_one_trial)."""
    change_one_trial(root / "outputs" / "cache")
    return run_stage(code, "aggregate", overrides(root, size, epochs, None))


def paired(codes: list[Path], size: int, epochs: int, workers: int, keep: bool,
           repeat: int, sweeps: int = 1) -> list[dict]:
    """`sweeps` sweeps of each checkout from nothing, then `repeat` runs of aggregate_one, the
    checkouts alternating; each stage's medians and CPU per trial, and with a baseline each
    stage's `cpu_ratio`: the median of this checkout's CPU over the baseline's, sweep by sweep."""
    roots: dict = {}  # checkout -> the root of its latest sweep

    def sweep(i, _):
        out, root = prepare(codes[i], size, epochs, workers)
        if i in roots and not keep:
            shutil.rmtree(roots[i], ignore_errors=True)
        roots[i] = root
        return out
    try:
        done = interleaved(range(len(codes)), sweeps, sweep)
        runs = interleaved(range(len(codes)), repeat, lambda i, _: changed_once(
            codes[i], roots[i], size, epochs), flip=False)
        outs = [dict(done[i][-1], aggregate_one=median_of(runs[i])) for i in range(len(codes))]
        for i, out in enumerate(outs):
            for stage in STAGES:
                if stage != "aggregate_one":
                    out[stage] = median_of([s[stage] for s in done[i]])
                out[stage]["cpu_ms_per_trial"] = round(1000 * out[stage]["cpu_s"] / size, 3)
        for stage in STAGES[:-1] if len(codes) > 1 else ():
            outs[0][stage]["cpu_ratio"] = round(statistics.median(
                a[stage]["cpu_s"] / b[stage]["cpu_s"] for a, b in zip(done[0], done[1])), 3)
        return outs
    finally:
        for root in roots.values() if not keep else ():
            shutil.rmtree(root, ignore_errors=True)


PLANNING = """
import json, resource, sys, time
from pipeline import simulate
from pipeline.config import compose
cfg, out = compose(json.loads(sys.argv[1])), {}
for name in ("plan", "plan_saved"):
    wall, cpu = time.perf_counter(), time.process_time()
    jobs = simulate.jobs_of(cfg)
    out[name] = dict(wall_s=round(time.perf_counter() - wall, 3),
                     cpu_s=round(time.process_time() - cpu, 3),
                     trials=sum(len(j.trials) for j in jobs))
out["peak_mb"] = round(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024, 1)
print(json.dumps(out))
"""


def planning(code: Path, size: int, epochs: int, workers: int) -> dict:
    """Plan a sweep of `size` trials in checkout `code` as simulate does, twice (the second
    time from the saved plan), in a temporary root: wall and CPU of each, peak memory."""
    root = Path(tempfile.mkdtemp(prefix=f"scale-plan-{size}-"))
    try:
        return child(code, PLANNING, json.dumps(overrides(root, size, epochs, workers)))
    finally:
        shutil.rmtree(root, ignore_errors=True)


def sampled(code: Path, size: int, sample: int, epochs: int, workers: int, keep: bool) -> dict:
    """A sweep of `size` trials planned, run on `sample` of them (`estimated_cpu_s`)."""
    out = paired([code], sample, epochs, workers, keep, 1)[0]
    out.update(sampled=sample, size=size, **planning(code, size, epochs, workers))
    out["estimated_cpu_s"] = {stage: round(out[stage]["cpu_ms_per_trial"] * size / 1000, 1)
                              for stage in STAGES}
    return out


def packing(n: int, rows: int = 11) -> dict:
    """The cache's layout (per_trial: a Parquet curve and a JSON sidecar each) against a packed
    one (one Parquet of every curve with a key column, one JSON of every sidecar), on `n`
    synthetic curves of `rows` epochs: files, MB, ms per trial to write and to read back."""
    import hashlib

    import numpy as np
    import pyarrow as pa

    rng = np.random.default_rng(0)
    curves = [pa.table({f.name: pa.array(rng.integers(1, 10, rows) if pa.types.is_integer(
        f.type) else rng.random(rows), f.type) for f in io.TRIAL_CURVE}) for _ in range(n)]
    keys = [f"{i:020x}" for i in range(n)]
    sides = [dict(key=k, M=rng.random((2, 5)).tolist(), status="ok") for k in keys]

    def read(curve: Path, side: Path, name: str, digest: str) -> None:
        data = curve.read_bytes()
        side = io.check_seal(io.parse_json(side.read_bytes(), name))
        assert hashlib.sha256(data).hexdigest() == side[digest]
        io.parse_table(data, name)

    def per_trial(folder: Path, write: bool) -> None:
        for k, c, side in zip(keys, curves, sides):
            curve, side_file = folder / k[:2] / f"{k}.parquet", folder / k[:2] / f"{k}.json"
            if not write:
                read(curve, side_file, k, "curve_sha256")
                continue
            side = dict(side, curve_sha256=io.write_table(curve, c))
            io.write_json(side_file, io.seal(side), compact=True)

    def packed(folder: Path, write: bool) -> None:
        if not write:
            return read(folder / "curves.parquet", folder / "sidecars.json", "pack",
                        "curves_sha256")
        table = pa.concat_tables([c.append_column("key", pa.array([k] * rows))
                                  for k, c in zip(keys, curves)])
        digest = io.write_table(folder / "curves.parquet", table)
        io.write_json(folder / "sidecars.json", io.seal(dict(curves_sha256=digest, trials=sides)),
                      compact=True)

    out = {}
    with tempfile.TemporaryDirectory() as tmp:
        for layout in (per_trial, packed):
            folder = Path(tmp) / layout.__name__
            t0 = time.process_time()
            layout(folder, True)
            t1 = time.process_time()
            layout(folder, False)
            t2 = time.process_time()
            files, mb = files_mb(folder, 2)
            out[layout.__name__] = dict(files=files, write_ms=round(1e3 * (t1 - t0) / n, 4),
                                        read_ms=round(1e3 * (t2 - t1) / n, 4), mb=mb)
    return out


def table(results: list[dict]) -> str:
    head = f"{'checkout':<28} {'trials':>7} {'stage':<17} {'wall s':>8} {'CPU s':>8} " \
           f"{'ms CPU/trial':>12} {'peak MB':>8} {'files':>7}"
    lines = [head, "-" * len(head)]
    for r in results:
        size = f"{r['sampled']}/{r['size']}" if "sampled" in r else str(r["size"])
        rows = [(size, stage, r[stage], r[stage]["cpu_ms_per_trial"], r[stage]["peak_mb"],
                 r["files"] if stage == "simulate" else "") for stage in STAGES]
        rows += [(str(r["size"]), stage, r[stage], 1000 * r[stage]["cpu_s"] / r["size"],
                  r["peak_mb"], "") for stage in (("plan", "plan_saved") if "sampled" in r else ())]
        lines += [f"{r['code'][-28:]:<28} {n:>7} {stage:<17} {s['wall_s']:>8.2f} "
                  f"{s['cpu_s']:>8.2f} {ms:>12.3f} {mb:>8.1f} {files:>7}"
                  for n, stage, s, ms, mb, files in rows]
    return "\n".join(lines)


def load() -> str:
    one, five, fifteen = os.getloadavg()
    return f"load average {one:.2f} {five:.2f} {fifteen:.2f} on {os.cpu_count()} CPUs"


# ---- report: a cold report against a baseline; stages: the cached Makefile stages ----------------
def report_args(experiments: list[str], profile: str, out: Path, root: Path = REPO) -> list[str]:
    """The Makefile's report command on the aggregates under `root`, into `out` (under it)."""
    return [f"experiments=[{','.join(experiments)}]", f"profile={profile}", f"paths.root={root}",
            f"paths.report={out}"]


def cold_report(code: Path, args: list[str], out: Path) -> float:
    """CPU seconds of one report of checkout `code` into `out`; RuntimeError with the stage's
    last words when it fails or leaves no report.md."""
    usage, rc, err = run_command(code, "report", args)
    if rc != 0 or not (out / "report.md").is_file():
        tail = " | ".join(err.decode(errors="replace").strip().splitlines()[-3:])
        raise RuntimeError(f"the report of {code} exited {rc} without {out}/report.md: {tail}")
    return usage["cpu_s"]


def differing(a: Path, b: Path) -> list[str]:
    """The files of report folder `a` whose bytes differ from `b`'s (or that only one has)."""
    files = {p.relative_to(d).as_posix() for d in (a, b) for p in d.rglob("*") if p.is_file()}
    return sorted(f for f in files if not ((a / f).is_file() and (b / f).is_file()
                                           and filecmp.cmp(a / f, b / f, shallow=False)))


def report_pairs(trees: dict, roots: dict, exps: list[str], profile: str, rounds: int) -> tuple:
    """`rounds` pairs of cold reports of the checkouts `trees` (this, baseline) on the aggregates
    under `roots`: (CPU seconds per checkout, the files that differ in the last pair)."""
    tmps = {}

    def one(t: str, r: int) -> float:
        out = tmps[t] / f"{t}{r}"
        cpu = cold_report(trees[t], report_args(exps, profile, out, roots[t]), out)
        print(f"round {r + 1}, {t}: {cpu:.2f} s CPU", flush=True)
        return cpu
    try:
        for t in trees:  # a report is written under paths.root only
            (roots[t] / "outputs").mkdir(exist_ok=True)
            tmps[t] = Path(tempfile.mkdtemp(prefix=f".bench_report_{t}_",
                                            dir=roots[t] / "outputs"))
        cpu, last = interleaved(trees, rounds, one), rounds - 1
        return cpu, differing(tmps["this"] / f"this{last}", tmps["baseline"] / f"baseline{last}")
    finally:
        for tmp in tmps.values():
            shutil.rmtree(tmp, ignore_errors=True)


def report_main(a) -> int:
    from ..experiments import config_folders, listed

    if not (a.baseline / "pipeline" / "report.py").is_file():
        return fail(f"--baseline={a.baseline}: not a checkout of this project")
    if a.rounds < 1:
        return fail(f"--rounds={a.rounds}: at least 1")
    exps = a.experiments.split(",") if a.experiments else listed(config_folders())
    trees = {"this": REPO, "baseline": a.baseline.resolve()}
    roots = {t: (trees[t] if a.aggregates == "own" else REPO) for t in trees}
    try:
        cpu, diff = report_pairs(trees, roots, exps, a.profile, a.rounds)
    except RuntimeError as err:
        return fail(err)
    ratios = [x / y for x, y in zip(cpu["this"], cpu["baseline"])]
    print(f"cold {a.profile} report ({len(exps)} experiments), {a.rounds} interleaved pairs: "
          f"this {statistics.median(cpu['this']):.2f} s CPU, baseline "
          f"{statistics.median(cpu['baseline']):.2f} s (medians); median ratio this / baseline "
          f"{statistics.median(ratios):.3f} [{min(ratios):.3f}, {max(ratios):.3f}], "
          f"{1 / statistics.median(ratios):.2f}x faster")
    print(f"files that differ ({len(diff)}): {', '.join(diff) or 'none'}")
    return 0


def stages_main(a) -> int:
    from ..experiments import config_folders, listed

    r = cached_smoke([REPO], ",".join(listed(config_folders())), a.repeats, a.profile)[0]
    print(f"fully cached stages, profile={a.profile}, {a.repeats} repeats (medians):")
    for name in SMOKE_STAGES:
        print(f"  {name:10s} {r[name]['wall_s']:6.1f} s wall  {r[name]['cpu_s']:6.1f} s CPU")
    print(f"  total      {r['cpu_s']:6.1f} s CPU ({', '.join(map(str, r['runs_cpu_s']))})")
    return 0


def parser(command: str | None) -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(prog=f"python -m pipeline.tools.scale {command or ''}".strip(),
                                 description=None if command else __doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    add = ap.add_argument
    if command == "report":
        add("--baseline", type=Path, required=True, help="another checkout")
        add("--rounds", type=int, default=3, help="pairs of reports (default 3)")
        add("--experiments", help="comma-separated (default: every make list's)")
        add("--aggregates", choices=("this", "own"), default="this",
            help="whose aggregates each checkout reports (own: each its own outputs/)")
    if command:
        add("--profile", default="smoke", choices=("smoke", "full"))
        if command == "stages":
            add("--repeats", type=int, default=3)
        return ap
    add("--sizes", default="1000,10000", help="trials per sweep, comma-separated")
    add("--epochs", type=int, default=10, help="epochs per trial (default 10)")
    add("--workers", type=int, default=2, help="simulate's workers (default 2)")
    add("--baseline", type=Path, help="another checkout to run beside this one")
    add("--out", type=Path, default=REPO / "outputs" / "bench" / "scale.json")
    add("--keep", action="store_true", help="keep the temporary roots")
    add("--sampled", type=int, metavar="N",
        help="instead of --sizes: plan N trials, run a sample of --sample of them")
    add("--sample", type=int, default=1000, help="trials run for --sampled (1000)")
    add("--smoke-experiments", metavar="E1,E2,...",
        help="also time a fully cached make smoke of these experiments")
    add("--repeat", type=int, default=3,
        help="runs of aggregate_one and of the cached smoke, medians (default 3)")
    add("--sweeps", type=int, default=1,
        help="sweeps from nothing per checkout and size, alternating with the baseline's: "
             "medians, and CPU ratios to the baseline sweep by sweep (default 1)")
    add("--packing", type=int, metavar="N",
        help="instead: the cache's files against one packed file, for N trials")
    return ap


def bad_input(a) -> str | None:
    """What is wrong with a sweep's options, in one line; None when nothing is."""
    try:
        sizes = [int(s) for s in a.sizes.split(",")]
    except ValueError:
        sizes = []
    sample_ok = CONDITIONS <= a.sample <= (a.sampled or 0) and not (a.sample % CONDITIONS
                                                                   or a.sampled % CONDITIONS)
    return next((why for is_bad, why in (
        (not sizes or any(s < CONDITIONS or s % CONDITIONS for s in sizes),
         f"--sizes={a.sizes}: positive multiples of {CONDITIONS}"),
        (a.baseline is not None and not (a.baseline / "pipeline" / "simulate.py").is_file(),
         f"--baseline={a.baseline}: not a checkout of this project"),
        (min(a.epochs, a.workers, a.repeat, a.sweeps) < 1,
         "--epochs, --workers, --repeat and --sweeps: at least 1"),
        (a.sampled is not None and not sample_ok, f"--sampled={a.sampled} --sample={a.sample}: "
         f"multiples of {CONDITIONS}, the sample at most the sweep")) if is_bad), None)


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    if argv[:1] in (["report"], ["stages"]):
        a = parser(argv[0]).parse_args(argv[1:])
        return (report_main if argv[0] == "report" else stages_main)(a)
    a = parser(None).parse_args(argv)
    if a.packing is not None:
        if a.packing < 1:
            return fail(f"--packing={a.packing}: at least 1 trial")
        print(json.dumps(dict(trials=a.packing, **packing(a.packing), machine=load()), indent=1))
        return 0
    if (why := bad_input(a)) is not None:
        return fail(why)
    codes = [REPO] + ([a.baseline.resolve()] if a.baseline else [])
    results, loads = [], [load()]
    for size in [int(s) for s in a.sizes.split(",")] if a.sampled is None else [a.sampled]:
        done = (paired(codes, size, a.epochs, a.workers, a.keep, a.repeat, a.sweeps)
                if a.sampled is None
                else [sampled(code, size, a.sample, a.epochs, a.workers, a.keep)
                      for code in codes])
        results += done
        loads.append(load())
        print("\n".join(table(done).splitlines()[2:]), file=sys.stderr)
    smokes = cached_smoke(codes, a.smoke_experiments, a.repeat) if a.smoke_experiments else []
    if smokes:
        loads.append(load())
    record = dict(epochs=a.epochs, workers=a.workers, conditions=CONDITIONS, repeat=a.repeat,
                  sweeps=a.sweeps,
                  loads=loads, results=results, cached_smoke=smokes)
    io.write_text(a.out, json.dumps(record, indent=1) + "\n")
    print(table(results))
    print("\n".join(headline(results, smokes)))
    print(f"machine: {loads[0]} before, {loads[-1]} after; written to {a.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
