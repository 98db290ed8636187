"""From a composed config to the list of trials to run: variants x conditions x trial index.

Everything a trial needs is plain data (a dict), so it can be sent to a worker process or a
cluster and hashed into the cache key. Every value is checked here, before any stage writes
anything: the trial's own values by gbmodel (TrialSpec.validate, whose SpecError names the config
key), the plan's by this module; either way a ConfigError with one line naming the key.

A condition is a body growing by a pattern from a start to an end size over T_G epochs, or a body
of constant size (a reference). Its name: `TG<period>` or `const<size>`, prefixed by the variant's
label when the experiment has variants.
"""
from __future__ import annotations

import ast
import hashlib
import json
import logging
import os
from functools import lru_cache
from pathlib import Path

import numpy as np

import gbmodel
import gbmodel.bodies
from gbmodel.growth import check_int
from omegaconf import DictConfig, OmegaConf

from .config import ConfigError, check_backend

log = logging.getLogger(__name__)
MAX_EPOCHS = 10**9  # a trial's memory does not grow with its epochs, but its time does


def _bad(key, value, why):
    raise ConfigError(f"{key}={value!r}: {why}")


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


def source_fingerprint(sources) -> str:
    """Hash of the code of `sources`, (name, source text) pairs (names + syntax trees): a change
    of what the code computes changes it; comments, docstrings and layout do not."""
    h = hashlib.sha256()
    for name, text in sorted(sources):
        h.update(name.encode() + b"\0")
        h.update(_code_of(text).encode() + b"\0")
    return h.hexdigest()[:16]


@lru_cache(maxsize=None)
def code_fingerprint(learner: str) -> str:
    """The fingerprint of the code a trial of `learner` runs: gbmodel's shared core (every file
    outside gbmodel/learners/, and the registry) plus that learner's own files. Changing one
    learner recomputes its trials only; an edited comment recomputes none."""
    root = Path(gbmodel.__file__).resolve().parent
    shared = [p for p in root.rglob("*.py")
              if "learners" not in p.relative_to(root).parts[:-1]]
    shared.append(root / "learners" / "__init__.py")
    own = [(p.relative_to(root.parent).as_posix(), p.read_text()) for p in shared]
    return source_fingerprint(own + gbmodel.learners.sources(learner))


def _sized(pattern, size):
    return dict(pattern=pattern, start_size=float(size), end_size=float(size), period=0)


def conditions(cfg: DictConfig) -> list[dict]:
    """The conditions of one (variant of a) config: the growth group's (or the experiment's
    periods), then the constant-size references, each a dict(condition, growth label, period,
    growth spec)."""
    g = OmegaConf.to_container(cfg.growth)
    pattern = g.pop("pattern")
    periods = list(cfg.conditions.periods)
    for p in periods:
        check_int("conditions.periods", p, 0)
    refs = list(cfg.conditions.references)
    for s in refs:
        if isinstance(s, bool) or not isinstance(s, (int, float)) or not s > 0:
            _bad("conditions.references", s, "a body size must be > 0")
    # A reference shrinks the body the way the figure's growth does (Fig. 5: non-proportionally).
    ref_pattern = "proportional" if pattern == "none" else pattern
    out = []
    if pattern == "none" or (g["period"] == 0 and not periods):
        refs = [g["end_size"]] + refs
    else:
        for p in periods or [g["period"]]:
            out.append(dict(condition=f"TG{p}", growth=pattern, growth_period=p,
                            spec={**g, "pattern": pattern, "period": p}))
    for s in refs:
        out.append(dict(condition=f"const{float(s)}", growth="none", growth_period=0,
                        spec={**g, **_sized(ref_pattern, s)}))
    unique = {}  # a reference may repeat the growth group's constant size
    for c in out:
        unique.setdefault(c["condition"], c)
    return list(unique.values())


def variants(cfg: DictConfig) -> list[tuple[dict | None, DictConfig]]:
    """(variant, its config) for each variant of the experiment, or [(None, cfg)] without any."""
    out = []
    for v in cfg.conditions.variants or [None]:
        if v is None:  # a copy: planning never changes the caller's config
            vcfg = cfg.copy()
            apply_budget(vcfg)
            out.append((None, vcfg))
            continue
        vcfg = cfg.copy()
        groups = [o for o in v.set if "=" in o and "." not in o.split("=", 1)[0]]
        try:
            for o in groups:  # `learner=<name>`: that learner's config, for this body
                group, name = o.split("=", 1)
                if group != "learner":
                    raise ValueError(f"{o}: a variant can choose a learner, not a {group}")
                from .config import compose
                vcfg.learner = compose([f"body={cfg.body.name}", o]).learner
            vcfg.merge_with(OmegaConf.from_dotlist([o for o in v.set if o not in groups]))
        except Exception as err:  # an unknown key or a wrong type in the variant
            _bad("conditions.variants", v.label, f"set {list(v.set)}: {err}".splitlines()[0])
        apply_budget(vcfg)
        out.append((dict(label=v.label, choice=v.choice, chosen=bool(v.chosen)), vcfg))
    labels = [v["label"] for v, _ in out if v]
    if len(set(labels)) != len(labels):
        _bad("conditions.variants", labels, "labels must differ")
    return out


def apply_budget(cfg: DictConfig) -> None:
    """conditions.budget: the learner's epochs and the growth period from a sample budget."""
    c = cfg.conditions
    if c.budget is None:
        return
    check_int("conditions.budget", c.budget, 1)
    learner = dict(OmegaConf.to_container(cfg.learner))
    for k in ("epochs", "evals_per_decade"):
        learner.pop(k)
    name = learner.pop("name")
    module = gbmodel.learners.get(name)
    per_epoch = module.samples_per_epoch(module.Params(**learner), gbmodel.make_body(
        OmegaConf.to_container(cfg.body)))
    epochs = max(1, round(c.budget * c.budget_scale / per_epoch))
    cfg.learner.epochs = epochs
    if cfg.growth.pattern != "none":
        c.periods = [max(1, round(c.growth_share * epochs))]


def trial_spec(cfg: DictConfig, growth: dict) -> gbmodel.TrialSpec:
    """The TrialSpec of one condition, validated (ConfigError naming the config key)."""
    learner = OmegaConf.to_container(cfg.learner)
    epochs, per_decade = learner.pop("epochs"), learner.pop("evals_per_decade")
    snaps = tuple(sorted({e for e in cfg.conditions.snapshots
                          if isinstance(e, int) and e <= epochs}))
    for e in cfg.conditions.snapshots:
        check_int("conditions.snapshots", e, 1)
    if isinstance(epochs, int) and epochs > MAX_EPOCHS:
        _bad("learner.epochs", epochs, f"at most {MAX_EPOCHS:.0e} epochs per trial")
    spec = gbmodel.TrialSpec(
        body=OmegaConf.to_container(cfg.body), growth=growth, learner=learner,
        evaluation=OmegaConf.to_container(cfg.evaluation), epochs=epochs,
        evals_per_decade=per_decade, snapshots=snaps)
    try:
        spec.validate()
    except ValueError as err:
        raise ConfigError(str(err)) from None
    check_reach(_canonical(spec.body))
    return spec


@lru_cache(maxsize=64)
def check_reach(body_json: str) -> None:
    """Warn (once per body description and process) when some targets of the body's grid are
    reached by no posture within its limits (gbmodel.bodies.unreachable, at full size)."""
    body = gbmodel.make_body(json.loads(body_json))
    missed = gbmodel.bodies.unreachable(body, np.random.default_rng(0))
    if len(missed):
        log.warning("warning: body.grid=%s: %d of %d targets of %s are reached by no posture within 1 mm "
                    "(e.g. %s)", json.loads(body_json)["grid"], len(missed), len(body.targets),
                    body.name, np.round(body.targets[missed[0]], 3).tolist())


def check_paths(cfg: DictConfig) -> None:
    """Every output folder is a folder (or can become one)."""
    for key in ("root", "out", "cache", "aggregate", "report", "published", "bench"):
        path = Path(cfg.paths[key])
        for p in [path, *path.parents]:
            if p.exists():
                if not p.is_dir():
                    _bad(f"paths.{key}", str(path), f"{p} is a file, not a folder")
                if not os.access(p, os.W_OK | os.X_OK) and p == path:
                    _bad(f"paths.{key}", str(path), "is not writable")
                break


def plan(cfg: DictConfig) -> list[dict]:
    """Every trial of the config as plain data, in order (variant, condition, trial index)."""
    trials = []
    try:
        check_int("trials.count", cfg.trials.count, 1)
        check_int("trials.root_seed", cfg.trials.root_seed, 0)
        check_int("workers", cfg.workers, 1)
        check_backend(cfg.executor.backend)  # an unknown engine, or one whose package is missing
        if not cfg.figure or "/" in cfg.figure or cfg.figure.startswith("."):
            _bad("figure", cfg.figure, "must be a plain name (it names a folder)")
        check_paths(cfg)
        for variant, vcfg in variants(cfg):
            conds = conditions(vcfg)
            for cond in conds:
                spec = trial_spec(vcfg, cond["spec"]).to_dict()
                # The random stream depends on the condition's body and growth only, so that the
                # variants of an experiment differ by their choice, not by their draws.
                g = spec["growth"]
                stream = stable_hash32(dict(body=spec["body"]["name"], pattern=g["pattern"],
                                            start_size=g["start_size"],
                                            end_size=g["end_size"], period=g["period"]))
                name = (cond["condition"] if variant is None else variant["label"]
                        if len(conds) == 1 else f"{variant['label']} | {cond['condition']}")
                for i in range(vcfg.trials.count):
                    labels = dict(figure=cfg.figure, body=spec["body"]["name"],
                                  learner=spec["learner"]["name"], growth=cond["growth"],
                                  growth_period=cond["growth_period"], condition=name, trial=i)
                    trial = dict(labels=labels, spec=spec,
                                 seed=dict(entropy=vcfg.trials.root_seed, spawn_key=[stream, i]),
                                 code=code_fingerprint(spec["learner"]["name"]))
                    if variant is not None:
                        trial["variant"] = variant
                    trial["key"] = hashlib.sha256(_canonical(trial).encode()).hexdigest()[:20]
                    trials.append(trial)
    except gbmodel.SpecError as err:
        raise ConfigError(str(err)) from None
    return trials


def cost(trial: dict) -> float:
    """Rough relative run time of a trial: samples per epoch x joints x epochs."""
    spec = gbmodel.TrialSpec.from_dict(trial["spec"])
    learner, params = spec.make_learner()
    body = spec.make_body()
    return float(spec.epochs) * learner.samples_per_epoch(params, body) * body.m
