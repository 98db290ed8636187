"""Learners as plug-ins: the registry, and what a learner module provides.

A learner is one module (or package) in this folder, found by its name (`goal_babbling` is
`gbmodel/learners/goal_babbling/`). It provides:

    Params                 frozen dataclass of hyperparameters, with defaults; its validate()
                           returns it or raises gbmodel.spec.SpecError naming `learner.<field>`
    init(params, body, size, rng) -> state
                           the initial state with the body at size `size` (the first epoch's)
    draw(params, body, B, rng) -> tuple of arrays
                           the random numbers of B epochs, each array with leading axis B (drawn
                           in blocks of gbmodel.trial.DRAW_BLOCK epochs, so that where a trial is
                           evaluated or snapshot never changes the draws)
    train(state, params, body, sizes, scales, draws, epochs) -> state
                           len(sizes) epochs with the body at size sizes[e] and per-joint length
                           factors scales[e] (m,), consuming draws (sliced to those epochs);
                           epochs: their numbers, 1-based (for a schedule over the epochs)
    predict(state, params, body, x) -> q
                           the inverse estimate: commands (N, m) for positions (N, n)
    model(state) -> np.ndarray | None
                           a copy of the learned parameters to store (M for a polynomial inverse)
    samples_per_epoch(params, body) -> int
                           forward-kinematics evaluations (reaching movements) per epoch

and may provide (OPTIONAL; the pipeline falls back where one is missing):

    sample_cost(params) -> float
                           CPU time per sample and joint relative to Goal Babbling's fast
                           batch path (1.0 if missing): a run's ETA and its shards' balance
    notes(params, body) -> list[str]
                           what a user should know about these settings on this body (printed
                           once per run, e.g. a learning rate made for another body)
    predict_model(model, params, body, x) -> q
                           predict from what `model(state)` stored (the report draws with it;
                           a learner without it is not drawn)
    distances(state, params, body, scale, xs) -> (N,)
                           |f(g(x*)) - x*| per point, computed its own (faster) way

The trial loop (gbmodel.trial) owns the body, its growth, the draws, the evaluation and the
snapshots; a learner only learns. `register` adds a module under a name at run time (tests).
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
    """Names of every learner: the modules of this package and those registered at run time."""
    found = {m.name for m in pkgutil.iter_modules([str(Path(__file__).parent)])}
    return sorted(found | set(_REGISTERED))


def register(name: str, module: ModuleType) -> None:
    """Make `module` the learner `name` in this process (it must provide REQUIRED)."""
    missing = [a for a in REQUIRED if not hasattr(module, a)]
    if missing:
        raise TypeError(f"learner {name!r} lacks {', '.join(missing)}")
    _REGISTERED[name] = module


def get(name: str) -> ModuleType:
    """The learner module `name`; ValueError naming `learner.name` if there is none."""
    if name in _REGISTERED:
        return _REGISTERED[name]
    loaded = sys.modules.get(f"{__name__}.{name}")
    if loaded is not None:  # imported before: no listing of the folder (twice per trial)
        return loaded
    if name not in available():
        raise ValueError(f"learner.name={name!r}: unknown learner; choose one of {available()}")
    return importlib.import_module(f"{__name__}.{name}")


def sources(name: str) -> list[tuple[str, str]]:
    """(label, source text) of learner `name`'s code, for the cache key's code fingerprint: its
    files under gbmodel/learners/, or, for a module registered from elsewhere (or built at run
    time), its module name and the source of what it provides."""
    module = get(name)
    here = Path(__file__).resolve().parent
    path = Path(getattr(module, "__file__", None) or "")
    if path.is_file() and here in path.resolve().parents:
        files = sorted(path.parent.rglob("*.py")) if path.name == "__init__.py" else [path]
        return [(f.resolve().relative_to(here.parents[1]).as_posix(), f.read_text()) for f in files]
    text = "\n".join(inspect.getsource(getattr(module, a)) for a in REQUIRED
                     if callable(getattr(module, a)) or inspect.isclass(getattr(module, a)))
    return [(f"{module.__name__}:{name}", text)]
