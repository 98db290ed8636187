"""Config schema (dataclasses registered in Hydra's ConfigStore) and config helpers.

The YAML files under conf/ extend these dataclasses, so a misspelt key or a value of the wrong type
fails when the config is composed, before any stage starts. The sections that describe a trial
(body, growth, learner, evaluation) are generated from gbmodel's own dataclasses, so every value
of the numerical core has one source: its default in gbmodel, or the YAML file that changes it.
Checks of *values* live in gbmodel (TrialSpec.validate) and pipeline.plan.
"""
from __future__ import annotations

import dataclasses
import hashlib
import json
import os
import pkgutil
import socket
import sys
import time
import types
import typing
from functools import lru_cache
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Optional

from hydra.core.config_store import ConfigStore
from omegaconf import MISSING, DictConfig, OmegaConf, open_dict

import gbmodel
from gbmodel import evaluation
from gbmodel.growth import LIMITS as growth_limits
from gbmodel.spec import MAX_EPOCHS, MAX_INT64, MAX_SIZE, Int, Number

from . import engines, searchpath
from .errors import ConfigError
from .experiments import Declares, config_folders, listed  # noqa: F401 (config_folders: its home was here)

REPO_ROOT = Path(__file__).resolve().parents[1]  # the checkout (installed: site-packages)
CONF_DIR = gbmodel.bodies.CONF_DIR  # conf/ of the checkout, else the installed gbgrowth_conf
IN_CHECKOUT = CONF_DIR == REPO_ROOT / "conf"
# every stage's @hydra.main takes config_path=CONFIG_PATH: the checkout's folder, else the
# installed package through Hydra's package search path; a conf/ of the working directory is
# added after it (pipeline/searchpath.py), hydra.searchpath after that
CONFIG_PATH = str(CONF_DIR) if IN_CHECKOUT else f"pkg://{gbmodel.bodies.CONF_PACKAGE}"


def default_root() -> str:
    """paths.root unless given: the checkout (make and every documented command write into its
    outputs/, wherever they are started), else the working directory (an installed package)."""
    return str(REPO_ROOT) if IN_CHECKOUT else os.getcwd()


def defaults_of(cls) -> list[tuple[str, Any, Any]]:
    """(name, type, default) of each field of dataclass `cls` that has a default."""
    hints = typing.get_type_hints(cls)
    return [(f.name, hints[f.name], f.default) for f in dataclasses.fields(cls)
            if f.default is not dataclasses.MISSING]


def schema_of(cls, name: str, extra: tuple = (), defaults: list | None = None) -> type:
    """A Hydra schema with the fields (types and defaults) of gbmodel dataclass `cls` (or the
    `defaults` of defaults_of(cls) given), plus `extra` (name, type, default) fields."""
    fields = [(k, kind, field(default=v))
              for k, kind, v in (defaults_of(cls) if defaults is None else defaults)]
    return dataclasses.make_dataclass(name, list(extra) + fields)


def conf_of(cls, name: str) -> type:
    """A Hydra schema with every field of gbmodel dataclass `cls`, its type and its default (a
    field without one is MISSING: it must be given); a field whose type is a dataclass gets that
    class's schema, generated the same way."""
    hints = typing.get_type_hints(cls)
    out = []
    for f in dataclasses.fields(cls):
        kind = hints[f.name]
        if dataclasses.is_dataclass(kind):
            kind = conf_of(kind, f"{kind.__name__}Conf")
            out.append((f.name, kind, field(default_factory=kind)))
        elif f.default_factory is not dataclasses.MISSING:
            out.append((f.name, kind, field(default_factory=f.default_factory)))
        else:
            default = MISSING if f.default is dataclasses.MISSING else f.default
            out.append((f.name, kind, field(default=default)))
    return dataclasses.make_dataclass(name, out)


# body: gbmodel.bodies.Description's fields (conf/body/<name>.yaml). It goes into every trial's
# spec, so editing one body's file recomputes that body's trials only.
BodyConf = conf_of(gbmodel.bodies.Description, "BodyConf")
# growth: gbmodel.Growth's fields; pattern `none` is a body of constant size end_size
GrowthConf = schema_of(gbmodel.Growth, "GrowthConf")
EvaluationConf = dataclasses.make_dataclass(
    "EvaluationConf", [(k, type(v), field(default=v)) for k, v in evaluation.DEFAULTS.items()])
LEARNER_EXTRA = (("name", str, field(default=MISSING)), ("epochs", int, field(default=MISSING)),
                 ("evals_per_decade", int, field(default=MISSING)))


@dataclass
class TrialsConf:
    count: int = MISSING
    root_seed: int = MISSING


@dataclass
class PathsConf:
    root: str = MISSING
    out: str = MISSING
    cache: str = MISSING
    aggregate: str = MISSING
    report: str = MISSING
    published: str = MISSING
    bench: str = MISSING


@dataclass
class VariantConf:
    """One variant of an experiment: a label and the dotted overrides that make it."""

    label: str = MISSING
    choice: str = ""  # what is varied (a row group of the choices table)
    chosen: bool = False  # the value this project uses
    set: list[str] = field(default_factory=list)  # e.g. ["learner.learning_rate=0.5"]


@dataclass
class ConditionsConf:
    """What an experiment sweeps. Empty lists: the single condition of the growth group."""

    periods: list[int] = field(default_factory=list)  # growth periods T_G, one condition each
    references: list[float] = field(default_factory=list)  # constant sizes run as references
    snapshots: list[int] = field(default_factory=list)  # epochs after which M is stored
    # more epochs after which M is stored: this many, log-spaced over 1 ... epochs (the report's
    # animation of each condition, pipeline/studies/animation.py); 0: none
    frames: int = 0
    variants: list[VariantConf] = field(default_factory=list)  # each: all of the above again
    # a budget of reaching movements (forward-kinematics samples) per trial instead of epochs:
    # each learner gets budget / its samples per epoch epochs, growing over growth_share of them
    budget: Optional[int] = None
    growth_share: float = 0.5
    budget_scale: float = 1.0  # profiles shrink the budget (smoke)
    # a continuation: each trial starts from the saved state after this many epochs of the trial
    # of its condition and index under the experiment's settings without its variants
    # (pipeline.checkpoint); a multiple of 1000 (the draw block), ignored where the run has no
    # more epochs (the smoke profile); null: every trial starts at epoch 1
    continues: Optional[int] = None


@dataclass
class PaperConf:
    title: str = ""
    final_abs_error: Optional[float] = None  # the paper's stated final accuracy [m], if any
    # whether the report checks the paper's claims on this experiment: its figures and studies
    # declare it; a custom experiment does not, and is reported by its curves alone
    claims: bool = False
    # the report section that reports it (pipeline/studies/sections.py): figures, readings,
    # baselines, explain, choices, or a study of one's own
    study: str = "figures"
    # the figure whose cells the scorecard's headline counts instead of this one's, when both
    # are reported (Fig. 7 on fig7_20trials); this one's are shown beside
    judged_on: Optional[str] = None


@dataclass
class AggregateConf:
    fail_factor: float = MISSING


@dataclass
class ReportConf:
    dpi: int = MISSING
    log_error_axis: bool = MISSING
    postures: dict[str, Any] = MISSING
    joint_space_figure: str = MISSING
    publish: bool = False  # write the committed report (paths.published): make reproduce / make studies only
    paper_experiments: list[str] = MISSING  # what the committed report must hold, at full scale
    stamp_findings: bool = False  # record these numbers as the ones findings.md discusses
    # a GIF per figure and condition whose trial 0 stored >= 2 models (conditions.frames)
    animate: bool = True
    explain: bool = True  # the explanation rows, read from the explain_* aggregates (explain.py)
    scale: str = ""  # a reduced scale the title names ("smoke"; set by the profile), "" = as set


@dataclass
class BenchConf:
    repeats: int = 5  # timed trials per body and path (medians are reported)
    parallel: bool = True  # also time 8 arm5 trials on 1 and on 2 workers


@dataclass
class Config:
    body: BodyConf = field(default_factory=BodyConf)
    growth: Any = field(default_factory=GrowthConf)
    learner: Any = MISSING
    evaluation: Any = field(default_factory=EvaluationConf)
    trials: TrialsConf = field(default_factory=TrialsConf)
    paths: PathsConf = field(default_factory=PathsConf)
    conditions: ConditionsConf = field(default_factory=ConditionsConf)
    paper: PaperConf = field(default_factory=PaperConf)
    # where the experiment belongs: its make list and place, what it reads (pipeline.experiments)
    declares: Declares = field(default_factory=Declares)
    aggregate: AggregateConf = field(default_factory=AggregateConf)
    report: ReportConf = field(default_factory=ReportConf)
    engine: Any = MISSING  # where the trials run: engine=<name> (pipeline.engines, generated)
    bench: BenchConf = field(default_factory=BenchConf)
    figure: str = MISSING
    workers: int = MISSING
    # simulate: plan these experiments in one process (make smoke / make reproduce); the
    # other overrides of the command line apply to each
    experiments: list[str] = field(default_factory=list)


def register_schemas() -> None:
    """The primary schema, and one schema per learner (`learner/<name>_schema`) that its YAML
    file extends: the learner's Params fields with their defaults, plus name and epochs. A
    learner module not imported yet is described by shipped_params (no import of its kernels:
    numba, scipy)."""
    cs = ConfigStore.instance()
    cs.store(name="base_config", node=Config)
    shipped = shipped_params()
    for name in gbmodel.learners.available():
        defaults = None if name in gbmodel.learners._REGISTERED or (
            f"{gbmodel.learners.__name__}.{name}" in sys.modules) else shipped.get(name)
        params = None if defaults is not None else gbmodel.learners.get(name).Params
        cs.store(group="learner", name=f"{name}_schema",
                 node=schema_of(params, f"{name}_conf", LEARNER_EXTRA, defaults))


PARAMS_FORMAT = 1  # the layout of shipped_params' record: a new one is a new file name
_PLAIN_TYPES = {t.__name__: t for t in (int, float, str, bool)}


def _type_name(kind) -> str | None:
    """`int`, `float`, `str`, `bool` or one of them `| None` by name; None for any other type."""
    args = typing.get_args(kind)
    if kind in _PLAIN_TYPES.values():
        return kind.__name__
    if len(args) == 2 and type(None) in args and typing.get_origin(kind) in (
            typing.Union, types.UnionType):
        inner = _type_name(next(a for a in args if a is not type(None)))
        return None if inner is None or inner.endswith("| None") else f"{inner} | None"
    return None


def _type_of(name: str):
    plain, _, optional = name.partition(" | ")
    return _PLAIN_TYPES[plain] | None if optional else _PLAIN_TYPES[plain]


def shipped_params() -> dict[str, list]:
    """learner -> defaults_of(its Params), for every learner module under gbmodel/learners/,
    without importing them where it can: kept in gbmodel/__pycache__/ under the SHA-256 of every
    gbmodel source file's path and bytes (parsed never, trusted from no modification time; a
    changed byte anywhere in gbmodel is a new record). Made by importing the learners once per
    content; {} where a field's type or default is not a plain one (then each is imported)."""
    from .fingerprint import keep, kept

    root = Path(gbmodel.__file__).resolve().parent
    h = hashlib.sha256()
    for p in sorted(root.rglob("*.py")):
        h.update(p.relative_to(root).as_posix().encode() + b"\0" + p.read_bytes() + b"\0")
    path = root / "__pycache__" / f"params.{PARAMS_FORMAT}" / f"{h.hexdigest()}.json"
    try:
        found = json.loads(kept(path) or b"null")
    except ValueError:
        found = None
    if not isinstance(found, dict):
        found = {}
        for m in pkgutil.iter_modules([str(root / "learners")]):
            fields = defaults_of(gbmodel.learners.get(m.name).Params)
            if any(_type_name(kind) is None or type(v) not in (*_PLAIN_TYPES.values(), type(None))
                   for _, kind, v in fields):
                return {}
            found[m.name] = [(k, _type_name(kind), v) for k, kind, v in fields]
        keep(path, json.dumps(found).encode())
    try:
        return {name: [(k, _type_of(kind), v) for k, kind, v in fields]
                for name, fields in found.items()}
    except (KeyError, TypeError, ValueError):
        return {}


def sweep_tag() -> str:
    """A name part no other sweep gets (this host, process and nanosecond, hashed): two sweeps
    started in the same second get their own folder, so their plan records make two groups
    (pipeline.cli.hydra_run). Resolved once per sweep: Hydra caches it like `now` and copies the
    cache to every job's config, in any launcher."""
    who = f"{socket.gethostname()}/{os.getpid()}/{time.time_ns()}"
    return hashlib.sha256(who.encode()).hexdigest()[:8]


if not OmegaConf.has_resolver("experiments"):  # report.paper_experiments: ${experiments:}
    OmegaConf.register_new_resolver("experiments", lambda *groups: listed(config_folders(),
                                                                          *groups))
if not OmegaConf.has_resolver("default_root"):
    OmegaConf.register_new_resolver("default_root", default_root)
if not OmegaConf.has_resolver("sweep_tag"):
    OmegaConf.register_new_resolver("sweep_tag", sweep_tag, use_cache=True)
register_schemas()
engines.register_configs()  # the config group `engine`: one node per engine
searchpath.register(CONFIG_PATH)


def compose(overrides: list[str] | tuple = (), hydra: bool = False) -> DictConfig:
    """The config `python -m pipeline.<stage> OVERRIDES` would get (Hydra's compose API); with
    `hydra`, Hydra's own section too (callbacks, launcher, logging: check_hydra).

    Used by the tests and by callers that want a config without the command line."""
    from hydra import compose as hydra_compose

    with initialized():
        return hydra_compose(config_name="config", overrides=list(overrides),
                             return_hydra_config=hydra)


def without_hydra(full: DictConfig) -> DictConfig:
    """`full` (composed with hydra=True) without Hydra's section, in place: what compose() returns
    for the same overrides (Hydra's compose API drops the section just so), with no second
    compose."""
    with open_dict(full):
        del full["hydra"]
    return full


def initialized():
    """Hydra's compose API on the stages' config (CONFIG_PATH), a fresh one each time."""
    from hydra import initialize_config_dir, initialize_config_module
    from hydra.core.global_hydra import GlobalHydra

    GlobalHydra.instance().clear()
    if IN_CHECKOUT:
        return initialize_config_dir(config_dir=str(CONF_DIR), version_base="1.3")
    return initialize_config_module(gbmodel.bodies.CONF_PACKAGE, version_base="1.3")


def check_experiments(cfg, overrides: list[str] | tuple = ()) -> None:
    """Every name of `experiments=[...]` is an experiment (conf/experiment/, or a folder on
    hydra.searchpath given in `overrides`)."""
    names = list(cfg.get("experiments") or [])
    if not names:
        return
    from hydra.core.global_hydra import GlobalHydra

    with initialized():
        search = [o for o in overrides if o.startswith("hydra.searchpath=")]
        if search:  # the options a searchpath adds: compose once to load it
            from hydra import compose as hydra_compose
            hydra_compose(config_name="config", overrides=search)
        options = GlobalHydra.instance().config_loader().get_group_options("experiment")
    for name in names:
        if name not in options:
            raise ConfigError(f"experiments={names}: {name!r} is not an experiment; choose "
                              f"from {', '.join(options)}")


# ---- limits, checked by plan() before it plans a variant's trials ---------------------------------
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


def declared(key: str, cfg):
    """The declared range of a config key (a gbmodel.spec constraint), or None: RANGES, the
    limits of growth (gbmodel.growth.LIMITS), of the config's learner (its LIMITS) and the
    counts of check_limits."""
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


def check_ranges(cfg) -> None:
    """Refuse (one line naming the key and its range) a value outside RANGES."""
    for key, constraint in RANGES.items():
        value = OmegaConf.select(cfg, key, default=None)
        if value is not None and not constraint.ok(value):
            raise ConfigError(f"{key}={value!r}: must be {constraint.describe()}")
    for s in cfg.conditions.references:
        if isinstance(s, (int, float)) and not isinstance(s, bool) and not s <= MAX_SIZE:
            raise ConfigError(f"conditions.references={s!r}: a size factor of at most "
                              f"{MAX_SIZE:g}")


def _too_big(key, value, limit, unit, shown=None):
    if isinstance(value, int) and not isinstance(value, bool) and value > limit:
        raise ConfigError(f"{key}={value!r}: at most {shown or f'{limit:,}'} {unit}")


def check_limits(cfg) -> None:
    """Refuse (ConfigError naming the key and its unit) what would exhaust memory or overflow
    before a trial is planned: the trial count, the epochs, growth periods beyond int64, and the
    whole run's size."""
    _too_big("trials.count", cfg.trials.count, MAX_TRIALS, "trials per condition")
    _too_big("learner.epochs", cfg.learner.epochs, MAX_EPOCHS, "epochs per trial",
             f"{MAX_EPOCHS:.0e}")  # before planning multiplies the trials
    check_ranges(cfg)
    growth = cfg.growth
    _too_big("growth.period", growth.get("period"), MAX_INT64, "epochs (int64)")
    for p in cfg.conditions.periods:
        _too_big("conditions.periods", p, MAX_INT64, "epochs (int64)")
    count = cfg.trials.count
    if isinstance(count, int):
        conditions = max(len(cfg.conditions.periods) + len(cfg.conditions.references), 1)
        total = count * conditions * max(len(cfg.conditions.variants), 1)
        if total > MAX_PLANNED:
            raise ConfigError(f"trials.count={count}: {total:,} trials in all ({conditions} "
                              f"conditions x {max(len(cfg.conditions.variants), 1)} variants); "
                              f"at most {MAX_PLANNED:,} per run")


def config_notes(cfg) -> list[str]:
    """Notes about legitimate but unusual values (a shrinking body)."""
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


def check_choices(cfg, overrides) -> None:
    """Refuse (one line) what a command line would otherwise accept in silence: a body file
    whose `name:` differs from its file name (`body=my_arm` loading `name: other`), a growth
    period with growth=none (it would become 0), and a growth period given on the command line
    that is longer than the run (the body would never reach its end size)."""
    given = {o.lstrip("+~").split("=", 1)[0]: o.split("=", 1)[1] for o in overrides if "=" in o}
    body = given.get("body")
    if body is not None and "body.name" not in given and cfg.body.name != body:
        raise ConfigError(f"body={body}: its file {body}.yaml says name: {cfg.body.name}; a body "
                          f"file is named after its body (rename one of them)")
    g = cfg.growth
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


def check_keys(cfg) -> None:
    """Refuse a top-level key the schema does not know (`+foo=1` is composed without a word)."""
    known = {f.name for f in dataclasses.fields(Config)}
    unknown = sorted(set(cfg.keys()) - known - {"hydra"})
    if unknown:
        raise ConfigError(f"{unknown[0]}: not a config key; the top-level keys are "
                          f"{', '.join(sorted(known))}")


def check_root(cfg) -> None:
    """paths.root must be an absolute folder, and every output folder must lie under it or be
    the committed report (`published`, `bench`): an empty root would write at the file system's
    root, a relative one wherever the command happens to run."""
    root = cfg.paths.root
    if not isinstance(root, str) or not root.strip():
        raise ConfigError(f"paths.root={root!r}: must be a folder (an absolute path)")
    if not Path(root).is_absolute():
        raise ConfigError(f"paths.root={root!r}: must be an absolute path (it would be "
                          f"{Path(root).resolve()} here); e.g. paths.root=$PWD/{root}")
    base = Path(root).resolve()
    for key in ("out", "cache", "aggregate", "report", "published", "bench"):
        path = Path(cfg.paths[key])
        if not path.is_absolute() or ".." in path.parts:
            raise ConfigError(f"paths.{key}={str(path)!r}: must be an absolute path without '..'")
        resolved = path.resolve()
        if resolved != base and base not in resolved.parents:
            raise ConfigError(f"paths.{key}={str(path)!r}: outside paths.root={root}")


def check_names(cfg) -> None:
    """Every name of the config that becomes part of a path (pipeline.io.safe_name): the figure,
    the posture figures and their panels' figure names, the joint-space figure. A name like
    `../../esc` would write outside paths.root."""
    from .io import UnsafeName, safe_name

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
    """report.stamp_findings rewrites the committed pipeline/studies/findings_numbers.csv: only
    the publishing run (make reproduce: report.publish=true) may, never a smoke or custom run."""
    if cfg.report.stamp_findings and not cfg.report.publish:
        raise ConfigError("report.stamp_findings=true: only with report.publish=true (make "
                          "stamp, after make studies); this run's numbers are not "
                          "the committed report's")


# ---- what Hydra would run or write on the config's behalf ---------------------------------------
OWN_TARGETS = ("pipeline.",)  # a `_target_` the project's config may name
HYDRA_TARGETS = ("hydra._internal.", "hydra_plugins.")  # Hydra's own launchers and sweepers


def _targets(node, where: str):
    """(key, value) of every `_target_` in a plain config tree."""
    if isinstance(node, dict):
        for k, v in node.items():
            key = f"{where}.{k}" if where else str(k)
            if k == "_target_":
                yield key, v
            else:
                yield from _targets(v, key)
    elif isinstance(node, list):
        for i, v in enumerate(node):
            yield from _targets(v, f"{where}[{i}]")


# What a config may set under `hydra` (the command line and every config file on the search
# path alike): the only keys whose value may differ from the project's own (conf/config.yaml with
# Hydra's defaults), each with the check its value must pass. Everything else Hydra reads (its
# callbacks, env_set and env_copy, hydra.env, a launcher's or sweeper's own code) is refused:
# a logging factory, a callback or an environment variable (PYTHONPATH, LD_PRELOAD) runs code, a
# folder outside paths.root is written outside it.
HYDRA_ALLOWED = {
    "searchpath": "where config groups live (a body or an experiment of one's own)",
    "mode": "RUN or MULTIRUN", "verbose": "Hydra's debug logging",
    "job.chdir": "change into the run's folder (inside paths.root)",
    "job.name": "a plain name (it names the sweep's folder)",
    "job.config.override_dirname": "how override_dirname is spelt",
    "launcher": "Hydra's own launchers (hydra/launcher=basic|joblib), not their temp_folder",
    "sweeper": "Hydra's own sweepers",
    "job_logging": "to the terminal: StreamHandler to sys.stdout/stderr or NullHandler, "
                   "formatters by format, no factory ('()', class, ext://) of any kind",
    "hydra_logging": "the same as job_logging",
    "run.dir": "a folder inside paths.root (or the project's '.', where nothing is written)",
    "sweep.dir": "a folder inside paths.root", "sweep.subdir": "a relative name, no '..'",
    "output_subdir": "null, or a relative name inside a run folder under paths.root",
    "help": "the text of --help", "hydra_help": "the text of --hydra-help",
}
# filled by Hydra from the command line when it runs: what it says there is not a setting
HYDRA_RUNTIME = ("runtime", "overrides", "job.override_dirname", "job.id", "job.num",
                 "job.config_name")
LAUNCHER_KEYS = {"_target_", "n_jobs", "backend", "prefer", "require", "verbose", "timeout",
                 "pre_dispatch", "batch_size", "max_nbytes", "mmap_mode"}
LOG_HANDLERS = ("logging.StreamHandler", "logging.NullHandler")
LOG_STREAMS = ("ext://sys.stdout", "ext://sys.stderr")
LOG_FORMATTER_KEYS = {"format", "datefmt", "style", "validate"}
LOG_HANDLER_KEYS = {"class", "formatter", "stream", "level"}
LOG_LOGGER_KEYS = {"level", "handlers", "propagate"}


def _flat(node, where: str = "") -> dict:
    """Dotted key -> leaf value of a plain config tree (lists are leaves, an empty dict none)."""
    if isinstance(node, dict):
        out = {}
        for k, v in node.items():
            out.update(_flat(v, f"{where}.{k}" if where else str(k)))
        return out
    return {where: node}


def _under(key: str, prefixes) -> str | None:
    return next((p for p in prefixes if key == p or key.startswith(p + ".")), None)


HYDRA_DEFAULTS_FORMAT = 1  # the layout of _hydra_defaults' record: a new one is a new name


@lru_cache(maxsize=1)
def _hydra_defaults() -> dict:
    """The project's own `hydra` section, flat (conf/config.yaml over Hydra's defaults). A
    compose of its own (about 0.3 s CPU in every stage), so it is kept in pipeline/__pycache__/
    (beside the code, not in a folder of the run's) under the hash of everything it is composed
    from: the config files, pipeline's and gbmodel's code, Hydra's and OmegaConf's versions
    (planned.planning_sources), the config folders outside the checkout (config_sources) and
    where the config is read from; a changed byte is a new record, and a record whose checksum
    fails is composed again (fingerprint.kept)."""
    from .fingerprint import keep, kept
    from .planned import config_sources, planning_sources

    key = hashlib.sha256(f"{planning_sources()}\0{config_sources()}\0{CONFIG_PATH}"
                         .encode()).hexdigest()
    path = (Path(__file__).resolve().parent / "__pycache__"
            / f"hydra_defaults.{HYDRA_DEFAULTS_FORMAT}" / f"{key}.json")
    try:
        found = json.loads(kept(path) or b"null")
    except ValueError:
        found = None
    if isinstance(found, dict):
        return found
    cfg = compose(["paths.root=/"], hydra=True)
    flat = _flat(OmegaConf.to_container(cfg.hydra, resolve=False))
    text = json.dumps(flat, sort_keys=True)
    if json.loads(text) == flat:  # kept only where JSON gives the same values back
        keep(path, text.encode())
    return flat


def check_hydra(cfg) -> None:
    """Refuse what would make Hydra call or write something the project did not choose. `cfg` is
    composed with hydra=True: the command line and every config file (a body YAML on
    hydra.searchpath) count. Outside `hydra`: a `_target_` that is not the project's own. Under
    it: a key that differs from the project's own and is not in HYDRA_ALLOWED (callbacks, env_set,
    env_copy, hydra.env ...), or an allowed key whose value fails its check (_check_logging,
    _check_hydra_dirs, a launcher or sweeper that is not Hydra's)."""
    tree = OmegaConf.to_container(cfg, resolve=False)
    hydra = tree.pop("hydra", None) or {}
    for key, target in _targets(tree, ""):
        if not (isinstance(target, str) and target.startswith(OWN_TARGETS)):
            raise ConfigError(f"{key}={target!r}: the config names no code to run (only "
                              "pipeline's own)")
    for name in hydra.get("callbacks") or {}:
        raise ConfigError(f"hydra.callbacks.{name}: Hydra callbacks run code on every job; the "
                          "stages take none")
    for name in (hydra.get("job") or {}).get("env_set") or {}:
        raise ConfigError(f"hydra.job.env_set.{name}: sets an environment variable of every job "
                          "(PYTHONPATH, LD_PRELOAD: code the workers run); the stages take none")
    base, now = _hydra_defaults(), _flat(hydra)
    for key in sorted(set(base) | set(now)):
        if _under(key, HYDRA_RUNTIME) or base.get(key, _GONE) == now.get(key, _GONE):
            continue
        if _under(key, HYDRA_ALLOWED) is None:
            shown = f"={now[key]!r}" if key in now else " (removed)"
            raise ConfigError(f"hydra.{key}{shown}: not a setting the stages take from Hydra "
                              f"(allowed under hydra: {', '.join(HYDRA_ALLOWED)}; docs/faults.md)")
    for section in ("launcher", "sweeper"):
        target = (hydra.get(section) or {}).get("_target_")
        if target is not None and not (isinstance(target, str)
                                       and target.startswith(HYDRA_TARGETS)):
            raise ConfigError(f"hydra.{section}._target_={target!r}: only Hydra's own "
                              f"{section}s (hydra/{section}=...)")
    launcher = hydra.get("launcher") or {}
    n_jobs = launcher.get("n_jobs")
    if n_jobs is not None and (isinstance(n_jobs, bool) or not isinstance(n_jobs, int)
                               or n_jobs == 0):
        raise ConfigError(f"hydra.launcher.n_jobs={n_jobs!r}: a non-zero integer (-1: one "
                          "job per core)")
    for key in sorted(k for k, v in launcher.items() if k not in LAUNCHER_KEYS and v is not None):
        raise ConfigError(f"hydra.launcher.{key}={launcher[key]!r}: not a launcher setting the "
                          f"stages take ({', '.join(sorted(LAUNCHER_KEYS))}; a temp_folder "
                          "would be written outside paths.root)")
    name = (hydra.get("job") or {}).get("name")
    if name != base.get("job.name"):
        check_names_plain("hydra.job.name", name)
    for section in ("job_logging", "hydra_logging"):
        _check_logging(section, hydra.get(section) or {})
    _check_hydra_dirs(cfg, hydra)


_GONE = object()


def check_names_plain(key: str, value) -> None:
    from .io import UnsafeName, safe_name

    try:
        safe_name(key, value)
    except UnsafeName as err:
        raise ConfigError(str(err)) from None


def _check_logging(section: str, conf: dict) -> None:
    """A logging config (logging.config.dictConfig) that builds nothing but terminal handlers:
    no factory ('()') anywhere, no filters, a class only on a handler and only LOG_HANDLERS, a
    stream only sys.stdout or sys.stderr (ext:// imports any object), formatters by format."""
    where = f"hydra.{section}"
    for key, value in _flat(conf).items():
        if "()" in key.split(".") or (isinstance(value, str) and "ext://" in value
                                      and value not in LOG_STREAMS):
            raise ConfigError(f"{where}.{key}={value!r}: builds or imports its own object; the "
                              f"stages log to the terminal (hydra/{section}=stdout)")
    for name, f in (conf.get("formatters") or {}).items():
        for key in sorted(set(f or {}) - LOG_FORMATTER_KEYS):
            raise ConfigError(f"{where}.formatters.{name}.{key}: a formatter is its format "
                              f"({', '.join(sorted(LOG_FORMATTER_KEYS))}); nothing is built")
    for name in conf.get("filters") or {}:
        raise ConfigError(f"{where}.filters.{name}: a logging filter is built by a factory; the "
                          "stages take none")
    for name, h in (conf.get("handlers") or {}).items():
        h = h if isinstance(h, dict) else {}
        extra = sorted(set(h) - LOG_HANDLER_KEYS)
        if h.get("class") not in LOG_HANDLERS or extra or h.get("stream", LOG_STREAMS[0]) \
                not in LOG_STREAMS:
            raise ConfigError(f"{where}.handlers.{name}: writes a log file or builds its own "
                              "handler; the stages log to the terminal "
                              f"(hydra/{section}=stdout: {' or '.join(LOG_HANDLERS)} to "
                              "sys.stdout or sys.stderr)")
    loggers = dict(conf.get("loggers") or {}, root=conf.get("root") or {})
    for name, logger in loggers.items():
        for key in sorted(set(logger or {}) - LOG_LOGGER_KEYS):
            raise ConfigError(f"{where}.loggers.{name}.{key}: not a logger setting the stages "
                              f"take ({', '.join(sorted(LOG_LOGGER_KEYS))})")


def _check_hydra_dirs(cfg, hydra: dict) -> None:
    """Hydra's folders lie inside paths.root: run.dir (made at every run; `.` the project's,
    where nothing is written while output_subdir is null), sweep.dir and its subdir, and the
    output_subdir its config files go to (relative, inside the run's folder)."""
    root = OmegaConf.select(cfg, "paths.root", default=None)
    if not isinstance(root, str) or not Path(root).is_absolute():
        return  # check_root names it
    base = Path(root).resolve()
    base_dirs = _hydra_defaults()

    def inside(key: str) -> Path | None:
        raw = OmegaConf.select(cfg, f"hydra.{key}", throw_on_resolution_failure=False)
        if raw is None:
            raise ConfigError(f"hydra.{key}: cannot be resolved before the run; write it from "
                              "${paths.out}")
        path = Path(str(raw))
        led = (path if path.is_absolute() else Path.cwd() / path).resolve()
        if ".." in path.parts or (led != base and base not in led.parents):
            raise ConfigError(f"hydra.{key}={str(raw)!r}: outside paths.root={root}; Hydra "
                              "would write there")
        return led

    sub = (hydra.get("sweep") or {}).get("subdir")
    if sub != base_dirs.get("sweep.subdir") and (
            not isinstance(sub, str) or Path(sub).is_absolute() or ".." in Path(sub).parts):
        raise ConfigError(f"hydra.sweep.subdir={sub!r}: a relative name without '..' (a job's "
                          "folder inside the sweep's)")
    out = hydra.get("output_subdir")
    if out is not None and (not isinstance(out, str) or Path(out).is_absolute()
                            or ".." in Path(out).parts):
        raise ConfigError(f"hydra.output_subdir={out!r}: null, or a relative name without "
                          "'..' (Hydra writes its config files there, inside the run's folder)")
    run_dir = (hydra.get("run") or {}).get("dir")
    if run_dir != base_dirs.get("run.dir") or out is not None:
        inside("run.dir")
    if (hydra.get("sweep") or {}).get("dir") != base_dirs.get("sweep.dir"):
        inside("sweep.dir")
