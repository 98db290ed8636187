"""Results you can pick up: the trained models beside the report, what produced the report, and
the credits of the third-party robot models.

- `write_models`: models/<figure>.json in the report folder, per condition its trial spec and
  every trial's final inverse estimate M (no snapshots: a few kB per condition), the layout of
  the aggregate's models.json, so `pipeline.models.load(figure)` reads it on a fresh clone.
- `markdown`: the provenance block (when, by which command line and gbgrowth version, commit,
  lock file hash, Python and key package versions, CPU model, trials per figure and their CPU
  time, measured and estimated) and the credits section.

Two lines vary between two runs of the same checkout: the date and command line, and the
measured CPU time (the seconds each trial took when it was computed, whichever run computed
it: pipeline.cache.read_times; a trial computed before times were kept counts as unmeasured).
Everything else in the report is reproducible byte for byte, and so is the block within one
process (the date is taken once). The estimate beside it is the plan's cost model
(pipeline.plan.cost) in CPU seconds (pipeline.plan.cpu_seconds).
"""
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
from .sections import Context, register

PACKAGES = ("numpy", "numba", "scipy", "pandas", "pyarrow", "matplotlib", "hydra-core",
            "omegaconf")
LOCK = REPO_ROOT / "requirements.lock"
def write_models(aggs: dict, out: Path) -> list[Path]:
    """models/<figure>.json per figure with a model: each condition's spec and every trial's
    final M (rounded to float32's precision, 9 significant digits: the posture it gives
    differs by < 1e-6 rad), sealed (pipeline.models.load checks the seal); conditions of
    learners without a model are left out."""
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
    if isinstance(M, list):
        return [_rounded(x) for x in M]
    return float(f"{M:.9g}")


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
    """HEAD's commit, with `+ uncommitted changes` when the work tree differs from it (report
    files and outputs left out: the report being written is not part of what produced it)."""
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
    """The command line that runs this report stage with its overrides, as typed (`gbgrowth
    report ...` or `python -m pipeline.report ...`); for a call from Python, says so."""
    from hydra.core.hydra_config import HydraConfig

    if not HydraConfig.initialized():
        return "pipeline.report.report(cfg) from Python"
    hc = HydraConfig.get()
    prog = sys.argv[0]  # `gbgrowth report` (pipeline.__main__), else a file's path
    if not prog.startswith("gbgrowth "):
        prog = f"python -m pipeline.{hc.job.name}"
    return " ".join([prog, *(shlex.quote(o) for o in hc.overrides.task)])


def measured_costs(aggs: dict, out_dir) -> dict[str, tuple[int, float]]:
    """figure -> (trials measured, their CPU seconds) from the times each run kept
    (pipeline.cache.read_times under paths.out)."""
    from ..cache import read_times

    times, out = read_times(out_dir), {}
    for name, agg in aggs.items():
        found = [times[t["key"]] for c in agg["models"]["conditions"].values()
                 for t in c["trials"].values() if isinstance(t, dict) and t.get("key") in times]
        out[name] = (len(found), sum(found))
    return out


def distinct_costs(aggs: dict, out_dir) -> tuple[int, int, float, float]:
    """Over the trials of every figure, each counted once however many figures share it
    (pipeline.plan.stream: the same condition's trials are one set of files): (trials,
    trials measured, their measured CPU seconds, the estimated CPU seconds of all)."""
    from ..cache import read_times
    from ..plan import cost

    times = read_times(out_dir) if out_dir is not None else {}
    est, seen = {}, {}
    for agg in aggs.values():
        for c in agg["models"]["conditions"].values():
            units = None
            for i, t in {**c["trials"], **c.get("diverged", {})}.items():
                key = t.get("key") if isinstance(t, dict) else None
                key = key or (id(c), i)  # no key recorded: this condition's own trial
                if key not in est:
                    units = cost(dict(spec=c["spec"])) if units is None else units
                    est[key] = cpu_seconds(units, 1)
                    if key in times:
                        seen[key] = times[key]
    return len(est), len(seen), sum(seen.values()), sum(est.values())


def _duration(seconds: float) -> str:
    return f"{seconds:.1f} s" if seconds < 60 else f"{seconds / 60:.1f} min"


def figure_costs(aggs: dict) -> dict[str, tuple[int, float]]:
    """figure -> (trials, estimated CPU seconds) from each trial's spec (pipeline.plan.cost)."""
    from ..plan import cost

    out = {}
    for name, agg in aggs.items():
        n, units = 0, 0.0
        for c in agg["models"]["conditions"].values():
            k = len(c["trials"]) + len(c.get("diverged", {}))
            n += k
            units += k * cost(dict(spec=c["spec"]))
        out[name] = (n, cpu_seconds(units, n))
    return out


def credits(aggs: dict) -> list[str]:
    """Markdown lines crediting the third-party robot models the report's trials used: each
    body's `credits` (its conf/body/<name>.yaml), once per model."""
    used = {}
    for a in aggs.values():
        for c in a["models"]["conditions"].values():
            given = c["spec"]["body"].get("credits")
            if given:
                used[given["model"]] = given
    return [f"- {c['model']}: {c['source']}; licence {c['licence']}"
            for _, c in sorted(used.items())]


def markdown(aggs: dict, out_dir=None) -> list[str]:
    """The report's provenance block and credits section (markdown lines); out_dir: paths.out,
    whose runs kept the measured CPU times (None: not measured)."""
    from .. import __version__

    lock = (hashlib.sha256(LOCK.read_bytes()).hexdigest()[:16] if LOCK.exists()
            else "no requirements.lock")
    v = versions()
    measured = measured_costs(aggs, out_dir) if out_dir is not None else {}
    md = ["## Provenance", "",
          f"- made {made_at()} by gbgrowth {__version__}: `{command_line()}`",
          f"- commit: `{commit()}`",
          f"- requirements.lock: sha256 `{lock}`",
          "- " + ", ".join(f"{k} {val}" for k, val in v.items()),
          f"- CPU: {cpu_model()}", "",
          "| figure | trials | CPU time (measured) | CPU time (estimated) |",
          "|---|---|---|---|"]
    for name, (n, seconds) in figure_costs(aggs).items():
        k, spent = measured.get(name, (0, 0.0))
        mine = ("not measured" if k == 0 else _duration(spent)
                + (f" ({k} of {n} trials)" if k < n else ""))
        md.append(f"| {name} | {n} | {mine} | {_duration(seconds)} |")
    n, k, spent, seconds = distinct_costs(aggs, out_dir)
    mine = ("not measured" if k == 0 else _duration(spent)
            + (f" ({k} of {n} trials)" if k < n else ""))
    md.append(f"| all, each shared trial once | {n} | {mine} | {_duration(seconds)} |")
    md += ["", "CPU time: measured, the CPU seconds each trial took when it was computed (any "
           "run; a trial cached before times were kept is not measured); estimated, the plan's "
           "cost model (pipeline.plan.cost), calibrated on whole trials "
           "(pipeline.plan.cpu_seconds); the last row counts a trial that several figures "
           "share (the same condition, pipeline.plan.stream) once. The final models of every "
           "condition: `models/<figure>.json` (`pipeline.models.load(path)`).", ""]
    lines = credits(aggs)
    md += ["## Credits", "",
           "The Goal Babbling model and the paper's bodies: Rolf, Steil and Gienger (2010), "
           "reproduced here."] + ([""] + ["Third-party robot models used by this report:", ""]
                                 + lines if lines else []) + [""]
    return md


@register("provenance", 1000)
def section(ctx: Context) -> list[str]:
    """The report's last section: the paper figures' trained models (models/<figure>.json),
    what produced the report, and the credits of the robot models it used."""
    if not ctx.groups:
        return []
    ctx.written.extend(write_models(ctx.of("figures"), ctx.out))
    every = {k: a for group in ctx.groups.values() for k, a in group.items()}
    return markdown(dict(sorted(every.items())), ctx.cfg.paths.out)
