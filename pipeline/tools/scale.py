"""Benchmarks of the pipeline at scale: sweeps of many short trials from nothing, stage by stage
(`make scale`); a cold report against another checkout; the cached Makefile stages.

    python -m pipeline.tools.scale                           # 1,000 and 10,000 trials
    python -m pipeline.tools.scale --sizes 100000            # the large one (about an hour)
    python -m pipeline.tools.scale --baseline /tmp/base      # the same, beside another checkout
    python -m pipeline.tools.scale --sampled 100000          # 100,000 planned, 1,000 run
    python -m pipeline.tools.scale report --baseline /tmp/base [--rounds 3] [--profile full]
                                          [--experiments E1,E2] [--aggregates this|own]
    python -m pipeline.tools.scale stages [--profile full] [--repeats 3]

A sweep: arm5 trials of --epochs (10) epochs over ten conditions (growth periods 1 ... 10), in
a temporary root; each stage runs as the command a user types, in the checkout under test, with
its wall and CPU time (its processes and workers), peak memory and the cache's files: simulate
(from nothing), simulate_cached, aggregate, aggregate_cached, aggregate_one (after one trial
changed: its sidecar's content, sealed again). --sampled N plans all N as simulate does (then
from the saved plan) and runs the stages on --sample trials (1,000), whose costs per trial times
N estimate the stages at N (`estimated_cpu_s`). --smoke-experiments (make scale passes make
smoke's) also times a fully cached make smoke, --repeat times after bringing it up to date. The
last lines: the cached smoke's CPU (target SMOKE_TARGET_S) and aggregate's after one changed
trial of 10,000 (target ONE_TRIAL_TARGET_S), each the median of --repeat runs. With --baseline,
every size runs on the baseline right after this one, the start-up runs alternating (a shared
machine's load falls on both alike). Results: --out (JSON) and a table (ms CPU per trial).

report: a cold report (every figure drawn), this checkout against BASELINE (`git worktree add
/tmp/base <commit>`) in CPU time, A B then B A ...; both on this checkout's aggregates (make
smoke, or make reproduce for --profile full, first), or with --aggregates own each on its own
outputs/ (an older checkout). A report that fails or writes no report.md stops it with its error.
It prints each pair's ratio this / baseline, their median (the figure to quote) and the files
whose bytes differ in the last pair. stages: the three stage commands of every make list's
experiments on a fully cached tree (cached_smoke), --repeats times: each one's median.
"""
from __future__ import annotations

import argparse
import filecmp
import json
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from pipeline import io

REPO = Path(__file__).resolve().parents[2]
CONDITIONS = 10  # growth periods 1 ... 10: trials.count = size / CONDITIONS
STAGES = ("simulate", "simulate_cached", "aggregate", "aggregate_cached", "aggregate_one")
SMOKE_STAGES = ("simulate", "aggregate", "report")  # make smoke's commands
SMOKE_TARGET_S, ONE_TRIAL_TARGET_S = 8.0, 2.0  # CPU seconds (issue 43)


def overrides(root: Path, size: int, epochs: int, workers: int) -> list[str]:
    periods = ",".join(str(p) for p in range(1, CONDITIONS + 1))
    return [f"paths.root={root}", "figure=scale", "body=arm5", f"learner.epochs={epochs}",
            f"conditions.periods=[{periods}]", f"trials.count={size // CONDITIONS}",
            f"workers={workers}"]


def run_stage(code: Path, stage: str, args: list[str]) -> dict:
    """Run `python -m pipeline.<stage> args` in checkout `code`: wall, CPU (the process and the
    children it waited for) and peak resident memory of its largest process."""
    out, rc, err = run_command(code, stage, args)
    if rc not in (0, 1):
        raise RuntimeError(f"{stage} in {code} exited {rc}: {err.decode(errors='replace')[-2000:]}")
    return out


def run_command(code: Path, stage: str, args: list[str]) -> tuple[dict, int, bytes]:
    """run_stage's measures, the exit status and what the stage wrote to stderr."""
    env = dict(os.environ, PYTHONPATH=str(code))
    start = time.perf_counter()
    proc = subprocess.Popen([sys.executable, "-m", f"pipeline.{stage}", *args], cwd=code,
                            env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    err = proc.stderr.read()
    _, status, usage = os.wait4(proc.pid, 0)
    wall = time.perf_counter() - start
    return (dict(wall_s=round(wall, 3), cpu_s=round(usage.ru_utime + usage.ru_stime, 3),
                 peak_mb=round(usage.ru_maxrss / 1024, 1)),
            os.waitstatus_to_exitcode(status), err)


def smoke_once(code: Path, experiments: str, profile: str = "smoke") -> dict:
    """make smoke's three commands (or make reproduce's: profile full) in checkout `code`: each
    stage's wall, CPU and peak memory."""
    args = [f"experiments=[{experiments}]", f"profile={profile}"]
    out = {stage: run_stage(code, stage, args) for stage in SMOKE_STAGES}
    return dict(out, cpu_s=round(sum(out[s]["cpu_s"] for s in SMOKE_STAGES), 3))


def median_of(runs: list[dict]) -> dict:
    """Each measure's median over `runs` (dicts of wall_s, cpu_s, peak_mb), and the runs' CPU."""
    out = {k: round(statistics.median(r[k] for r in runs), 3) for k in runs[0]
           if isinstance(runs[0][k], (int, float))}
    return dict(out, runs_cpu_s=[r["cpu_s"] for r in runs])


def cached_smoke(codes: list[Path], experiments: str, repeat: int,
                 profile: str = "smoke") -> list[dict]:
    """A fully cached make smoke in each checkout: brought up to date (the cache, the aggregates
    and the report, unmeasured), then `repeat` measured runs, the checkouts alternating; per
    checkout each stage's median and the median total."""
    for code in codes:
        smoke_once(code, experiments, profile)
    runs = {code: [] for code in codes}
    for _ in range(repeat):
        for code in codes:
            runs[code].append(smoke_once(code, experiments, profile))
    return [dict({s: median_of([r[s] for r in runs[code]]) for s in SMOKE_STAGES}, code=str(code),
                 cpu_s=round(statistics.median(r["cpu_s"] for r in runs[code]), 3),
                 runs_cpu_s=[r["cpu_s"] for r in runs[code]]) for code in codes]


def headline(results: list[dict], smokes: list[dict]) -> list[str]:
    """The start-up numbers against their targets: a cached make smoke's CPU, and aggregate's
    after one changed trial of a 10,000-trial sweep, per checkout."""
    lines = [f"cached make smoke ({r['code'][-28:]}): {r['cpu_s']:.2f} s CPU ("
             + ", ".join(f"{s} {r[s]['cpu_s']:.2f}" for s in SMOKE_STAGES)
             + f"){_median(r)}; target at most {SMOKE_TARGET_S:g} s" for r in smokes]
    lines += [f"aggregate after one changed trial of {r['size']:,} ({r['code'][-28:]}): "
              f"{r['aggregate_one']['cpu_s']:.2f} s CPU{_median(r['aggregate_one'])}; "
              f"target at most {ONE_TRIAL_TARGET_S:g} s"
              for r in results if r["size"] == 10_000 and "sampled" not in r]
    return lines


def _median(r: dict) -> str:
    runs = r.get("runs_cpu_s", [])
    return f" (median of {len(runs)}: {', '.join(f'{c:.2f}' for c in runs)})" if len(runs) > 1 else ""


def change_one_trial(cache: Path) -> str:
    """Give one finished trial other content (its largest jump, by a tiny amount) and seal its
    sidecar again: what a recomputed trial with other results looks like to aggregate."""
    side = min((cache / "trials").rglob("*.json"))
    record = io.read_json(side)
    record["largest_jump"] = record["largest_jump"] * (1 + 1e-12) + 1e-300
    io.write_json(side, io.seal(record))
    return side.stem


def files_under(folder: Path) -> int:
    return sum(len(files) for _, _, files in os.walk(folder))


def prepare(code: Path, size: int, epochs: int, workers: int) -> tuple[dict, Path]:
    """Every stage of a sweep of `size` trials on checkout `code` but the last (aggregate_one),
    in a new temporary root: (the results, the root)."""
    root = Path(tempfile.mkdtemp(prefix=f"scale-{size}-"))
    try:
        args = overrides(root, size, epochs, workers)
        out = dict(code=str(code), size=size)
        out["simulate"] = run_stage(code, "simulate", args)
        cache = root / "outputs" / "cache"
        out["files"] = files_under(cache / "trials")
        out["cache_mb"] = round(sum(p.stat().st_size for p in (cache / "trials").rglob("*")
                                    if p.is_file()) / 2**20, 1)
        out["simulate_cached"] = run_stage(code, "simulate", args)
        agg = aggregate_args(root, size, epochs)
        out["aggregate"] = run_stage(code, "aggregate", agg)
        out["aggregate_cached"] = run_stage(code, "aggregate", agg)
    except BaseException:
        shutil.rmtree(root, ignore_errors=True)
        raise
    return out, root


def aggregate_args(root: Path, size: int, epochs: int) -> list[str]:
    return [a for a in overrides(root, size, epochs, 1) if not a.startswith("workers=")]


def changed_once(code: Path, root: Path, size: int, epochs: int) -> dict:
    """aggregate after one trial of the sweep in `root` changed (change_one_trial)."""
    change_one_trial(root / "outputs" / "cache")
    return run_stage(code, "aggregate", aggregate_args(root, size, epochs))


def finish(out: dict, runs: list[dict]) -> dict:
    """`out` with aggregate_one the median of `runs`, and each stage's CPU per trial."""
    out["aggregate_one"] = median_of(runs)
    for stage in STAGES:
        out[stage]["cpu_ms_per_trial"] = round(1000 * out[stage]["cpu_s"] / out["size"], 3)
    return out


def sweep(code: Path, size: int, epochs: int, workers: int, keep: bool) -> dict:
    """Every stage of one sweep of `size` trials on checkout `code`, in a new temporary root."""
    return paired([code], size, epochs, workers, keep, 1)[0]


def paired(codes: list[Path], size: int, epochs: int, workers: int, keep: bool,
           repeat: int) -> list[dict]:
    """sweep() of each checkout, the `repeat` runs of aggregate_one alternating between them."""
    prepared = []
    try:
        for code in codes:
            prepared.append((code, *prepare(code, size, epochs, workers)))
        runs = {code: [] for code in codes}
        for _ in range(repeat):
            for code, _, root in prepared:
                runs[code].append(changed_once(code, root, size, epochs))
        return [finish(out, runs[code]) for code, out, _ in prepared]
    finally:
        for _, _, root in prepared if not keep else ():
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
        args = json.dumps(overrides(root, size, epochs, workers))
        proc = subprocess.run([sys.executable, "-c", PLANNING, args], cwd=code,
                              env=dict(os.environ, PYTHONPATH=str(code)), capture_output=True,
                              text=True)
        if proc.returncode:
            raise RuntimeError(f"planning in {code} exited {proc.returncode}: "
                               f"{proc.stderr[-2000:]}")
        return json.loads(proc.stdout.strip().splitlines()[-1])
    finally:
        shutil.rmtree(root, ignore_errors=True)


def sampled(code: Path, size: int, sample: int, epochs: int, workers: int, keep: bool) -> dict:
    """A sweep of `size` trials measured on a sample: planning all of them (planning), every
    stage on `sample` trials (sweep), and each stage's CPU per trial times `size`."""
    out = sweep(code, sample, epochs, workers, keep)
    out.update(sampled=sample, size=size, **planning(code, size, epochs, workers))
    out["estimated_cpu_s"] = {stage: round(out[stage]["cpu_ms_per_trial"] * size / 1000, 1)
                              for stage in STAGES}
    return out


def packing(n: int, rows: int = 11) -> dict:
    """The cache's layout (per_trial: a Parquet curve and a JSON sidecar each) against a packed
    one (one Parquet of every curve, a key column, and one JSON of every sidecar), on `n`
    synthetic curves of `rows` epochs: files, MB, ms per trial to write and to read back."""
    import hashlib

    import numpy as np
    import pyarrow as pa

    rng = np.random.default_rng(0)
    curves = [pa.table({f.name: pa.array(rng.integers(1, 10, rows) if pa.types.is_integer(
        f.type) else rng.random(rows), f.type) for f in io.TRIAL_CURVE}) for _ in range(n)]
    keys = [f"{i:020x}" for i in range(n)]
    sides = [dict(key=k, M=rng.random((2, 5)).tolist(), status="ok") for k in keys]
    out = {}
    with tempfile.TemporaryDirectory() as tmp:
        one = Path(tmp) / "per_trial"
        t0 = time.process_time()
        for k, c, side in zip(keys, curves, sides):
            side = dict(side, curve_sha256=io.write_table(one / k[:2] / f"{k}.parquet", c))
            io.write_json(one / k[:2] / f"{k}.json", io.seal(side), compact=True)
        t1 = time.process_time()
        for k in keys:
            data = (one / k[:2] / f"{k}.parquet").read_bytes()
            side = io.check_seal(io.parse_json((one / k[:2] / f"{k}.json").read_bytes(), k))
            assert hashlib.sha256(data).hexdigest() == side["curve_sha256"]
            io.parse_table(data, k)
        t2 = time.process_time()
        out["per_trial"] = dict(files=files_under(one), write_ms=1e3 * (t1 - t0) / n,
                                read_ms=1e3 * (t2 - t1) / n)
        packed = Path(tmp) / "packed"
        t0 = time.process_time()
        table = pa.concat_tables([c.append_column("key", pa.array([k] * rows))
                                  for k, c in zip(keys, curves)])
        digest = io.write_table(packed / "curves.parquet", table)
        io.write_json(packed / "sidecars.json", io.seal(dict(curves_sha256=digest, trials=sides)),
                      compact=True)
        t1 = time.process_time()
        data = (packed / "curves.parquet").read_bytes()
        side = io.check_seal(io.parse_json((packed / "sidecars.json").read_bytes(), "pack"))
        assert hashlib.sha256(data).hexdigest() == side["curves_sha256"]
        io.parse_table(data, "pack")
        t2 = time.process_time()
        out["packed"] = dict(files=files_under(packed), write_ms=1e3 * (t1 - t0) / n,
                             read_ms=1e3 * (t2 - t1) / n)
        for name, folder in (("per_trial", one), ("packed", packed)):
            out[name]["mb"] = round(sum(p.stat().st_size for p in folder.rglob("*")
                                        if p.is_file()) / 2**20, 2)
            out[name] = {k: round(v, 4) if isinstance(v, float) else v
                         for k, v in out[name].items()}
    return out


def table(results: list[dict]) -> str:
    head = f"{'checkout':<28} {'trials':>7} {'stage':<17} {'wall s':>8} {'CPU s':>8} " \
           f"{'ms CPU/trial':>12} {'peak MB':>8} {'files':>7}"
    lines = [head, "-" * len(head)]
    for r in results:
        size = f"{r['sampled']}/{r['size']}" if "sampled" in r else str(r["size"])
        for stage in STAGES:
            s = r[stage]
            lines.append(f"{r['code'][-28:]:<28} {size:>7} {stage:<17} {s['wall_s']:>8.2f} "
                         f"{s['cpu_s']:>8.2f} {s['cpu_ms_per_trial']:>12.3f} "
                         f"{s['peak_mb']:>8.1f} {r['files'] if stage == 'simulate' else '':>7}")
        for stage in ("plan", "plan_saved") if "sampled" in r else ():
            s = r[stage]
            lines.append(f"{r['code'][-28:]:<28} {r['size']:>7} {stage:<17} {s['wall_s']:>8.2f} "
                         f"{s['cpu_s']:>8.2f} {1000 * s['cpu_s'] / r['size']:>12.3f} "
                         f"{r['peak_mb']:>8.1f} {'':>7}")
    return "\n".join(lines)


def load() -> str:
    one, five, fifteen = os.getloadavg()
    return f"load average {one:.2f} {five:.2f} {fifteen:.2f} on {os.cpu_count()} CPUs"


# ---- report: a cold report against a baseline; stages: the cached Makefile stages ----------------
def report_args(experiments: list[str], profile: str, out: Path, root: Path = REPO) -> list[str]:
    """The Makefile's report command of `experiments` (pipeline.report's arguments), on the
    aggregates under `root` (this checkout's), into `out` (inside `root`)."""
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
    files = {p.relative_to(a).as_posix() for p in a.rglob("*") if p.is_file()}
    files |= {p.relative_to(b).as_posix() for p in b.rglob("*") if p.is_file()}
    return sorted(f for f in files if not ((a / f).is_file() and (b / f).is_file()
                                           and filecmp.cmp(a / f, b / f, shallow=False)))


def report_pairs(trees: dict, roots: dict, exps: list[str], profile: str, rounds: int) -> tuple:
    """`rounds` pairs of cold reports of the checkouts `trees` (this, baseline) on the aggregates
    under `roots`: (CPU seconds per checkout, the files that differ in the last pair)."""
    cpu, tmps = {t: [] for t in trees}, {}
    try:
        for t in trees:  # a report is written under paths.root only
            (roots[t] / "outputs").mkdir(exist_ok=True)
            tmps[t] = Path(tempfile.mkdtemp(prefix=f".bench_report_{t}_",
                                            dir=roots[t] / "outputs"))
        for r in range(rounds):
            for t in (list(trees) if r % 2 == 0 else list(trees)[::-1]):
                out = tmps[t] / f"{t}{r}"
                cpu[t].append(cold_report(trees[t], report_args(exps, profile, out, roots[t]),
                                          out))
            print(f"round {r + 1}: this {cpu['this'][-1]:.2f} s CPU, baseline "
                  f"{cpu['baseline'][-1]:.2f} s, ratio {cpu['this'][-1] / cpu['baseline'][-1]:.3f}",
                  flush=True)
        last = rounds - 1
        return cpu, differing(tmps["this"] / f"this{last}", tmps["baseline"] / f"baseline{last}")
    finally:
        for tmp in tmps.values():
            shutil.rmtree(tmp, ignore_errors=True)


def report_main(argv: list[str]) -> int:
    from ..experiments import listed
    from ..experiments import config_folders

    ap = argparse.ArgumentParser(prog="python -m pipeline.tools.scale report")
    ap.add_argument("--baseline", type=Path, required=True, help="another checkout")
    ap.add_argument("--rounds", type=int, default=3, help="pairs of reports (default 3)")
    ap.add_argument("--profile", default="smoke", choices=("smoke", "full"))
    ap.add_argument("--experiments", help="comma-separated (default: every make list's)")
    ap.add_argument("--aggregates", choices=("this", "own"), default="this",
                    help="whose aggregates each checkout reports (own: each its own outputs/)")
    a = ap.parse_args(argv)
    bad = ((not (a.baseline / "pipeline" / "report.py").is_file(),
            f"--baseline={a.baseline}: not a checkout of this project"),
           (a.rounds < 1, f"--rounds={a.rounds}: at least 1"))
    for why in (why for is_bad, why in bad if is_bad):
        print(f"error: {why}", file=sys.stderr)
        return 2
    exps = a.experiments.split(",") if a.experiments else listed(config_folders())
    trees = {"this": REPO, "baseline": a.baseline.resolve()}
    roots = {t: (trees[t] if a.aggregates == "own" else REPO) for t in trees}
    try:
        cpu, diff = report_pairs(trees, roots, exps, a.profile, a.rounds)
    except RuntimeError as err:
        return print(f"error: {err}", file=sys.stderr) or 2
    ratios = [x / y for x, y in zip(cpu["this"], cpu["baseline"])]
    print(f"cold {a.profile} report ({len(exps)} experiments), {a.rounds} interleaved pairs: "
          f"this {statistics.median(cpu['this']):.2f} s CPU, baseline "
          f"{statistics.median(cpu['baseline']):.2f} s (medians); median ratio this / baseline "
          f"{statistics.median(ratios):.3f} [{min(ratios):.3f}, {max(ratios):.3f}], "
          f"{1 / statistics.median(ratios):.2f}x faster")
    print(f"files that differ ({len(diff)}): {', '.join(diff) or 'none'}")
    return 0


def stages_main(argv: list[str]) -> int:
    from ..experiments import listed
    from ..experiments import config_folders

    ap = argparse.ArgumentParser(prog="python -m pipeline.tools.scale stages")
    ap.add_argument("--profile", default="smoke", choices=("smoke", "full"))
    ap.add_argument("--repeats", type=int, default=3)
    a = ap.parse_args(argv)
    r = cached_smoke([REPO], ",".join(listed(config_folders())), a.repeats, a.profile)[0]
    print(f"fully cached stages, profile={a.profile}, {a.repeats} repeats (medians):")
    for name in SMOKE_STAGES:
        print(f"  {name:10s} {r[name]['wall_s']:6.1f} s wall  {r[name]['cpu_s']:6.1f} s CPU")
    print(f"  total      {r['cpu_s']:6.1f} s CPU ({', '.join(map(str, r['runs_cpu_s']))})")
    return 0


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    if argv[:1] in (["report"], ["stages"]):
        return (report_main if argv[0] == "report" else stages_main)(argv[1:])
    ap = argparse.ArgumentParser(prog="python -m pipeline.tools.scale", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--sizes", default="1000,10000", help="trials per sweep, comma-separated")
    ap.add_argument("--epochs", type=int, default=10, help="epochs per trial (default 10)")
    ap.add_argument("--workers", type=int, default=2, help="simulate's workers (default 2)")
    ap.add_argument("--baseline", type=Path, help="another checkout to run beside this one")
    ap.add_argument("--out", type=Path, default=REPO / "outputs" / "bench" / "scale.json")
    ap.add_argument("--keep", action="store_true", help="keep the temporary roots")
    ap.add_argument("--sampled", type=int, metavar="N",
                    help="instead of --sizes: plan N trials, run a sample of --sample of them")
    ap.add_argument("--sample", type=int, default=1000, help="trials run for --sampled (1000)")
    ap.add_argument("--smoke-experiments", metavar="E1,E2,...",
                    help="also time a fully cached make smoke of these experiments")
    ap.add_argument("--repeat", type=int, default=3,
                    help="runs of aggregate_one and of the cached smoke, medians (default 3)")
    ap.add_argument("--packing", type=int, metavar="N",
                    help="instead: the cache's files against one packed file, for N trials")
    a = ap.parse_args(argv)
    if a.packing is not None:
        if a.packing < 1:
            return print(f"error: --packing={a.packing}: at least 1 trial", file=sys.stderr) or 2
        print(json.dumps(dict(trials=a.packing, **packing(a.packing), machine=load()), indent=1))
        return 0
    try:
        sizes = [int(s) for s in a.sizes.split(",")]
    except ValueError:
        sizes = []
    if not sizes or any(s < CONDITIONS or s % CONDITIONS for s in sizes):
        print(f"error: --sizes={a.sizes}: positive multiples of {CONDITIONS}", file=sys.stderr)
        return 2
    if a.baseline is not None and not (a.baseline / "pipeline" / "simulate.py").is_file():
        return print(f"error: --baseline={a.baseline}: not a checkout of this project",
                     file=sys.stderr) or 2
    if a.epochs < 1 or a.workers < 1 or a.repeat < 1:
        return print("error: --epochs, --workers and --repeat: at least 1", file=sys.stderr) or 2
    if a.sampled is not None and not (CONDITIONS <= a.sample <= a.sampled and a.sample % CONDITIONS == 0
                                      and a.sampled % CONDITIONS == 0):
        print(f"error: --sampled={a.sampled} --sample={a.sample}: multiples of {CONDITIONS}, "
              "the sample at most the sweep", file=sys.stderr)
        return 2
    codes = [REPO] + ([a.baseline.resolve()] if a.baseline else [])
    results, loads = [], [load()]
    for size in sizes if a.sampled is None else [a.sampled]:
        done = (paired(codes, size, a.epochs, a.workers, a.keep, a.repeat) if a.sampled is None
                else [sampled(code, size, a.sample, a.epochs, a.workers, a.keep)
                      for code in codes])
        results += done
        loads.append(load())
        print("\n".join(table(done).splitlines()[2:]), file=sys.stderr)
    smokes = cached_smoke(codes, a.smoke_experiments, a.repeat) if a.smoke_experiments else []
    if smokes:
        loads.append(load())
    record = dict(epochs=a.epochs, workers=a.workers, conditions=CONDITIONS, repeat=a.repeat,
                  loads=loads,
                  results=results, cached_smoke=smokes)
    a.out.parent.mkdir(parents=True, exist_ok=True)
    a.out.write_text(json.dumps(record, indent=1) + "\n")
    print(table(results))
    print("\n".join(headline(results, smokes)))
    print(f"machine: {loads[0]} before, {loads[-1]} after; written to {a.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
