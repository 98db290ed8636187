"""The first hour, measured: set-up, make smoke and make test in a fresh clone of this checkout.

    python -m pipeline.tools.firsthour [--no-test] [--keep] [--out FILE]    (make first-hour)

The clone is of the committed HEAD, in a temporary folder; each command is timed as a new user
types it (wall, and CPU of the make and every process under it), smoke with the trials it ran,
test with pytest's counts, beside the machine's state. The results (--out, default OUT) are the
pages' named values `first_hour.*` (render: `{{ first_hour.smoke.cpu_min:.1f }}`).
"""
from __future__ import annotations

import argparse
import json
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from .. import io
from . import REPO, timed

OUT = Path("outputs") / "bench" / "first_hour.json"
COUNTS = re.compile(r"(\d+) (passed|skipped|failed|errors?)\b")


def run(cwd: Path, *cmd: str) -> tuple[dict, str]:
    """`cmd` in `cwd`, as typed in a shell (not as make's child): its times and its output."""
    env = {k: v for k, v in os.environ.items()
           if k not in ("MAKEFLAGS", "MFLAGS", "MAKELEVEL", "MAKEOVERRIDES")}
    wall, cpu, _, rc, text = timed(list(cmd), cwd, env, merged=True)
    return dict(wall_s=round(wall, 1), wall_min=round(wall / 60, 2), cpu_s=round(cpu, 1),
                cpu_min=round(cpu / 60, 2), rc=rc), text.decode(errors="replace")


def pytest_counts(text: str) -> dict:
    """pytest's last summary line ("1156 passed, 34 skipped in 812.3s") as {passed: 1156, ...},
    and the tests that failed (its FAILED lines) as failures: [test id, ...]."""
    lines = [ln for ln in text.splitlines() if " in " in ln and COUNTS.search(ln)]
    if not lines:
        return {}
    failures = [ln.split()[1] for ln in text.splitlines() if ln.startswith(("FAILED ", "ERROR "))]
    out = {kind.rstrip("s") if kind.startswith("error") else kind: int(n)
           for n, kind in COUNTS.findall(lines[-1])}
    return dict(out, failures=failures) if failures else out


def machine() -> dict:
    return dict(cores=os.cpu_count(), load_average=[round(x, 2) for x in os.getloadavg()],
                date=time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime()))


def measure(clone: Path, test: bool) -> dict:
    """set-up, smoke (and test) in `clone`; a failing command's tail printed, the rest skipped."""
    out = {}
    for name in ("setup", "smoke", "test")[:3 if test else 2]:
        print(f"make {name} in {clone} ...", file=sys.stderr, flush=True)
        out[name], text = run(clone, "make", name)
        if name == "smoke":  # one sidecar each
            out[name]["trials"] = sum(1 for p in clone.glob("outputs/smoke/cache/trials/*/*.json")
                                      if not p.name.endswith(".state.json"))
        if name == "test":
            out[name].update(pytest_counts(text))
        print(f"  {json.dumps(out[name])}", file=sys.stderr, flush=True)
        if out[name]["rc"] != 0:
            print(text[-3000:], file=sys.stderr)
            break
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m pipeline.tools.firsthour",
                                 description=__doc__.split("\n")[0])
    ap.add_argument("--out", type=Path, default=REPO / OUT, help=f"the results (default: {OUT})")
    ap.add_argument("--no-test", action="store_true", help="set-up and smoke only")
    ap.add_argument("--keep", action="store_true", help="keep the fresh clone")
    args = ap.parse_args(argv)
    tmp = Path(tempfile.mkdtemp(prefix="gbgrowth-first-hour-"))
    clone = tmp / "clone"
    subprocess.run(["git", "clone", "--quiet", str(REPO), str(clone)], check=True)
    head = subprocess.run(["git", "rev-parse", "HEAD"], cwd=REPO, capture_output=True, text=True,
                          check=True).stdout.strip()  # as committed now, whatever comes after
    subprocess.run(["git", "checkout", "--quiet", head], cwd=clone, check=True)
    before = machine()
    try:
        results = measure(clone, not args.no_test)
    finally:
        if args.keep:
            print(f"the clone: {clone}", file=sys.stderr)
        else:
            shutil.rmtree(tmp, ignore_errors=True)
    after = machine()
    doc = dict(commit=head[:7], machine=dict(before, load_average_after=after["load_average"]),
               **results)
    io.write_text(args.out, json.dumps(doc, indent=1) + "\n")
    failed = [name for name, r in results.items() if r["rc"] != 0]
    print(f"{args.out}: written" + (f" (failed: {', '.join(failed)}; its output above)"
                                    if failed else ""), file=sys.stderr)
    return 1 if failed else 0


def values(path: Path) -> dict:
    """The named values of a first_hour.json: `first_hour.<command>.<measure>`, the machine's,
    and as text date, commit, test.counts ("1,156 passed, 34 skipped") and test.failures."""
    if not path.is_file():
        return {}
    doc = json.loads(path.read_text())
    out = {f"first_hour.{cmd}.{k}": float(v) for cmd in ("setup", "smoke", "test")
           for k, v in doc.get(cmd, {}).items() if isinstance(v, (int, float))}
    out.update({f"first_hour.machine.{k}": float(v) for k, v in doc["machine"].items()
                if isinstance(v, (int, float))})
    loads = doc["machine"].get("load_average", [])
    if loads:
        out["first_hour.machine.load_1min"] = float(loads[0])
    counts = ", ".join(f"{doc['test'][k]:,} {k}" for k in ("passed", "failed", "error", "skipped")
                       if doc.get("test", {}).get(k))
    failures = ", ".join(f"`{t}`" for t in doc.get("test", {}).get("failures", [])) or "none"
    return dict(out, **{"first_hour.date": doc["machine"]["date"][:10],
                        "first_hour.commit": doc["commit"], "first_hour.test.counts": counts,
                        "first_hour.test.failures": failures})


if __name__ == "__main__":
    sys.exit(main())
