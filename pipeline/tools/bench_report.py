"""Benchmark: a cold report stage, this checkout against a baseline checkout, in CPU time.

    python -m pipeline.tools.bench_report --baseline /tmp/base               # make smoke's
    python -m pipeline.tools.bench_report --baseline /tmp/base --rounds 5 --profile full
    python -m pipeline.tools.bench_report --baseline /tmp/old --aggregates own

BASELINE is another checkout of the project (`git worktree add /tmp/base <commit>`, or `git
archive <commit> | tar -x -C /tmp/base` and `ln -s $PWD/.venv /tmp/base/.venv`). By default both
checkouts report the aggregates of this one (paths.root: run `make smoke`, or `make reproduce`
for --profile full, here first): the same inputs, so the files of the two reports can be
compared. A baseline whose aggregates have another format (an older commit: its report stops
on what it cannot read) reports its own instead with `--aggregates own`: run the same `make
smoke` in the baseline first (each checkout's outputs/ then holds its own trials and aggregates).

Each round runs the Makefile's report command of both, in turn (A B, then B A, ...), each in a
child process writing into a new folder (under that checkout's outputs/, removed after), so that
nothing is up to date (a cold report: every figure drawn, every table computed); its CPU time
(user + system of the child and its children) is the operating system's. A report that fails
or writes no report.md stops the bench with its error (its time would mean nothing). It prints
each round's seconds and the ratio this / baseline of the pair, their median (the figure to
quote: a pair shares the machine's load, so the ratio keeps its meaning on a loaded machine
where wall time does not), and the files whose bytes differ between the two reports of the last
round (report.md and provenance name the code, so they do; with --aggregates own, every file
made from trials that differ between the two checkouts does too).
"""
from __future__ import annotations

import argparse
import filecmp
import shutil
import statistics
import sys
import tempfile
from pathlib import Path

from .scale import REPO, run_command


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


def main(argv: list[str] | None = None) -> int:
    from ..experiments import listed
    from .experiments import config_folders

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--baseline", type=Path, required=True, help="another checkout")
    ap.add_argument("--rounds", type=int, default=3, help="pairs of reports (default 3)")
    ap.add_argument("--profile", default="smoke", choices=("smoke", "full"))
    ap.add_argument("--experiments", help="comma-separated (default: every make list's)")
    ap.add_argument("--aggregates", choices=("this", "own"), default="this",
                    help="whose aggregates each checkout reports (default this checkout's; own: "
                         "each its own outputs/)")
    a = ap.parse_args(argv)
    if not (a.baseline / "pipeline" / "report.py").is_file():
        print(f"error: --baseline={a.baseline}: not a checkout of this project", file=sys.stderr)
        return 2
    if a.rounds < 1:
        print(f"error: --rounds={a.rounds}: at least 1", file=sys.stderr)
        return 2
    exps = a.experiments.split(",") if a.experiments else listed(config_folders())
    trees = {"this": REPO, "baseline": a.baseline.resolve()}
    roots = {t: (trees[t] if a.aggregates == "own" else REPO) for t in trees}
    cpu = {t: [] for t in trees}
    tmps = {}
    try:
        for t in trees:  # a report is written under paths.root only
            (roots[t] / "outputs").mkdir(exist_ok=True)
            tmps[t] = Path(tempfile.mkdtemp(prefix=f".bench_report_{t}_",
                                            dir=roots[t] / "outputs"))
        for r in range(a.rounds):
            order = list(trees) if r % 2 == 0 else list(trees)[::-1]
            for t in order:
                out = tmps[t] / f"{t}{r}"
                try:
                    cpu[t].append(cold_report(trees[t], report_args(
                        exps, a.profile, out, roots[t]), out))
                except RuntimeError as err:
                    print(f"error: {err}", file=sys.stderr)
                    return 2
            print(f"round {r + 1}: this {cpu['this'][-1]:.2f} s CPU, baseline "
                  f"{cpu['baseline'][-1]:.2f} s, ratio {cpu['this'][-1] / cpu['baseline'][-1]:.3f}",
                  flush=True)
        last = a.rounds - 1
        diff = differing(tmps["this"] / f"this{last}", tmps["baseline"] / f"baseline{last}")
    finally:
        for tmp in tmps.values():
            shutil.rmtree(tmp, ignore_errors=True)
    ratios = [x / y for x, y in zip(cpu["this"], cpu["baseline"])]
    print(f"cold {a.profile} report ({len(exps)} experiments), {a.rounds} interleaved pairs: "
          f"this {statistics.median(cpu['this']):.2f} s CPU, baseline "
          f"{statistics.median(cpu['baseline']):.2f} s (medians); median ratio this / baseline "
          f"{statistics.median(ratios):.3f} [{min(ratios):.3f}, {max(ratios):.3f}], "
          f"{1 / statistics.median(ratios):.2f}x faster")
    print(f"files that differ ({len(diff)}): {', '.join(diff) or 'none'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
