"""Benchmark: the pipeline's stages on a fully cached tree, as whole commands.

    python -m pipeline.tools.bench_stages                 # make smoke's three stages, 3 times
    python -m pipeline.tools.bench_stages --profile full  # make reproduce's (needs its cache)

It runs `make smoke` (or the full pipeline without publishing) once to fill or confirm the cache,
then times each stage command of the Makefile `--repeats` times and prints the median (and
min/max) seconds of simulate, aggregate, report and their sum. A fully cached run should take
seconds: its cost grows with what changed, not with what was ever computed.
"""
from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
import time

from ..config import REPO_ROOT

STAGES = ("simulate", "aggregate", "report")


def stage_command(stage: str, profile: str) -> list[str]:
    return ["make", "--no-print-directory", "-C", str(REPO_ROOT), stage, f"PROFILE={profile}"]


def timed(cmd: list[str]) -> float:
    t0 = time.perf_counter()
    r = subprocess.run(cmd, capture_output=True, text=True)
    if r.returncode != 0:
        sys.exit(f"error: {' '.join(cmd)} exited {r.returncode}: {r.stderr.strip()[-300:]}")
    return time.perf_counter() - t0


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--profile", default="smoke", choices=("smoke", "full"))
    ap.add_argument("--repeats", type=int, default=3)
    args = ap.parse_args(argv)
    for stage in STAGES:  # fill (or confirm) the cache and every stage's outputs
        timed(stage_command(stage, args.profile))
    times = {s: [] for s in STAGES}
    for _ in range(args.repeats):
        for s in STAGES:
            times[s].append(timed(stage_command(s, args.profile)))
    totals = [sum(ts) for ts in zip(*times.values())]
    print(f"fully cached stages, profile={args.profile}, {args.repeats} repeats "
          "(median [min, max] seconds):")
    for name, ts in [*times.items(), ("total", totals)]:
        print(f"  {name:10s} {statistics.median(ts):6.1f}  [{min(ts):.1f}, {max(ts):.1f}]")
    return 0


if __name__ == "__main__":
    sys.exit(main())
