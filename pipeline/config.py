"""Config schema (dataclasses registered in Hydra's ConfigStore) and config helpers.

The YAML files under conf/ extend these dataclasses, so a misspelt key or a value of the wrong type
fails when the config is composed, before any stage starts. Checks of *values* (a negative period,
zero epochs) live in `pipeline.plan`, which turns a config into trials.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Optional

from hydra.core.config_store import ConfigStore
from omegaconf import DictConfig, OmegaConf

REPO_ROOT = Path(__file__).resolve().parents[1]
CONF_DIR = REPO_ROOT / "conf"


class ConfigError(ValueError):
    """A bad value in the config; its message is one line naming the key and the value."""


@dataclass
class BodyConf:
    name: str = "arm5"  # arm2 | arm5 | icub (gbmodel.BODIES)


@dataclass
class GrowthConf:
    pattern: str = "proportional"  # none | proportional | nonproportional
    period: int = 1000  # T_G [epochs]
    start_size: float = 0.5  # size factor in the first epoch (1.0 = the full body)
    end_size: float = 1.0  # size factor after growth


@dataclass
class LearnerConf:
    variations: int = 20  # V
    radius: float = 0.2  # R
    targets_per_epoch: int = 15  # K
    steps: int = 7  # L
    learning_rate: float = 1.0  # = gbmodel.trial.DEFAULT_LEARNING_RATE
    epochs: int = 100_000
    init_range: float = 0.1
    degree: int = 3
    evals_per_decade: int = 20


@dataclass
class TrialsConf:
    count: int = 20
    root_seed: int = 2010


@dataclass
class PathsConf:
    root: str = "${repo_root:}"
    out: str = "${.root}/outputs"
    cache: str = "${.out}/cache"
    aggregate: str = "${.out}/aggregate"
    report: str = "${.out}/report"


@dataclass
class ConditionsConf:
    """What an experiment sweeps. Empty lists: the single condition of the growth group."""

    periods: list[int] = field(default_factory=list)  # growth periods T_G, one condition each
    references: list[float] = field(default_factory=list)  # constant sizes run as references
    snapshots: list[int] = field(default_factory=list)  # epochs after which M is stored


@dataclass
class PaperConf:
    title: str = ""
    final_abs_error: Optional[float] = None  # the paper's stated final accuracy [m], if any


@dataclass
class AggregateConf:
    # A trial failed to bootstrap when its final relative error exceeds fail_factor times the
    # median final relative error of its condition's trials.
    fail_factor: float = 3.0


@dataclass
class ReportConf:
    dpi: int = 120
    log_error_axis: bool = True  # error axis of the learning curves on a log scale too
    # Target grid vs reached grid with postures (paper Fig. 3 and 6): panels of
    # [figure, condition], each drawn from the final M of trial 0.
    postures: dict[str, Any] = field(default_factory=lambda: {
        "fig3": [["fig4", "const0.5"], ["fig4", "TG1000"], ["fig5", "TG1000"]],
        "fig6": [["fig7", "const0.5"], ["fig7", "TG1000"]],
    })
    joint_space_figure: str = "fig2"  # drawn in the joint space of arm2 (paper Fig. 2)


@dataclass
class Config:
    body: BodyConf = field(default_factory=BodyConf)
    growth: GrowthConf = field(default_factory=GrowthConf)
    learner: LearnerConf = field(default_factory=LearnerConf)
    trials: TrialsConf = field(default_factory=TrialsConf)
    paths: PathsConf = field(default_factory=PathsConf)
    conditions: ConditionsConf = field(default_factory=ConditionsConf)
    paper: PaperConf = field(default_factory=PaperConf)
    aggregate: AggregateConf = field(default_factory=AggregateConf)
    report: ReportConf = field(default_factory=ReportConf)
    figure: str = "custom"
    fast: bool = True
    workers: int = 2


if not OmegaConf.has_resolver("repo_root"):
    OmegaConf.register_new_resolver("repo_root", lambda: str(REPO_ROOT))
ConfigStore.instance().store(name="base_config", node=Config)


def compose(overrides: list[str] | tuple = ()) -> DictConfig:
    """The config `python -m pipeline.<stage> OVERRIDES` would get (Hydra's compose API).

    Used by the tests and by callers that want a config without the command line.
    """
    from hydra import compose as hydra_compose
    from hydra import initialize_config_dir
    from hydra.core.global_hydra import GlobalHydra

    GlobalHydra.instance().clear()
    with initialize_config_dir(config_dir=str(CONF_DIR), version_base="1.3"):
        return hydra_compose(config_name="config", overrides=list(overrides))


def learner_settings(body: str) -> dict:
    """The TrialSpec fields `body=<body>` selects: the body and its learner group (the paper's
    V, R, K, L and our learning rate, conf/learner/*.yaml). bench and choices start from these."""
    return dict(body=body, **OmegaConf.to_container(compose([f"body={body}"]).learner))
