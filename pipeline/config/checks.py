"""Each value checked once, where it enters: the run's settings (check_run) on every run, a
variant's (check_limits) when planned, a trial's by gbmodel (TrialSpec.validate, LIMITS); a
ConfigError of one line naming the key."""
from __future__ import annotations

import dataclasses
import os
from pathlib import Path

from omegaconf import DictConfig, OmegaConf

import gbmodel
from gbmodel.growth import LIMITS as growth_limits
from gbmodel.spec import MAX_EPOCHS, Int, Number, check_int

from ..errors import ConfigError
from .schema import Config


MAX_TRIALS = 10_000  # trials.count: independent trials per condition (the paper's figures use 20)
MAX_PLANNED = 100_000  # trials of one run in all (conditions x variants x trials.count)
MAX_FRAMES = 100  # conditions.frames: the report draws each condition's frames (~0.12 s each)
# key -> its range (gbmodel.spec's constraints): a number of the config outside it is one line
RANGES = {"aggregate.fail_factor": Number(1.0, 1e3, lo_open=True),  # x the median: <= 1 flags
          # half or all
          "conditions.budget_scale": Number(0.0, 1e3, lo_open=True),
          "conditions.growth_share": Number(0.0, 1.0, lo_open=True),
          "conditions.frames": Int(0, MAX_FRAMES, " (the report draws every frame of every "
                                   "condition)"),
          "report.dpi": Number(10, 1200),
          **{f"growth.{k}": growth_limits[k] for k in ("start_size", "end_size", "fixed_scale")}}
EACH = {"conditions.periods": growth_limits["period"],  # list keys: the range of each value
        "conditions.references": growth_limits["end_size"],
        "conditions.snapshots": Int(1, MAX_EPOCHS)}


def declared(key: str, cfg):
    """The declared range of a config key (a gbmodel.spec constraint), or None."""
    section, _, name = key.partition(".")
    if key in RANGES:
        return RANGES[key]
    if section == "growth":
        return growth_limits.get(name)
    if section == "learner":
        if name == "epochs":
            return Int(1, MAX_EPOCHS)
        learner = OmegaConf.select(cfg, "learner.name", default=None)
        if learner in gbmodel.learners.available():
            return getattr(gbmodel.learners.get(learner), "LIMITS", {}).get(name)
    if key == "trials.count":
        return Int(1, MAX_TRIALS)
    return None


STAGE_SECTIONS = ("aggregate", "report")  # check_run's; a trial's are check_limits'


def check_ranges(cfg, stages: bool = False) -> None:
    """A value outside RANGES: the stages' sections' (stages) or the trial's."""
    values = [(k, v, OmegaConf.select(cfg, k, default=None)) for k, v in RANGES.items()
              if (k.split(".")[0] in STAGE_SECTIONS) == stages]
    if not stages:
        values += [(k, v, x) for k, v in EACH.items() for x in OmegaConf.select(cfg, k)]
    for key, constraint, value in values:
        if value is not None and not constraint.ok(value):
            raise ConfigError(f"{key}={value!r}: must be {constraint.describe()}")


def check_limits(cfg) -> None:
    """The trial's ranges and what would overflow or exhaust memory, on each variant's copy
    (a SpecError: plan makes it a ConfigError); the epochs: TrialSpec.validate."""
    Int(1, MAX_TRIALS, " trials per condition").check("trials.count", cfg.trials.count)
    check_ranges(cfg)
    growth_limits["period"].check("growth.period", cfg.growth.get("period"))
    count = cfg.trials.count
    conditions = max(len(cfg.conditions.periods) + len(cfg.conditions.references), 1)
    total = count * conditions * max(len(cfg.conditions.variants), 1)
    if total > MAX_PLANNED:
        raise ConfigError(f"trials.count={count}: {total:,} trials in all ({conditions} "
                          f"conditions x {max(len(cfg.conditions.variants), 1)} variants); "
                          f"at most {MAX_PLANNED:,} per run")


def config_notes(cfg) -> list[str]:
    growth, notes = cfg.growth, []
    start, end, period = growth.get("start_size"), growth.get("end_size"), growth.get("period")
    if (isinstance(start, (int, float)) and isinstance(end, (int, float)) and start > end
            and (period or cfg.conditions.periods)):
        notes.append(f"note: growth.start_size={start} > growth.end_size={end} (size factors): "
                     "the body shrinks over the growth period")
    loop = cfg.body.get("callable") if "body" in cfg else None
    if loop is not None and loop.get("factory"):
        notes.append(f"note: body.callable: the cache key holds {loop.factory}, the source of its "
                     f"module and the files in body.callable.files ({len(loop.get('files') or [])}"
                     "), not the modules it imports, a simulator's version or a robot's state: "
                     "change body.callable.version when those change (gbmodel/body_loop.py)")
    return notes


def check_choices(cfg, overrides, sweep: bool = False) -> str | None:
    """Refuse what a command line would otherwise pass in silence: a body file named unlike its
    body, a period with growth=none (in a `sweep`: a note, returned), one longer than the run."""
    given = {o.lstrip("+~").split("=", 1)[0]: o.split("=", 1)[1] for o in overrides if "=" in o}
    body = given.get("body")
    if body is not None and "body.name" not in given and cfg.body.name != body:
        raise ConfigError(f"body={body}: its file {body}.yaml says name: {cfg.body.name}; a body "
                          f"file is named after its body (rename one of them)")
    g = cfg.growth
    if g.pattern == "none" and g.period and sweep:
        return (f"note: growth.period={g.period} is ignored in the jobs of growth=none (a body "
                "of one size has no period); the sweep's growing jobs use it")
    if g.pattern == "none" and g.period:
        raise ConfigError(f"growth.period={g.period}: growth=none keeps the body at one size, so "
                          "it has no period; drop growth.period or choose a growth pattern "
                          "(growth=proportional)")
    epochs = cfg.learner.epochs
    if ("growth.period" in given and g.pattern != "none" and not cfg.conditions.periods
            and cfg.conditions.budget is None and isinstance(epochs, int)
            and isinstance(g.period, int) and g.period > epochs):
        raise ConfigError(f"growth.period={g.period}: longer than the run (learner.epochs="
                          f"{epochs}), so the body never reaches its end size; choose a period "
                          "of at most learner.epochs")
    return None


def check_keys(cfg) -> None:
    """Refuse a top-level key the schema does not know (`+foo=1` composes without a word)."""
    known = {f.name for f in dataclasses.fields(Config)}
    unknown = sorted(set(cfg.keys()) - known - {"hydra"})
    if unknown:
        raise ConfigError(f"{unknown[0]}: not a config key; the top-level keys are "
                          f"{', '.join(sorted(known))}")


def check_names(cfg) -> None:
    """Every name of the config that becomes part of a path (pipeline.io.safe_name)."""
    from ..io import UnsafeName, safe_name

    try:
        safe_name("figure", cfg.figure)
        safe_name("report.joint_space_figure", cfg.report.joint_space_figure)
        for name, panels in cfg.report.postures.items():
            safe_name("report.postures", name)
            for panel in panels or ():
                if panel:
                    safe_name(f"report.postures.{name}", str(panel[0]))
    except UnsafeName as err:
        raise ConfigError(str(err)) from None


def check_stamp(cfg) -> None:
    """report.stamp_findings (the committed numbers) only with report.publish."""
    if cfg.report.stamp_findings and not cfg.report.publish:
        raise ConfigError("report.stamp_findings=true: only with report.publish=true (make "
                          "stamp, after make studies); this run's numbers are not "
                          "the committed report's")


def check_paths(cfg: DictConfig) -> None:
    """paths.root is absolute; every output folder lies under it and is (or can become) a
    folder, writable but the cache (a read-only cache is read; a write it needs fails in one
    line in cli.finish)."""
    root = cfg.paths.root
    if not isinstance(root, str) or not root.strip():
        raise ConfigError(f"paths.root={root!r}: must be a folder (an absolute path)")
    if not Path(root).is_absolute():
        raise ConfigError(f"paths.root={root!r}: must be an absolute path (it would be "
                          f"{Path(root).resolve()} here); e.g. paths.root=$PWD/{root}")
    base = Path(root).resolve()
    for key in ("root", "out", "cache", "aggregate", "report", "published", "bench"):
        path = Path(cfg.paths[key])
        if key != "root" and (not path.is_absolute() or ".." in path.parts):
            raise ConfigError(f"paths.{key}={str(path)!r}: must be an absolute path without '..'")
        if key != "root" and path.resolve() != base and base not in path.resolve().parents:
            raise ConfigError(f"paths.{key}={str(path)!r}: outside paths.root={root}")
        for p in [path, *path.parents]:
            if p.exists():
                if not p.is_dir():
                    raise ConfigError(f"paths.{key}={str(path)!r}: {p} is a file, not a folder")
                if key != "cache" and not os.access(p, os.W_OK | os.X_OK) and p == path:
                    raise ConfigError(f"paths.{key}={str(path)!r}: is not writable")
                break


def check_run(cfg: DictConfig) -> None:
    """The run's own settings (not its trials': check_limits)."""
    check_int("trials.root_seed", cfg.trials.root_seed, 0)
    check_int("workers", cfg.workers, 1)
    check_ranges(cfg, stages=True)
    check_paths(cfg)
    check_names(cfg)
    check_stamp(cfg)
