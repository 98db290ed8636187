"""Learners as plug-ins: a module (or package) of this folder, found by its name, or one
`register`ed at run time. It provides (REQUIRED):

    Params                 frozen dataclass of hyperparameters with defaults; validate() returns
                           it or raises SpecError naming `learner.<field>`
    init(params, body, size, rng) -> state
    draw(params, body, B, rng) -> arrays with leading axis B (per block of trial.DRAW_BLOCK
                           epochs, so where a trial is evaluated never changes the draws)
    train(state, params, body, sizes, scales, draws, epochs) -> state
                           epochs at sizes[e], per-joint length factors scales[e]; epochs:
                           their 1-based numbers
    predict(state, params, body, x) -> q (N, m) for x (N, n)
    model(state) -> np.ndarray | None: a copy of what to store (M)
    samples_per_epoch(params, body) -> int: forward-kinematics evaluations per epoch

and may provide (OPTIONAL): sample_cost(params) (CPU time per sample and joint relative to Goal
Babbling's fast path; 1.0), notes(params, body) (what a user should know), predict_model(model,
params, body, x) (a learner without it is not drawn), distances(state, params, body, scale, xs)
(|f(g(x*)) - x*| its own faster way). The trial loop owns the rest; a learner only learns.
"""
from __future__ import annotations

import importlib
import inspect
import pkgutil
import sys
from pathlib import Path
from types import ModuleType

_REGISTERED: dict[str, ModuleType] = {}
REQUIRED = ("Params", "init", "draw", "train", "predict", "model", "samples_per_epoch")
OPTIONAL = ("sample_cost", "notes", "predict_model", "distances")


def available() -> list[str]:
    found = {m.name for m in pkgutil.iter_modules([str(Path(__file__).parent)])}
    return sorted(found | set(_REGISTERED))


def registered() -> list[str]:
    """The names `register`ed in this process (each may shadow a module of this folder)."""
    return sorted(_REGISTERED)


def register(name: str, module: ModuleType) -> None:
    missing = [a for a in REQUIRED if not hasattr(module, a)]
    if missing:
        raise TypeError(f"learner {name!r} lacks {', '.join(missing)}")
    _REGISTERED[name] = module


def get(name: str) -> ModuleType:
    if name in _REGISTERED:
        return _REGISTERED[name]
    loaded = sys.modules.get(f"{__name__}.{name}")
    if loaded is not None:  # imported before: no listing of the folder (twice per trial)
        return loaded
    if name not in available():
        raise ValueError(f"learner.name={name!r}: unknown learner; choose one of {available()}")
    return importlib.import_module(f"{__name__}.{name}")


def sources(name: str) -> list[tuple[str, str]]:
    """(label, source text) of learner `name`'s code for the key's fingerprint: its files here,
    read without importing it (a cached simulate loads no numba), or a registered module's name
    and the source of what it provides."""
    here = Path(__file__).resolve().parent
    package, single = here / name / "__init__.py", here / f"{name}.py"
    if name not in _REGISTERED and name in available():  # (a module or package here)
        files = sorted(package.parent.rglob("*.py")) if package.is_file() else [single]
        return [(f.resolve().relative_to(here.parents[1]).as_posix(), f.read_text()) for f in files]
    module = get(name)
    text = "\n".join(inspect.getsource(getattr(module, a)) for a in REQUIRED
                     if callable(getattr(module, a)) or inspect.isclass(getattr(module, a)))
    return [(f"{module.__name__}:{name}", text)]
