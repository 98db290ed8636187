"""Config schema (dataclasses registered in Hydra's ConfigStore) and config helpers.

The YAML files under conf/ extend these dataclasses, so a misspelt key or a value of the wrong type
fails when the config is composed, before any stage starts. The sections that describe a trial
(body, growth, learner, evaluation) are generated from gbmodel's own dataclasses, so every value
of the numerical core has one source: its default in gbmodel, or the YAML file that changes it.
Checks of *values* live in gbmodel (TrialSpec.validate) and pipeline.plan.
"""
from __future__ import annotations

import dataclasses
import importlib.util
import typing
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Optional

from hydra.core.config_store import ConfigStore
from omegaconf import MISSING, DictConfig, OmegaConf

import gbmodel
from gbmodel import evaluation

REPO_ROOT = Path(__file__).resolve().parents[1]
CONF_DIR = REPO_ROOT / "conf"


class ConfigError(ValueError):
    """A bad value in the config; its message is one line naming the key and the value."""


BACKENDS = ("local", "ray", "slurm", "submitit_local")
EXTRA = {"ray": ("ray", "ray"), "slurm": ("submitit", "slurm"),
         "submitit_local": ("submitit", "slurm")}  # backend -> (package, pyproject extra)


def check_backend(backend: str) -> None:
    """ConfigError (one line) for an unknown backend, or one whose package is not installed."""
    if backend not in BACKENDS:
        raise ConfigError(f"executor.backend={backend!r}: choose one of {', '.join(BACKENDS)}")
    if backend in EXTRA:
        package, extra = EXTRA[backend]
        if importlib.util.find_spec(package) is None:
            raise ConfigError(f"executor.backend={backend!r} needs the package {package}: "
                              f"pip install -e '.[{extra}]'")


def schema_of(cls, name: str, extra: tuple = ()) -> type:
    """A Hydra schema with the fields (types and defaults) of gbmodel dataclass `cls`, plus
    `extra` (name, type, default) fields."""
    hints = typing.get_type_hints(cls)
    fields = [(f.name, hints[f.name], field(default=f.default)) for f in dataclasses.fields(cls)
              if f.default is not dataclasses.MISSING]
    return dataclasses.make_dataclass(name, list(extra) + fields)


@dataclass
class GridConf:
    lo: list[float] = MISSING
    hi: list[float] = MISSING
    num: list[int] = MISSING


@dataclass
class BodyConf:
    name: str = MISSING  # arm2 | arm5 | icub (gbmodel.BODIES)
    grid: Optional[GridConf] = None  # the target grid; null: the body's own (gbmodel/bodies.py)
    home: Optional[list[float]] = None  # the home posture; null: the body's own
    saturate: Optional[bool] = None  # commands clipped at the joint limits; null: the body's own


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
    variants: list[VariantConf] = field(default_factory=list)  # each: all of the above again
    # a budget of reaching movements (forward-kinematics samples) per trial instead of epochs:
    # each learner gets budget / its samples per epoch epochs, growing over growth_share of them
    budget: Optional[int] = None
    growth_share: float = 0.5
    budget_scale: float = 1.0  # profiles shrink the budget (smoke)


@dataclass
class PaperConf:
    title: str = ""
    final_abs_error: Optional[float] = None  # the paper's stated final accuracy [m], if any
    # whether the report checks the paper's claims on this experiment: its figures and studies
    # declare it; a custom experiment does not, and is reported by its curves alone
    claims: bool = False


@dataclass
class AggregateConf:
    fail_factor: float = MISSING


@dataclass
class ReportConf:
    dpi: int = MISSING
    log_error_axis: bool = MISSING
    postures: dict[str, Any] = MISSING
    joint_space_figure: str = MISSING
    publish: bool = False  # write the committed report (paths.published): make reproduce only
    paper_experiments: list[str] = MISSING  # what the committed report must hold, at full scale
    stamp_findings: bool = False  # record these numbers as the ones findings.md discusses
    explain: bool = True  # the explanation rows, read from the explain_* aggregates (explain.py)
    scale: str = ""  # a reduced scale the title names ("smoke"; set by the profile), "" = as set


@dataclass
class SlurmConf:
    """SLURM jobs through submitit (executor=slurm; pipeline/backends.py)."""

    partition: Optional[str] = None  # --partition; null: the cluster's default
    timeout_min: int = 1440  # --time of each job, minutes (a job runs a whole shard)
    mem_gb: float = 2.0  # --mem per job
    shards: Optional[int] = None  # array jobs; null: `workers`
    setup: list[str] = field(default_factory=list)  # shell lines before each job
    poll_s: float = 10.0  # how often the driver asks SLURM about its jobs


@dataclass
class ExecutorConf:
    backend: str = MISSING  # local | ray | slurm | submitit_local (conf/executor/)
    address: Optional[str] = None  # a Ray cluster's address (`auto`, `ray://host:10001`)
    slurm: SlurmConf = field(default_factory=SlurmConf)


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
    aggregate: AggregateConf = field(default_factory=AggregateConf)
    report: ReportConf = field(default_factory=ReportConf)
    executor: ExecutorConf = field(default_factory=ExecutorConf)
    bench: BenchConf = field(default_factory=BenchConf)
    figure: str = MISSING
    workers: int = MISSING


def register_schemas() -> None:
    """The primary schema, and one schema per learner (`learner/<name>_schema`) that its YAML
    file extends: the learner's Params fields with their defaults, plus name and epochs."""
    cs = ConfigStore.instance()
    cs.store(name="base_config", node=Config)
    for name in gbmodel.learners.available():
        params = gbmodel.learners.get(name).Params
        cs.store(group="learner", name=f"{name}_schema",
                 node=schema_of(params, f"{name}_conf", LEARNER_EXTRA))


if not OmegaConf.has_resolver("repo_root"):
    OmegaConf.register_new_resolver("repo_root", lambda: str(REPO_ROOT))
register_schemas()


def compose(overrides: list[str] | tuple = ()) -> DictConfig:
    """The config `python -m pipeline.<stage> OVERRIDES` would get (Hydra's compose API).

    Used by the tests and by callers that want a config without the command line."""
    from hydra import compose as hydra_compose
    from hydra import initialize_config_dir
    from hydra.core.global_hydra import GlobalHydra

    GlobalHydra.instance().clear()
    with initialize_config_dir(config_dir=str(CONF_DIR), version_base="1.3"):
        return hydra_compose(config_name="config", overrides=list(overrides))
