"""From a composed config to the list of trials to run: conditions x trial index.

Everything a trial needs is plain data (a dict), so it can be sent to a worker process and hashed
into the cache key. Every value is checked here, before any stage writes anything; a bad value
raises ConfigError with one line naming the config key and the value.

A condition is (growth pattern, start size, end size, growth period T_G) on one body. Its name:
`TG<period>` for a growing body, `const<size>` for a body of constant size (a reference).
"""
from __future__ import annotations

import ast
import hashlib
import json
from functools import lru_cache
from pathlib import Path

import gbmodel
from omegaconf import DictConfig, OmegaConf

from .config import ConfigError

GROWTH_OPTIONS = ("none",) + tuple(gbmodel.GROWTH_PATTERNS)

# TrialSpec field -> the config key a user sets it with (for error messages).
SPEC_KEYS = {
    "body": "body.name", "pattern": "growth.pattern", "start_size": "growth.start_size",
    "end_size": "growth.end_size", "period": "growth.period",
    "snapshot_epochs": "conditions.snapshots",
    **{k: f"learner.{k}" for k in (
        "epochs", "variations", "radius", "targets_per_epoch", "steps", "learning_rate",
        "init_range", "degree", "evals_per_decade")},
}


def _bad(key, value, why):
    raise ConfigError(f"{key}={value!r}: {why}")


def _check_int(key, value, minimum):
    if isinstance(value, bool) or not isinstance(value, int) or value < minimum:
        what = "a positive integer" if minimum == 1 else "a non-negative integer"
        _bad(key, value, f"must be {what}")


def _canonical(obj) -> str:
    return json.dumps(obj, sort_keys=True, separators=(",", ":"))


def stable_hash32(obj) -> int:
    """A 32-bit integer from the canonical JSON of obj: the same on every machine and run."""
    return int.from_bytes(hashlib.sha256(_canonical(obj).encode()).digest()[:4], "big")


def _code_of(source: str) -> str:
    """The syntax tree of a module without its docstrings (comments are not in it anyway)."""
    tree = ast.parse(source)
    for node in ast.walk(tree):
        body = getattr(node, "body", None)
        if (isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef))
                and body and isinstance(body[0], ast.Expr)
                and isinstance(body[0].value, ast.Constant) and isinstance(body[0].value.value, str)):
            node.body = body[1:] or [ast.Pass()]
    return ast.dump(tree, annotate_fields=False, include_attributes=False)


def source_fingerprint(root: Path) -> str:
    """Hash of the code of every .py file under root (sorted names + syntax trees): a change of
    what the code computes changes it; comments, docstrings and layout do not."""
    h = hashlib.sha256()
    for path in sorted(Path(root).rglob("*.py")):
        h.update(path.relative_to(root).as_posix().encode() + b"\0")
        h.update(_code_of(path.read_text()).encode() + b"\0")
    return h.hexdigest()[:16]


@lru_cache(maxsize=1)
def code_fingerprint() -> str:
    """The fingerprint of gbmodel's code: part of every cache key, so that a change of the
    numerical core recomputes every trial, and an edited comment recomputes none."""
    return source_fingerprint(Path(gbmodel.__file__).resolve().parent)


def conditions(cfg: DictConfig) -> list[dict]:
    """The conditions of the config: the growth group's (or the experiment's periods), then the
    constant-size references. Each is a dict of labels and TrialSpec growth fields."""
    g = cfg.growth
    if g.pattern not in GROWTH_OPTIONS:
        _bad("growth.pattern", g.pattern, f"unknown growth option; choose one of {list(GROWTH_OPTIONS)}")
    _check_int("growth.period", g.period, 0)
    periods = list(cfg.conditions.periods)
    for p in periods:
        _check_int("conditions.periods", p, 0)
    refs = list(cfg.conditions.references)
    for s in refs:
        if not s > 0:
            _bad("conditions.references", s, "a body size must be > 0")
    # A reference shrinks the body the way the figure's growth does (fig. 5: non-proportionally).
    ref_pattern = "proportional" if g.pattern == "none" else g.pattern

    out = []
    if g.pattern == "none":
        if not g.end_size > 0:
            _bad("growth.end_size", g.end_size, "a body size must be > 0")
        refs = [g.end_size] + refs
    else:
        for p in periods or [g.period]:
            out.append(dict(condition=f"TG{p}", growth=g.pattern, growth_period=p,
                            pattern=g.pattern, start_size=g.start_size, end_size=g.end_size,
                            period=p))
    for s in refs:
        out.append(dict(condition=f"const{float(s)}", growth="none", growth_period=0,
                        pattern=ref_pattern, start_size=float(s), end_size=float(s), period=0))
    unique = {}  # a reference may repeat the growth group's constant size
    for c in out:
        unique.setdefault(c["condition"], c)
    return list(unique.values())


def _spec(cfg: DictConfig, cond: dict) -> gbmodel.TrialSpec:
    learner = OmegaConf.to_container(cfg.learner)
    snaps = tuple(sorted({e for e in cfg.conditions.snapshots if e <= learner["epochs"]}))
    spec = gbmodel.TrialSpec(
        body=cfg.body.name, pattern=cond["pattern"], start_size=cond["start_size"],
        end_size=cond["end_size"], period=cond["period"], snapshot_epochs=snaps, **learner)
    try:
        return spec.validate()
    except ValueError as err:
        name, _, rest = str(err).partition("=")
        key = SPEC_KEYS.get(name, name)
        if cond["growth"] == "none" and name in ("start_size", "end_size"):
            key = "conditions.references"
        raise ConfigError(f"{key}={rest}") from None


def plan(cfg: DictConfig) -> list[dict]:
    """Every trial of the config as plain data, in order (condition, trial index)."""
    if cfg.body.name not in gbmodel.BODIES:
        _bad("body.name", cfg.body.name, f"unknown body; choose one of {sorted(gbmodel.BODIES)}")
    _check_int("learner.epochs", cfg.learner.epochs, 1)
    _check_int("trials.count", cfg.trials.count, 1)
    _check_int("trials.root_seed", cfg.trials.root_seed, 0)
    _check_int("workers", cfg.workers, 1)
    if cfg.learner.radius < 0:
        _bad("learner.radius", cfg.learner.radius, "must be >= 0")
    for e in cfg.conditions.snapshots:
        _check_int("conditions.snapshots", e, 1)
    if not cfg.figure or "/" in cfg.figure or cfg.figure.startswith("."):
        _bad("figure", cfg.figure, "must be a plain name (it names a folder)")

    trials = []
    for cond in conditions(cfg):
        spec = _spec(cfg, cond).to_dict()
        # The random stream depends on the condition's content, not on its position or figure.
        stream = stable_hash32({k: spec[k] for k in
                                ("body", "pattern", "start_size", "end_size", "period")})
        for i in range(cfg.trials.count):
            labels = dict(figure=cfg.figure, body=cfg.body.name, growth=cond["growth"],
                          growth_period=cond["growth_period"], condition=cond["condition"],
                          trial=i)
            seed = dict(entropy=cfg.trials.root_seed, spawn_key=[stream, i])
            trial = dict(labels=labels, spec=spec, seed=seed, fast=bool(cfg.fast),
                         code=code_fingerprint())
            trial["key"] = hashlib.sha256(_canonical(trial).encode()).hexdigest()[:20]
            trials.append(trial)
    return trials


def cost(trial: dict) -> float:
    """Rough relative run time of a trial: samples per epoch x joints x epochs."""
    s = trial["spec"]
    m = gbmodel.make_body(s["body"]).m
    return float(s["epochs"]) * s["variations"] * s["targets_per_epoch"] * s["steps"] * m
