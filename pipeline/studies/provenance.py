"""Results you can pick up: the trained models beside the report (models/<figure>.json, read by
pipeline.models.load), what produced the report and the credits of the third-party robot models.
Only the date, command line and measured CPU times (pipeline.cache.read_times) vary between two
runs of one checkout; the estimate is the plan's cost model (pipeline.plan.cost, cpu_seconds)."""
from __future__ import annotations

import functools
import hashlib
import json
import platform
import shlex
import subprocess
import sys
import time
from importlib import metadata
from pathlib import Path

from ..config import IN_CHECKOUT, REPO_ROOT
from ..plan import cpu_seconds  # the CPU seconds of trials of pipeline.plan.cost
from .sections import Context, prose, register

PACKAGES = ("numpy", "numba", "scipy", "pandas", "pyarrow", "matplotlib", "hydra-core",
            "omegaconf")
LOCK = REPO_ROOT / "requirements.lock"


def write_models(aggs: dict, out: Path) -> list[Path]:
    """models/<figure>.json, sealed: each condition's spec and every trial's final M to 9
    significant digits (postures within 1e-6 rad); learners without a model are left out."""
    from .. import io

    written = []
    for name, agg in aggs.items():
        conds = {}
        for label, c in agg["models"]["conditions"].items():
            trials = {i: {"M": _rounded(t["M"])} for i, t in c["trials"].items()
                      if t.get("M") is not None}
            if trials:
                conds[label] = dict(spec=c["spec"], trials=trials)
        if conds:
            path = out / "models" / f"{name}.json"
            io.write_text(path, json.dumps(io.seal(dict(figure=name, conditions=conds)),
                                           sort_keys=True, separators=(",", ":")) + "\n")
            written.append(path)
    return written


def _rounded(M):
    return [_rounded(x) for x in M] if isinstance(M, list) else float(f"{M:.9g}")


def _git(*args) -> str | None:
    if not IN_CHECKOUT:  # installed: site-packages may lie in some other repository
        return None
    try:
        r = subprocess.run(["git", "-C", str(REPO_ROOT), *args], capture_output=True, text=True,
                           timeout=30)
    except (OSError, subprocess.SubprocessError):
        return None
    return r.stdout.strip() if r.returncode == 0 else None


def commit() -> str:
    """HEAD's commit, `+ uncommitted changes` when the work tree (outputs/ aside) differs."""
    head = _git("rev-parse", "HEAD")
    if head is None:
        return "unknown (not a git checkout)"
    dirty = _git("status", "--porcelain", "--untracked-files=no", "--", ".", ":!outputs")
    return head + (" + uncommitted changes" if dirty else "")


def cpu_model() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def versions() -> dict[str, str]:
    out = {"python": platform.python_version()}
    for p in PACKAGES:
        try:
            out[p] = metadata.version(p)
        except metadata.PackageNotFoundError:
            out[p] = "not installed"
    return out


@functools.lru_cache(maxsize=None)
def made_at() -> str:
    """This process's date and time (UTC, to the minute), taken once."""
    return time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime())


def command_line() -> str:
    """This report stage's command line with its overrides, as typed (or a call from Python)."""
    from hydra.core.hydra_config import HydraConfig

    if not HydraConfig.initialized():
        return "pipeline.report.report(cfg) from Python"
    hc = HydraConfig.get()
    prog = sys.argv[0]  # `gbgrowth report` (pipeline.__main__), else a file's path
    if not prog.startswith("gbgrowth "):
        prog = f"python -m pipeline.{hc.job.name}"
    return " ".join([prog, *(shlex.quote(o) for o in hc.overrides.task)])


def costs(aggs: dict, out_dir, times: dict | None = None) -> tuple[dict, tuple]:
    """figure -> (trials, trials measured, their measured CPU seconds, estimated CPU seconds), and
    the same over every figure counting a trial several figures share (pipeline.plan.stream)
    once; measured: the times the runs under out_dir kept (None: not measured), or `times`."""
    from ..cache import read_times
    from ..plan import cost

    if times is None:
        times = read_times(out_dir) if out_dir is not None else {}
    out, est, seen = {}, {}, {}
    for name, agg in aggs.items():
        n = k = 0
        spent = units = 0.0
        for c in agg["models"]["conditions"].values():
            u, m = cost(dict(spec=c["spec"])), len(c["trials"]) + len(c.get("diverged", {}))
            n, units = n + m, units + m * u
            for i, t in {**c["trials"], **c.get("diverged", {})}.items():
                key = (t.get("key") if isinstance(t, dict) else None) or (id(c), i)
                est.setdefault(key, cpu_seconds(u, 1))
                if key in times:
                    seen[key] = times[key]
            mine = [times[t["key"]] for t in c["trials"].values()
                    if isinstance(t, dict) and t.get("key") in times]
            k, spent = k + len(mine), spent + sum(mine)
        out[name] = (n, k, spent, cpu_seconds(units, n))
    return out, (len(est), len(seen), sum(seen.values()), sum(est.values()))


def _duration(seconds: float) -> str:
    return f"{seconds:.1f} s" if seconds < 60 else f"{seconds / 60:.1f} min"


def credits(aggs: dict) -> list[str]:
    """A line per third-party robot model the trials used (each body file's `credits`)."""
    used = {}
    for a in aggs.values():
        for c in a["models"]["conditions"].values():
            given = c["spec"]["body"].get("credits")
            if given:
                used[given["model"]] = given
    return [f"- {c['model']}: {c['source']}; licence {c['licence']}"
            for _, c in sorted(used.items())]


def markdown(aggs: dict, out_dir=None, apart: tuple = ()) -> list[str]:
    """The provenance block and credits (markdown lines); out_dir: as costs(); apart: figures
    (the replicate sets) whose CPU time is also given in a row of its own, and the rest in
    another."""
    from .. import __version__
    from ..cache import read_times

    lock = (hashlib.sha256(LOCK.read_bytes()).hexdigest()[:16] if LOCK.exists()
            else "no requirements.lock")
    times = read_times(out_dir) if out_dir is not None else {}  # read once for every row
    per, total = costs(aggs, out_dir, times)

    def row(name, n, k, spent, seconds):
        mine = ("not measured" if k == 0 else _duration(spent)
                + (f" ({k} of {n} trials)" if k < n else ""))
        return f"| {name} | {n} | {mine} | {_duration(seconds)} |"
    md = ["## Provenance", "",
          f"- made {made_at()} by gbgrowth {__version__}: `{command_line()}`",
          f"- commit: `{commit()}`", f"- requirements.lock: sha256 `{lock}`",
          "- " + ", ".join(f"{k} {val}" for k, val in versions().items()),
          f"- CPU: {cpu_model()}", "",
          "| figure | trials | CPU time (measured) | CPU time (estimated) |", "|---|---|---|---|"]
    md += [row(name, *c) for name, c in per.items()]
    if apart:
        md += [row("all but the replicate sets, each shared trial once", *costs(
                   {k: a for k, a in aggs.items() if k not in apart}, out_dir, times)[1]),
               row(f"the replicate sets ({', '.join(apart)})",
                   *costs({k: aggs[k] for k in apart}, out_dir, times)[1])]
    md.append(row("all, each shared trial once", *total))
    md += ["", prose("provenance.cpu"), ""]
    lines = credits(aggs)
    md += ["## Credits", "", prose("provenance.credits")] + ([""] + ["Third-party robot models used by this report:", ""]
                                 + lines if lines else []) + [""]
    return md


@register("provenance", 1000)
def section(ctx: Context) -> list[str]:
    if not ctx.groups:
        return []
    ctx.written.extend(write_models(ctx.of("figures"), ctx.out))
    every = {k: a for group in ctx.groups.values() for k, a in group.items()}
    return markdown(dict(sorted(every.items())), ctx.cfg.paths.out,
                    apart=tuple(sorted(ctx.of("replicate"))))
