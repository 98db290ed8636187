"""What a config may set under `hydra`: an allow-list of keys (HYDRA_KEYS), each checked on its
resolved value; anything else is one line, exit 2 (a logging factory, a callback or an
environment variable runs code; a folder outside paths.root is written outside it).
"""
from __future__ import annotations

import re
from pathlib import Path

from omegaconf import OmegaConf

from ..errors import ConfigError

OWN_TARGETS = ("pipeline.",)  # a `_target_` the project's config may name
HYDRA_TARGETS = ("hydra._internal.", "hydra_plugins.")  # Hydra's own launchers and sweepers
LAUNCHER_KEYS = {"_target_", "n_jobs", "backend", "prefer", "require", "verbose", "timeout",
                 "pre_dispatch", "batch_size", "max_nbytes", "mmap_mode"}
LOG_HANDLERS = ("logging.StreamHandler", "logging.NullHandler")
LOG_STREAMS = ("ext://sys.stdout", "ext://sys.stderr")
LOG_FORMATTER_KEYS = {"format", "datefmt", "style", "validate"}
LOG_HANDLER_KEYS = {"class", "formatter", "stream", "level"}
LOG_LOGGER_KEYS = {"level", "handlers", "propagate"}
# the keys a config may set under hydra (a refused key's message lists them), each checked below
# where it could run code or write: launcher and sweeper (Hydra's own), the loggings (to the
# terminal), job.env_copy (empty), the folders (inside paths.root); HYDRA_FILLED: Hydra's own
HYDRA_KEYS = ("searchpath", "mode", "verbose", "job.chdir", "job.name",
              "job.config.override_dirname", "launcher", "sweeper", "job_logging", "hydra_logging",
              "run.dir", "sweep.dir", "sweep.subdir", "output_subdir", "help", "hydra_help",
              "job.env_copy")
HYDRA_FILLED = ("runtime", "overrides", "job.override_dirname", "job.id", "job.num",
                "job.config_name")


def _flat(node, where: str = "", lists: bool = False) -> dict:
    """{dotted key: leaf} of a plain tree; lists are leaves, or (lists) entered as key[i]."""
    if isinstance(node, dict):
        parts = [(f"{where}.{k}" if where else str(k), v) for k, v in node.items()]
    elif lists and isinstance(node, list):
        parts = [(f"{where}[{i}]", v) for i, v in enumerate(node)]
    else:
        return {where: node}
    return {k: v for key, child in parts for k, v in _flat(child, key, lists).items()}


def check_hydra(cfg) -> None:
    """Refuse what would make Hydra call or write something the project did not choose (`cfg`:
    composed with hydra=True): a foreign `_target_`, a key HYDRA_KEYS does not allow, a value
    failing its check."""
    tree = OmegaConf.to_container(cfg, resolve=False)
    hydra = tree.pop("hydra", None) or {}
    for key, target in _flat(tree, lists=True).items():
        if "_target_" in re.split(r"[.\[]", key) and not (
                isinstance(target, str) and target.startswith(OWN_TARGETS)):
            raise ConfigError(f"{key}={target!r}: the config names no code to run (only "
                              "pipeline's own)")
    for name in hydra.get("callbacks") or {}:
        raise ConfigError(f"hydra.callbacks.{name}: Hydra callbacks run code on every job; the "
                          "stages take none")
    job = hydra.get("job") or {}
    for name in [*(job.get("env_set") or {}), *(job.get("env_copy") or [])]:
        raise ConfigError(f"hydra.job.env_set.{name}: sets an environment variable of every job "
                          "(PYTHONPATH, LD_PRELOAD: code the workers run); the stages take none")
    for key, value in sorted(_flat(hydra).items()):
        if not any(key == k or key.startswith(k + ".") for k in HYDRA_KEYS + HYDRA_FILLED):
            raise ConfigError(f"hydra.{key}={value!r}: not a setting the stages take from Hydra "
                              f"(allowed under hydra: {', '.join(HYDRA_KEYS)}; docs/faults.md)")
    for section in ("launcher", "sweeper"):
        target = (hydra.get(section) or {}).get("_target_")
        if target is not None and not (isinstance(target, str)
                                       and target.startswith(HYDRA_TARGETS)):
            raise ConfigError(f"hydra.{section}._target_={target!r}: only Hydra's own "
                              f"{section}s (hydra/{section}=...)")
    _check_launcher(hydra.get("launcher") or {})
    for section in ("job_logging", "hydra_logging"):
        _check_logging(section, hydra.get(section) or {})
    _check_dirs(cfg)


def _check_launcher(launcher: dict) -> None:
    n_jobs = launcher.get("n_jobs")
    if n_jobs is not None and (isinstance(n_jobs, bool) or not isinstance(n_jobs, int)
                               or n_jobs == 0):
        raise ConfigError(f"hydra.launcher.n_jobs={n_jobs!r}: a non-zero integer (-1: one "
                          "job per core)")
    for key in sorted(k for k, v in launcher.items() if k not in LAUNCHER_KEYS and v is not None):
        raise ConfigError(f"hydra.launcher.{key}={launcher[key]!r}: not a launcher setting the "
                          f"stages take ({', '.join(sorted(LAUNCHER_KEYS))}; a temp_folder "
                          "would be written outside paths.root)")


def _check_logging(section: str, conf: dict) -> None:
    """A logging config that builds nothing but terminal handlers (LOG_HANDLERS, LOG_STREAMS)."""
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


def _resolved(cfg, key: str):
    """hydra.<key> as the run sees it (job 0); ConfigError where it cannot be resolved."""
    node = OmegaConf.masked_copy(cfg, ["hydra", "paths"])
    OmegaConf.set_readonly(node, False)
    for k, v in (("job.num", 0), ("job.id", "0")):
        if OmegaConf.select(node, f"hydra.{k}", throw_on_missing=False) is None:
            OmegaConf.update(node, f"hydra.{k}", v, force_add=True)
    try:
        return OmegaConf.select(node, f"hydra.{key}", throw_on_missing=True)
    except Exception as err:
        why = str(err).splitlines()[0] if str(err) else type(err).__name__
        raise ConfigError(f"hydra.{key}: cannot be resolved before the run ({why}); write it "
                          "from ${paths.out}") from None


def _relative(key: str, value) -> None:
    if not isinstance(value, str) or Path(value).is_absolute() or ".." in Path(value).parts:
        raise ConfigError(f"hydra.{key}={value!r}: null, or a relative name without '..' (a "
                          "folder inside the run's or the sweep's)")


def _check_dirs(cfg) -> None:
    """Hydra's folders, resolved, lie inside paths.root (run.dir `.` writes nothing while
    output_subdir is null); job.name is a plain name."""
    from ..io import UnsafeName, safe_name

    root = OmegaConf.select(cfg, "paths.root", default=None)
    if not isinstance(root, str) or not Path(root).is_absolute():
        return  # check_paths names it
    base = Path(root).resolve()
    try:
        safe_name("hydra.job.name", _resolved(cfg, "job.name"))
    except UnsafeName as err:
        raise ConfigError(str(err)) from None
    out = _resolved(cfg, "output_subdir")
    if out is not None:
        _relative("output_subdir", out)
    _relative("sweep.subdir", str(_resolved(cfg, "sweep.subdir")))
    for key in ("run.dir", "sweep.dir"):
        raw = _resolved(cfg, key)
        path = Path(str(raw))
        led = (path if path.is_absolute() else Path.cwd() / path).resolve()
        if key == "run.dir" and raw == "." and out is None:
            continue  # the project's own: nothing is written there
        if ".." in path.parts or (led != base and base not in led.parents):
            raise ConfigError(f"hydra.{key}={str(raw)!r}: outside paths.root={root}; Hydra "
                              "would write there")
