"""Results you can pick up: the trained models beside the report, what produced the report, and
the credits of the third-party robot models.

- `write_models`: models/<figure>.json in the report folder, per condition its trial spec and
  every trial's final inverse estimate M (no snapshots: a few kB per condition), the layout of
  the aggregate's models.json, so `pipeline.models.load(figure)` reads it on a fresh clone.
- `markdown`: the provenance block (commit, lock file hash, Python and key package versions,
  CPU model, trials per figure and their estimated CPU time) and the credits section.

The block holds nothing that varies between two runs of the same checkout on the same machine
(no dates, no measured times), so the report's bytes stay reproducible. CPU time per figure is
the plan's cost model (pipeline.plan.cost) times SECONDS_PER_COST, not a measurement of this run: the cache does not keep
timings, so a cached trial costs the same whoever computed it.
"""
from __future__ import annotations

import hashlib
import json
import platform
import subprocess
from importlib import metadata
from pathlib import Path

from ..config import REPO_ROOT
from ..plan import SECONDS_PER_COST  # CPU seconds per unit of pipeline.plan.cost
from .sections import Context, register

PACKAGES = ("numpy", "numba", "scipy", "pandas", "pyarrow", "matplotlib", "hydra-core",
            "omegaconf")
LOCK = REPO_ROOT / "requirements.lock"
# Third-party robot models a report may use: body name -> (what, source, licence)
CREDITS = {
    "icub_urdf": ("the iCub's URDF (model iCubLisboa01)", "robotology/icub-models, PyPI "
                  "package icub-models", "CC-BY-SA-4.0"),
    "ergo_jr": ("the Poppy Ergo Jr's URDF", "poppy-project/poppy-ergo-jr, PyPI package "
                "poppy-ergo-jr", "GPL-3.0"),
    **{body: (f"the MJCF model {file} of Gymnasium's {env} (from OpenAI Gym)",
              "Farama-Foundation/Gymnasium, PyPI package gymnasium", "MIT")
       for body, file, env in (("pusher", "pusher.xml", "Pusher"),
                               ("reacher", "reacher.xml", "Reacher"),
                               ("humanoid_arm", "humanoid.xml", "Humanoid"))},
}


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
        out[name] = (n, units * SECONDS_PER_COST)
    return out


def credits(aggs: dict) -> list[str]:
    """Markdown lines crediting the third-party robot models the report's trials used."""
    used = {c["spec"]["body"].get("name") for a in aggs.values()
            for c in a["models"]["conditions"].values()}
    lines = [f"- {what}: {src}; licence {lic}" for body, (what, src, lic) in CREDITS.items()
             if body in used]
    return lines


def markdown(aggs: dict) -> list[str]:
    """The report's provenance block and credits section (markdown lines)."""
    lock = (hashlib.sha256(LOCK.read_bytes()).hexdigest()[:16] if LOCK.exists()
            else "no requirements.lock")
    v = versions()
    md = ["## Provenance", "",
          f"- commit: `{commit()}`",
          f"- requirements.lock: sha256 `{lock}`",
          "- " + ", ".join(f"{k} {val}" for k, val in v.items()),
          f"- CPU: {cpu_model()}", "",
          "| figure | trials | CPU time (estimated) |", "|---|---|---|"]
    for name, (n, seconds) in figure_costs(aggs).items():
        md.append(f"| {name} | {n} | " + (f"{seconds:.1f} s |" if seconds < 60
                                           else f"{seconds / 60:.1f} min |"))
    md += ["", "CPU time: the plan's cost model (pipeline.plan.cost) on Goal Babbling's "
           "calibration (pipeline.tools.bench_costs), not a measurement of this run. The final models of every "
           "condition: `models/<figure>.json` (`pipeline.models.load(figure)`).", ""]
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
    return markdown(dict(sorted(every.items())))
