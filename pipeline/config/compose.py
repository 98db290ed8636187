"""Where the config lives and how a command line becomes one (Hydra's compose API); importing
it registers the schema, the engines' group, the resolvers and the search path."""
from __future__ import annotations

import hashlib
import os
import socket
import time
from pathlib import Path

from omegaconf import DictConfig, OmegaConf, open_dict

import gbmodel

from .. import engines, searchpath
from ..errors import ConfigError
from ..experiments import config_folders, listed
from .schema import register_schemas

REPO_ROOT = Path(__file__).resolve().parents[2]  # the checkout (installed: site-packages)
CONF_DIR = gbmodel.bodies.CONF_DIR  # conf/ of the checkout, else the installed gbgrowth_conf
IN_CHECKOUT = CONF_DIR == REPO_ROOT / "conf"
# every stage's @hydra.main config_path: the checkout's conf/, else the installed package
CONFIG_PATH = str(CONF_DIR) if IN_CHECKOUT else f"pkg://{gbmodel.bodies.CONF_PACKAGE}"


def default_root() -> str:
    """paths.root unless given: the checkout, else (installed) the working directory."""
    return str(REPO_ROOT) if IN_CHECKOUT else os.getcwd()


def sweep_tag() -> str:
    """A name part no other sweep gets (host, process, nanosecond, hashed); resolved once per
    sweep (Hydra caches it like `now` for every job)."""
    who = f"{socket.gethostname()}/{os.getpid()}/{time.time_ns()}"
    return hashlib.sha256(who.encode()).hexdigest()[:8]


for _name, _fn in (("experiments", lambda *groups: listed(config_folders(), *groups)),
                   ("default_root", default_root), ("sweep_tag", sweep_tag)):
    if not OmegaConf.has_resolver(_name):  # ${experiments:}: report.paper_experiments
        OmegaConf.register_new_resolver(_name, _fn, use_cache=_name == "sweep_tag")
register_schemas()
engines.register_configs()  # the config group `engine`: one node per engine
searchpath.register(CONFIG_PATH)


def compose(overrides: list[str] | tuple = (), hydra: bool = False) -> DictConfig:
    """The config `python -m pipeline.<stage> OVERRIDES` gets; with `hydra`, Hydra's section."""
    from hydra import compose as hydra_compose

    with initialized():
        return hydra_compose(config_name="config", overrides=list(overrides),
                             return_hydra_config=hydra)


def without_hydra(full: DictConfig) -> DictConfig:
    """`full` (compose(hydra=True)) without Hydra's section, in place: compose()'s result."""
    with open_dict(full):
        del full["hydra"]
    return full


def initialized():
    from hydra import initialize_config_dir, initialize_config_module
    from hydra.core.global_hydra import GlobalHydra

    GlobalHydra.instance().clear()
    if IN_CHECKOUT:
        return initialize_config_dir(config_dir=str(CONF_DIR), version_base="1.3")
    return initialize_config_module(gbmodel.bodies.CONF_PACKAGE, version_base="1.3")


def group_options(group: str, overrides: list[str] | tuple = ()) -> list[str]:
    """The options of config group `group` (with the hydra.searchpath among `overrides`)."""
    from hydra import compose as hydra_compose
    from hydra.core.global_hydra import GlobalHydra

    with initialized():
        search = [o for o in overrides if o.startswith("hydra.searchpath=")]
        if search:  # the options a searchpath adds: compose once to load it
            hydra_compose(config_name="config", overrides=search)
        return GlobalHydra.instance().config_loader().get_group_options(group)


def check_experiments(cfg, overrides: list[str] | tuple = ()) -> None:
    """Every name of `experiments=[...]` is an experiment."""
    names = list(cfg.get("experiments") or [])
    if not names:
        return
    options = group_options("experiment", overrides)
    for name in names:
        if name not in options:
            raise ConfigError(f"experiments={names}: {name!r} is not an experiment; choose "
                              f"from {', '.join(options)}")


# Hydra's command-line flags that take a value as the next argument
FLAGS_WITH_VALUE = {"--cfg", "-c", "--config-path", "-cp", "--config-name", "-cn",
                    "--config-dir", "-cd", "--package", "-p", "--info", "-i",
                    "--experimental-rerun"}


def overrides_of(argv: list[str]) -> list[str]:
    out, skip = [], False
    for arg in argv:
        if skip:
            skip = False
        elif arg.startswith("-"):
            skip = arg in FLAGS_WITH_VALUE
        else:
            out.append(arg)
    return out
