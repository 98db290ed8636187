"""Engines: where the simulate stage runs its trials, one module each (or an entry point of
`gbgrowth.engines`), registered by `@engine(name, Settings)`; the config group `engine` is
generated from them (docs/engines.md). An engine yields (trial, fn(trial)) as trials finish and
imports nothing of the pipeline above it: the driver (pipeline.simulate) alone writes the cache,
so trial files are the same bytes whichever engine ran them. A launcher's unit (Hydra's ray or
submitit launchers) would be a whole stage run; here the unit is a trial, longest first.
"""
from __future__ import annotations

import dataclasses
import importlib
import importlib.util
import pkgutil
import typing
from dataclasses import dataclass
from typing import Callable

from ..errors import ConfigError
from ..plugins import ENGINES, load_plugins

# every worker, whichever engine starts it, runs one BLAS/OpenMP/numba thread
THREAD_VARS = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS",
               "NUMBA_NUM_THREADS", "VECLIB_MAXIMUM_THREADS")


@dataclass
class NoSettings:
    """An engine without settings of its own (engine=local)."""


@dataclass(frozen=True)
class Engine:
    name: str
    settings: type  # a dataclass: the engine's settings, engine.<field> on the command line
    run: Callable  # run(todo, workers, fn, settings, logs, **takes) -> (trial, result)...
    package: str | None = None  # the module it needs (imported only when it runs)
    extra: str | None = None  # the pyproject extra that installs that module
    # it loads the kernels in its own workers; else run() has them loaded here first (warm_up)
    warms_up: bool = False
    takes: tuple = ()  # what else run() is given, by keyword: "pool", "cost" (engines.run)


_ENGINES: dict[str, Engine] = {}
_BROKEN: dict[str, str] = {}  # engine name -> why its entry point's module did not import
_DISCOVERED: list = []  # [True] once discover() ran in this process


def engine(name: str, settings: type = NoSettings, package: str | None = None,
           extra: str | None = None, warms_up: bool = False, takes: tuple = ()):
    """Register the decorated run function as engine `name` (fields: Engine)."""
    if not dataclasses.is_dataclass(settings):
        raise TypeError(f"engine {name!r}: settings must be a dataclass, not {settings!r}")

    def register(run: Callable) -> Callable:
        other = _ENGINES.get(name)
        if other is not None and other.run.__module__ != run.__module__:
            raise ValueError(f"engine {name!r} is registered by {other.run.__module__} and "
                             f"{run.__module__}")
        _ENGINES[name] = Engine(name, settings, run, package, extra, warms_up, tuple(takes))
        return run

    return register


def discover() -> tuple[str, ...]:
    """Import every engine module (this package's and the entry points'); the names, sorted."""
    for m in pkgutil.iter_modules(__path__):
        importlib.import_module(f"{__name__}.{m.name}")
    load_plugins(ENGINES, _BROKEN)  # a failure is named when its engine is chosen
    _DISCOVERED[:] = [True]
    return tuple(sorted(_ENGINES))


def available() -> tuple[str, ...]:
    return tuple(sorted(_ENGINES)) if _DISCOVERED else discover()


def get(name: str) -> Engine:
    if name not in _ENGINES and not _DISCOVERED:
        discover()
    if name in _BROKEN and name not in _ENGINES:
        raise ConfigError(f"engine={name}: its module did not import ({_BROKEN[name]})")
    if name not in _ENGINES:
        raise ConfigError(f"engine={name!r}: choose one of {', '.join(available())}")
    return _ENGINES[name]


def check(name: str, package: bool = True) -> Engine:
    """get(name), and (package) a ConfigError where its package is not installed."""
    e = get(name)
    if package and e.package and importlib.util.find_spec(e.package) is None:
        raise ConfigError(f"engine={name} needs the package {e.package}: pip install -e "
                          f"'.[{e.extra or e.package}]'")
    return e


def schema(e: Engine) -> type:
    """The config node of engine `e`: its name, then its settings' fields (types, defaults)."""
    hints = typing.get_type_hints(e.settings)

    def default(f):
        if f.default_factory is not dataclasses.MISSING:
            return dataclasses.field(default_factory=f.default_factory)
        return dataclasses.field(default=f.default)

    return dataclasses.make_dataclass(f"{e.name}_engine", [
        ("name", str, dataclasses.field(default=e.name)),
        *[(f.name, hints[f.name], default(f)) for f in dataclasses.fields(e.settings)]])


def register_configs() -> None:
    """The config group `engine`: one node per registered engine (Hydra's ConfigStore)."""
    from hydra.core.config_store import ConfigStore

    cs = ConfigStore.instance()
    for name in discover():
        cs.store(group="engine", name=name, node=schema(_ENGINES[name]))
    for name in sorted(set(_BROKEN) - set(_ENGINES)):  # composes; check() names the error
        cs.store(group="engine", name=name, node={"name": name})


def settings_of(conf: dict) -> tuple[Engine, object]:
    """(engine, its settings) of an `engine` config section (plain data)."""
    conf = dict(conf)
    e = get(conf.pop("name", None))
    try:
        return e, e.settings(**conf)
    except TypeError as err:
        raise ConfigError(f"engine={e.name}: {err}") from None


def run(conf: dict, todo: list[dict], workers: int, fn=None, logs=None, warm_up=None,
        **given):
    """Yield (trial, fn(trial)) for every trial of `todo` on the engine `conf` names. logs: a
    folder for job files; warm_up(todo) loads the kernels here unless the engine does
    (Engine.warms_up); given: pool, cost, each engine gets those it declares (Engine.takes)."""
    e, settings = settings_of(conf)
    if not todo:
        return
    if warm_up is not None and not e.warms_up:
        warm_up(todo)
    yield from e.run(todo, workers, fn, settings, logs, **{k: given.get(k) for k in e.takes})


def call(fn, trial: dict) -> dict:
    """fn(trial) in a worker: a module-level function Ray and submitit can ship."""
    return fn(trial)


def failed(trial: dict, error: str, seconds: float = 0.0, tb: str | None = None) -> dict:
    """A failed result as pipeline.worker.run_one makes one: not cached, retried next run."""
    lines = [ln for ln in str(error).splitlines() if ln.strip()]
    return dict(status="failed", error=lines[0] if lines else "failed", key=trial["key"],
                seconds=seconds, traceback=tb or str(error))
