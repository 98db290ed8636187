"""Engines: where the simulate stage runs its trials, one module each, registered by name.

    python -m pipeline.simulate experiment=fig4 engine=ray engine.address=auto
    python -m pipeline.simulate experiment=fig4 engine=slurm engine.partition=short workers=64

An engine is a module of this package (or, for one kept outside the repository, a module its
distribution declares as an entry point of `gbgrowth.engines`: pipeline.plugins): a settings
dataclass and a run function, registered with `@engine(name, Settings)`. The config group `engine` is generated from them
(register_configs: `engine=<name>` picks one, `engine.<field>=...` sets its settings, typed by
the dataclass), so an engine added is an engine on the command line, with no other edit.

run(todo, workers, fn, settings, logs) yields (trial, fn(trial)) for every trial of `todo`
(plain data, longest first) as they finish; an engine that needs more is given it by the stage,
as arguments it declares (`takes`: the local `pool`, the trials' `cost`), and imports nothing
of the pipeline above it; the driver (pipeline.simulate) writes every result
to the cache itself. So no cache file is ever written by a worker or by two jobs, the per-trial
claims and plan records stay where they are, and the trial files are byte for byte those of a
local run (a result is the same plain data whichever process computed it). A worker checks that
its gbmodel code has the fingerprint the driver put into the trial's key
(pipeline.fingerprint.code_fingerprint; pipeline.worker.run_one), so a node with other code
fails the trial instead of caching a result computed by code the key does not name.

Why driver-side engines rather than Hydra's launchers (hydra-ray-launcher, submitit-launcher):
a launcher's unit of work is a whole stage run (one composed config, one `simulate`); here the
unit of work is a trial, and one figure is hundreds of trials of very different lengths. A
launcher would either run each figure on one node, or run many `simulate` processes that all
write into one cache. Driver-side engines keep one writer and schedule trials longest first.
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
    run: Callable  # run(todo, workers, fn, settings, logs) -> iterator of (trial, result)
    package: str | None = None  # the module it needs (imported only when it runs)
    extra: str | None = None  # the pyproject extra that installs that module
    # it loads the kernels in its own workers (local: the pool's first worker, or this process);
    # else run() has them loaded here first (its warm_up), into numba's cache its workers read
    warms_up: bool = False
    takes: tuple = ()  # what else run() is given, by keyword: "pool", "cost" (engines.run)


_ENGINES: dict[str, Engine] = {}
_BROKEN: dict[str, str] = {}  # engine name -> why its entry point's module did not import


def engine(name: str, settings: type = NoSettings, package: str | None = None,
           extra: str | None = None, warms_up: bool = False, takes: tuple = ()):
    """Register the decorated run function as engine `name`, with its settings dataclass and
    the package it needs (checked by the stage that submits, before anything runs); warms_up:
    it loads the kernels itself (Engine.warms_up); takes: what else it is given (Engine)."""
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


_DISCOVERED: list = []  # [True] once discover() ran in this process


def discover() -> tuple[str, ...]:
    """Import every engine module (this package's, and the entry points of gbgrowth.engines);
    the names registered, sorted. An engine module imports what it runs on (a pool, Ray,
    submitit) inside its run function: naming the engines costs no such import."""
    for m in pkgutil.iter_modules(__path__):
        importlib.import_module(f"{__name__}.{m.name}")
    load_plugins(ENGINES, _BROKEN)  # a failure is named when its engine is chosen
    _DISCOVERED[:] = [True]
    return tuple(sorted(_ENGINES))


def available() -> tuple[str, ...]:
    """The names of the engines (discovered on first use)."""
    return tuple(sorted(_ENGINES)) if _DISCOVERED else discover()


def _error(message: str) -> Exception:
    return ConfigError(message)


def get(name: str) -> Engine:
    if name not in _ENGINES and not _DISCOVERED:
        discover()
    if name in _BROKEN and name not in _ENGINES:
        raise _error(f"engine={name}: its module did not import ({_BROKEN[name]})")
    if name not in _ENGINES:
        raise _error(f"engine={name!r}: choose one of {', '.join(available())}")
    return _ENGINES[name]


def check(name: str, package: bool = True) -> Engine:
    """The engine `name`, or a ConfigError (one line) for an unknown one or (package) one whose
    package is not installed: only the stage that submits (simulate) needs it."""
    e = get(name)
    if package and e.package and importlib.util.find_spec(e.package) is None:
        raise _error(f"engine={name} needs the package {e.package}: pip install -e "
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
    for name in sorted(set(_BROKEN) - set(_ENGINES)):  # engine=<name> composes; the stage that
        # submits names the import error (check)
        cs.store(group="engine", name=name, node={"name": name})


def settings_of(conf: dict) -> tuple[Engine, object]:
    """(engine, its settings) of an `engine` config section (plain data: name and settings)."""
    conf = dict(conf)
    e = get(conf.pop("name", None))
    try:
        return e, e.settings(**conf)
    except TypeError as err:
        raise _error(f"engine={e.name}: {err}") from None


def run(conf: dict, todo: list[dict], workers: int, fn=None, logs=None, warm_up=None,
        **given):
    """Yield (trial, fn(trial)) for every trial of `todo` on the engine `conf` names, with its
    settings (the `engine` config section as plain data); fn: what a worker runs on a trial
    (the stage's pipeline.worker.run_one); logs: a folder for its job files;
    warm_up(todo): loads the trials' kernels in this process (execute.warm_up), first, unless
    the engine does it in its own workers (Engine.warms_up); given: what the engines may take
    (Engine.takes: pool, the local pool; cost, a trial's estimated cost), each engine gets the
    ones it declares."""
    e, settings = settings_of(conf)
    if not todo:
        return
    if warm_up is not None and not e.warms_up:  # the kernels loaded once here, not per worker
        warm_up(todo)
    yield from e.run(todo, workers, fn, settings, logs, **{k: given.get(k) for k in e.takes})


# --- shared by the engines ------------------------------------------------------------------

def call(fn, trial: dict) -> dict:
    """fn(trial) in a worker (pipeline.worker.run_one checks the worker's code fingerprint)."""
    return fn(trial)


def failed(trial: dict, error: str, seconds: float = 0.0, tb: str | None = None) -> dict:
    """A failed result as pipeline.worker.run_one makes one: not cached, retried next run."""
    lines = [ln for ln in str(error).splitlines() if ln.strip()]
    out = dict(status="failed", error=lines[0] if lines else "failed", key=trial["key"],
               seconds=seconds)
    out["traceback"] = tb or str(error)
    return out
