"""The config's schema, registered in Hydra's ConfigStore: a misspelt key or a wrong type fails
when composed. A trial's sections are generated from gbmodel's dataclasses (one source per
value); a plain learner's is read from its source (learner_params: composing imports no learner).
"""
from __future__ import annotations

import ast
import dataclasses
import sys
import typing
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Optional

from hydra.core.config_store import ConfigStore
from omegaconf import MISSING

import gbmodel
from gbmodel import evaluation

from ..experiments import Declares


def defaults_of(cls) -> list[tuple[str, Any, Any]]:
    hints = typing.get_type_hints(cls)
    return [(f.name, hints[f.name], f.default) for f in dataclasses.fields(cls)
            if f.default is not dataclasses.MISSING]


def conf_of(cls, name: str) -> type:
    """A schema of every field of `cls` (MISSING without a default; a dataclass field: its own)."""
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


BodyConf = conf_of(gbmodel.bodies.Description, "BodyConf")
# growth: gbmodel.Growth's fields; pattern `none` is a body of constant size end_size
GrowthConf = conf_of(gbmodel.Growth, "GrowthConf")
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
    label: str = MISSING
    choice: str = ""  # what is varied (a row group of the choices table)
    chosen: bool = False  # the value this project uses
    set: list[str] = field(default_factory=list)  # e.g. ["learner.learning_rate=0.5"]


@dataclass
class ConditionsConf:
    periods: list[int] = field(default_factory=list)  # growth periods T_G, one condition each
    references: list[float] = field(default_factory=list)  # constant sizes run as references
    snapshots: list[int] = field(default_factory=list)  # epochs after which M is stored
    frames: int = 0  # M also stored after this many log-spaced epochs (the report's animation)
    variants: list[VariantConf] = field(default_factory=list)  # each: all of the above again
    budget: Optional[int] = None  # samples per trial instead of epochs (growth: growth_share)
    growth_share: float = 0.5
    budget_scale: float = 1.0  # profiles shrink the budget (smoke)
    # each trial continues the saved state after this many epochs (a multiple of 1000) of its
    # trial without the variants (pipeline.checkpoint); ignored in a shorter run; null: none
    continues: Optional[int] = None


@dataclass
class PaperConf:
    title: str = ""
    final_abs_error: Optional[float] = None  # the paper's stated final accuracy [m], if any
    claims: bool = False  # the report checks the paper's claims on it (a custom one: curves)
    study: str = "figures"  # its report section (pipeline/studies/sections.py)
    judged_on: Optional[str] = None  # the figure the scorecard counts instead, when both ran


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
    # a learning-curve figure for a paper (pipeline.studies.paper.figure_options, docs/figures.md):
    title: str = ""  # its title line; "" keeps the figure's name and its trial count
    error_unit: str = "m"  # the errors' unit: m or mm (curves, bands, the paper's line, labels)
    log_epoch_axis: bool = True  # the epoch axis on a log scale; false: linear


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
    # simulate: these experiments in one process, each with the other overrides (make smoke)
    experiments: list[str] = field(default_factory=list)


def register_schemas() -> None:
    """The primary schema, and `learner/<name>_schema` per learner (its Params' fields)."""
    cs = ConfigStore.instance()
    cs.store(name="base_config", node=Config)
    for name in gbmodel.learners.available():
        loaded = name in gbmodel.learners._REGISTERED or (
            f"{gbmodel.learners.__name__}.{name}" in sys.modules)
        defaults = None if loaded else learner_params(name)
        if defaults is None:
            defaults = defaults_of(gbmodel.learners.get(name).Params)
        cs.store(group="learner", name=f"{name}_schema", node=dataclasses.make_dataclass(
            f"{name}_conf", [*LEARNER_EXTRA, *((k, kind, field(default=v))
                                               for k, kind, v in defaults)]))


_PLAIN_TYPES = {t.__name__: t for t in (int, float, str, bool)}


def _plain_type(node):
    """int, float, str, bool (or one `| None`) that an annotation names; else None."""
    if isinstance(node, ast.Name):
        return _PLAIN_TYPES.get(node.id)
    if isinstance(node, ast.BinOp) and isinstance(node.op, ast.BitOr):
        sides = [node.left, node.right]
        nones = [s for s in sides if isinstance(s, ast.Constant) and s.value is None]
        inner = [_plain_type(s) for s in sides if s not in nones]
        if len(nones) == 1 and inner[0] is not None:
            return inner[0] | None
    return None


def learner_params(name: str) -> list | None:
    """defaults_of(learner `name`'s Params) read from its source, None where not plain (a base
    class, a computed default, a class attribute): it is then imported."""
    folder = Path(gbmodel.learners.__file__).parent
    path = folder / f"{name}.py"
    path = path if path.is_file() else folder / name / "__init__.py"
    try:
        tree = ast.parse(path.read_text())
    except (OSError, SyntaxError, ValueError):
        return None
    cls = next((n for n in tree.body if isinstance(n, ast.ClassDef) and n.name == "Params"),
               None)
    if cls is None or cls.bases or cls.keywords:
        return None
    out = []
    for node in cls.body:
        if isinstance(node, (ast.Assign, ast.AugAssign)):
            return None  # a class attribute: not read here
        if not isinstance(node, ast.AnnAssign) or node.value is None:
            continue  # a method, a docstring, a field without a default (not in defaults_of)
        try:
            value = ast.literal_eval(node.value)
        except ValueError:
            return None
        kind = _plain_type(node.annotation)
        if kind is None or not isinstance(node.target, ast.Name) or \
                type(value) not in (*_PLAIN_TYPES.values(), type(None)):
            return None
        out.append((node.target.id, kind, value))
    return out
