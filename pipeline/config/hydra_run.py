"""Hydra's run of a stage given the config the check composed: one compose, not three (0.2 s
CPU each), and the run works on the very config that was checked."""
from __future__ import annotations

from contextlib import contextmanager

from .compose import CONFIG_PATH

COMPOSED: list = []  # [(what it was composed from, the config)] for Hydra's run (composed_once)
MODE: list = []  # [hydra.mode] of the command line the check composed with Hydra's section


def _load_key(loader, config_name, overrides, run_mode, from_shell, validate) -> tuple:
    """What a loader's load_configuration reads that may differ between calls: arguments, search
    path, job name, version base, working directory, environment."""
    import os

    from hydra import version
    from hydra.core.utils import JobRuntime

    return (config_name, tuple(overrides), run_mode, from_shell, validate,
            tuple((e.provider, e.path) for e in loader.config_search_path.get_path()),
            JobRuntime().get("name"), version.getbase(), os.getcwd(),
            tuple(sorted(os.environ.items())))


def compose_as_run(stage, overrides: list[str]):
    """The config (with Hydra's section) Hydra's run of `stage` composes, kept for the run
    (composed_once); None where the stage's module cannot be told."""
    import copy

    from hydra._internal.hydra import Hydra
    from hydra._internal.utils import (create_automatic_config_search_path,
                                       detect_calling_file_or_module_from_task_function,
                                       detect_task_name)
    from hydra.core.global_hydra import GlobalHydra
    from hydra.types import RunMode
    from omegaconf import OmegaConf

    task = getattr(stage, "__wrapped__", None)
    if task is None:
        return None
    calling_file, calling_module = detect_calling_file_or_module_from_task_function(task)
    if calling_file is None and calling_module is None:
        return None
    GlobalHydra.instance().clear()
    try:
        hydra = Hydra.create_main_hydra2(
            task_name=detect_task_name(calling_file, calling_module),
            config_search_path=create_automatic_config_search_path(
                calling_file, calling_module, CONFIG_PATH))
        cfg = hydra.compose_config(config_name="config", overrides=list(overrides),
                                   run_mode=RunMode.RUN, from_shell=True)
        run, given = copy.deepcopy(cfg), list(overrides)  # before the check changes cfg
        if cfg.hydra.mode is None:  # Hydra's run (_run_app) adds hydra.mode=RUN to the
            # overrides, which sets that key and is listed last among Hydra's own overrides
            given.append("hydra.mode=RUN")
            OmegaConf.update(run, "hydra.mode", "RUN", merge=True)
            run.hydra.overrides.hydra.append("hydra.mode=RUN")
        key = _load_key(hydra.config_loader, "config", given, RunMode.RUN, True, True)
    finally:
        GlobalHydra.instance().clear()
    COMPOSED[:] = [(key, run)]
    return cfg


@contextmanager
def composed_once(composed: list):
    """Hydra's loader returns the config compose_as_run kept when asked for the same thing
    (_load_key), once; any other load composes as Hydra does."""
    from hydra._internal.config_loader_impl import ConfigLoaderImpl

    if not composed:
        yield
        return
    real = ConfigLoaderImpl.load_configuration

    def load(self, config_name, overrides, run_mode, from_shell=True,
             validate_sweep_overrides=True):
        if composed and composed[0][0] == _load_key(self, config_name, overrides, run_mode,
                                                     from_shell, validate_sweep_overrides):
            return composed.pop()[1]
        return real(self, config_name=config_name, overrides=overrides, run_mode=run_mode,
                    from_shell=from_shell, validate_sweep_overrides=validate_sweep_overrides)

    ConfigLoaderImpl.load_configuration = load
    try:
        yield
    finally:
        ConfigLoaderImpl.load_configuration = real
        composed.clear()


@contextmanager
def known_mode(mode: list):
    """Hydra.get_mode (a whole compose) answered by the mode the check composed, where known."""
    from hydra._internal.hydra import Hydra

    if not mode:
        yield
        return
    real = Hydra.get_mode
    Hydra.get_mode = lambda self, config_name, overrides: mode[0]
    try:
        yield
    finally:
        Hydra.get_mode = real
