"""A composed config -> its trials as plain data (variants x conditions x trial index), each
value checked once before anything is written (a trial's by gbmodel's TrialSpec.validate, the
plan's here): a ConfigError naming the key. A condition is its settings (keys.condition_id:
spec and root seed), never a label; a reference keeps the body at one size.
"""
from __future__ import annotations

import json
import logging
from functools import lru_cache

import numpy as np

import gbmodel
import gbmodel.bodies
from gbmodel.spec import SpecError, check_int
from omegaconf import DictConfig, OmegaConf

from .config import ConfigError, check_limits, check_run
from .fingerprint import code_fingerprint
from .keys import canonical, condition_id, stable_hash32, trial_key

log = logging.getLogger(__name__)


def _sized(pattern, size):
    return dict(pattern=pattern, start_size=float(size), end_size=float(size), period=0)


def conditions(cfg: DictConfig) -> list[dict]:
    """The growth conditions (the growth group's, or conditions.periods), then the references:
    dict(condition, growth, growth_period, spec) each."""
    g = OmegaConf.to_container(cfg.growth)
    pattern = g.pop("pattern")
    periods, refs = list(cfg.conditions.periods), list(cfg.conditions.references)
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


TRIAL_SECTIONS = ("body", "growth", "learner", "evaluation", "conditions", "trials")


def variants(cfg: DictConfig) -> list[tuple[dict | None, DictConfig]]:
    """(variant, its config) for each variant of the experiment, or [(None, cfg)] without any."""
    out = []  # from a copy of the trial's sections without the variants (small deep copies)
    base = OmegaConf.masked_copy(cfg, list(TRIAL_SECTIONS))
    OmegaConf.set_struct(base, True)
    base.conditions.variants = []
    for v in cfg.conditions.variants or [None]:
        vcfg = base.copy()
        groups = [o for o in ([] if v is None else v.set) if "=" in o and "." not in o.split("=", 1)[0]]
        try:
            for o in groups:  # `learner=<name>`: that learner's config, for this body
                group, name = o.split("=", 1)
                if group != "learner":
                    raise ValueError(f"{o}: a variant can choose a learner, not a {group}")
                vcfg.learner = OmegaConf.create(_learner_for(cfg.body.name, o))
            if v is not None:
                vcfg.merge_with(OmegaConf.from_dotlist([o for o in v.set if o not in groups]))
        except Exception as err:  # an unknown key or a wrong type in the variant
            raise SpecError("conditions.variants", v.label,
                            f"set {list(v.set)}: {err}".splitlines()[0]) from None
        apply_budget(vcfg)
        out.append((None if v is None else dict(label=v.label, choice=v.choice,
                                                 chosen=bool(v.chosen)), vcfg))
    labels = [v["label"] for v, _ in out if v]
    if len(set(labels)) != len(labels):
        raise SpecError("conditions.variants", labels, "labels must differ")
    return out


@lru_cache(maxsize=None)
def _learner_for(body: str, choice: str) -> dict:
    """The learner section `learner=<name>` composes to for a body (cached: a third of a s)."""
    from .config import compose

    return OmegaConf.to_container(compose([f"body={body}", choice]).learner)


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


def frame_epochs(epochs: int, frames: int) -> list[int]:
    """`frames` epochs log-spaced over 1 ... epochs (fewer where two round alike)."""
    if frames <= 0:
        return []
    if frames == 1:
        return [int(epochs)]
    return sorted({int(e) for e in np.rint(np.geomspace(1, epochs, frames))})


def trial_spec(cfg: DictConfig, growth: dict) -> gbmodel.TrialSpec:
    learner = OmegaConf.to_container(cfg.learner)
    epochs, per_decade = learner.pop("epochs"), learner.pop("evals_per_decade")
    # a learner may leave fields out of the key that change nothing at their defaults
    try:
        learner = getattr(gbmodel.learners.get(learner["name"]), "keyed", dict)(learner)
    except ValueError as err:
        raise ConfigError(str(err)) from None
    frames = frame_epochs(epochs, cfg.conditions.frames) if isinstance(epochs, int) else []
    snaps = tuple(sorted({e for e in [*cfg.conditions.snapshots, *frames]
                          if isinstance(e, int) and e <= epochs}))
    body = body_content(OmegaConf.to_container(cfg.body))
    spec = gbmodel.TrialSpec(
        body=body, growth=constant_growth(canonical(body), canonical(growth)), learner=learner,
        evaluation=OmegaConf.to_container(cfg.evaluation), epochs=epochs,
        evals_per_decade=per_decade, snapshots=snaps)
    try:
        spec.validate()
    except ValueError as err:
        raise ConfigError(str(err)) from None
    check_reach(canonical(spec.body))
    return spec


SAME_SIZE = 8 * np.finfo(np.float64).eps  # relative: factors this close to S are S (rounding)


@lru_cache(maxsize=256)
def constant_growth(body_json: str, growth_json: str) -> dict:
    """A growth whose every segment stays at one size S (within SAME_SIZE) is the one constant
    growth (proportional at S, period 0), whatever named it: Fig. 5's full-size reference is
    Fig. 4's trials. Any other growth (a held segment off S) is returned as it is."""
    growth = json.loads(growth_json)
    try:
        g = gbmodel.Growth(**growth)
        if not (g.period == 0 or (g.start_size == g.end_size and g.schedule != "table")):
            return growth
        body = gbmodel.make_body(json.loads(body_json))
        size = float(g.sizes(np.array([1]), body)[0])
        if not np.all(np.abs(g.scales(body, np.array([size])) - size) <= SAME_SIZE * size):
            return growth
    except (TypeError, ValueError, KeyError, OSError):  # invalid: TrialSpec.validate says why
        return growth
    return gbmodel.Growth(start_size=size, end_size=size, period=0).to_dict()


def stream(spec: dict) -> int:
    """A condition's random stream: a hash of its body's name and growth pattern, sizes and
    period only, so variants changing anything else share their draws (common random numbers)."""
    g = spec["growth"]
    return stable_hash32(dict(body=spec["body"]["name"], pattern=g["pattern"],
                              start_size=g["start_size"], end_size=g["end_size"],
                              period=g["period"]))


def body_content(body: dict) -> dict:
    """The body with the SHA-256 of every file it reads (source_digest: an edited file is another
    body); `credits` left out where it has none."""
    if body.get("credits") is None:  # a body without credits: its key as before the field
        body = {k: v for k, v in body.items() if k != "credits"}
    for section in gbmodel.bodies.READS:
        try:
            sha = gbmodel.bodies.source_digest(section, body.get(section))
        except ValueError as err:
            raise ConfigError(str(err)) from None
        if sha is not None:
            body = {**body, section: {**body[section], "sha256": sha}}
    return body


@lru_cache(maxsize=64)
def check_reach(body_json: str) -> None:
    """Warn (once per body) of grid targets no posture reaches (gbmodel.bodies.unreachable)."""
    body = gbmodel.make_body(json.loads(body_json))
    missed = gbmodel.bodies.unreachable(body, np.random.default_rng(0))
    if len(missed):
        log.warning("warning: body.grid=%s: %d of %d targets of %s are reached by no posture within 1 mm "
                    "(e.g. %s)", json.loads(body_json)["grid"], len(missed), len(body.targets),
                    body.name, np.round(body.targets[missed[0]], 3).tolist())


_CHECKED: dict[str, list] = {}  # the plan the command-line check made, taken once by its stage


def _config_key(cfg: DictConfig) -> str | None:
    try:
        return canonical(OmegaConf.to_container(cfg, resolve=True))
    except Exception:  # an interpolation only Hydra's own run resolves: no reuse
        return None


def plan(cfg: DictConfig, remember: bool = False) -> list[dict]:
    """Every trial (key, spec, seed, code, labels, figure, condition, growth_label, variant) in
    order. remember: the next plan() of the same config in this process takes this one (the
    command line's check plans before Hydra starts the stage)."""
    key = _config_key(cfg) if (remember or _CHECKED) else None
    if key is not None and key in _CHECKED:
        check_run(cfg)  # the place may have changed since (a folder made a file): cheap
        return _CHECKED.pop(key)
    trials = _plan(cfg)
    if remember and key is not None:
        _CHECKED.clear()
        _CHECKED[key] = trials
    return trials


def _plan(cfg: DictConfig) -> list[dict]:
    trials = []
    try:
        check_run(cfg)
        for variant, vcfg in variants(cfg):
            check_limits(vcfg)  # a variant's `set` may change what the command line did not
            for cond in conditions(vcfg):
                spec = trial_spec(vcfg, cond["spec"]).to_dict()
                c = stream(spec)
                cid = condition_id(spec, vcfg.trials.root_seed)
                code = code_fingerprint(spec["learner"]["name"])
                base = base_spec(cfg, vcfg, variant, cond, spec)
                for i in range(vcfg.trials.count):
                    seed = dict(entropy=vcfg.trials.root_seed, spawn_key=[c, i])
                    labels = dict(body=spec["body"]["name"], learner=spec["learner"]["name"],
                                  growth=cond["growth"], growth_period=cond["growth_period"],
                                  trial=i)
                    t = dict(spec=spec, seed=seed, code=code, labels=labels,
                             figure=cfg.figure, condition=cid, growth_label=cond["condition"],
                             variant=variant)
                    if base is not None:  # a continuation: of its base's saved state
                        b = dict(t, key=trial_key(base, seed, code), spec=base, variant=None,
                                 condition=condition_id(base, vcfg.trials.root_seed),
                                 growth_label=f"{cond['condition']} (its first "
                                              f"{base['epochs']} epochs)", keep_state=True)
                        t.update(start=dict(epoch=base["epochs"], key=b["key"]), base=b)
                    trials.append(dict(key=trial_key(spec, seed, code, t.get("start")), **t))
    except gbmodel.SpecError as err:
        raise ConfigError(str(err)) from None
    return trials


# learner fields acting only through each epoch's rate (Params.rates): a continuation may change them
RATE_FIELDS = ("learning_rate", "rate_samples", "rate_schedule", "anneal_epochs",
               "rate_step_epoch", "rate_step_factor")


def base_spec(cfg: DictConfig, vcfg: DictConfig, variant, cond: dict, spec: dict) -> dict | None:
    """The spec a continuation continues (conditions.continues epochs of its condition without the
    variants), None without one or with fewer epochs; ConfigError for a variant that changes
    anything but the rate after those epochs."""
    n = cfg.conditions.continues
    if n is None:
        return None
    from gbmodel.trial import DRAW_BLOCK

    def bad(why):
        return SpecError("conditions.continues", n, why)

    check_int("conditions.continues", n, 1)
    if n % DRAW_BLOCK:
        raise bad(f"a continuation starts after a multiple of {DRAW_BLOCK} epochs (the draws "
                  "come in blocks of that many)")
    if cfg.conditions.budget is not None:
        raise bad("a continuation counts epochs, not a sample budget")
    if not isinstance(spec["epochs"], int) or n >= spec["epochs"]:
        return None
    bcfg = OmegaConf.masked_copy(cfg, list(TRIAL_SECTIONS))
    bcfg.conditions.variants = []
    bcfg.learner.epochs = n
    base = trial_spec(bcfg, cond["spec"]).to_dict()
    where = f"variant {variant['label']!r}" if variant else "the experiment"
    for k in ("body", "growth", "evaluation", "evals_per_decade"):
        if base[k] != spec[k]:
            raise bad(f"{where} changes {k}: a continuation may change the rate after its "
                      "base's epochs, nothing else")
    if not set(e for e in spec["snapshots"] if e <= n) <= set(base["snapshots"]):
        raise bad(f"{where} stores a snapshot its base does not")
    a, b = base["learner"], spec["learner"]
    changed = {k for k in set(a) | set(b) if a.get(k) != b.get(k)}
    if changed:
        module = gbmodel.learners.get(b["name"])
        epochs = np.arange(1, n + 1)
        rates = [module.Params(**{k: v for k, v in x.items() if k != "name"}).rates(epochs)
                 if hasattr(module.Params, "rates") else None for x in (a, b)]
        if not changed <= set(RATE_FIELDS) or not np.array_equal(*rates):
            raise bad(f"{where} changes learner.{sorted(changed)[0]} before epoch {n}: a "
                      "continuation may change the rate after its base's epochs only")
    return base


def plan_conditions(trials: list[dict]) -> list[dict]:
    """One entry per variant and condition id of planned trials, with their trials' keys."""
    out = {}
    for t in trials:
        v = t.get("variant")
        c = out.setdefault((v["label"] if v else None, t["condition"]), dict(
            id=t["condition"], spec=t["spec"], root_seed=t["seed"]["entropy"],
            growth_label=t["growth_label"], growth=t["labels"]["growth"],
            growth_period=t["labels"]["growth_period"], variant=v, trials=[]))
        c["trials"].append(dict(key=t["key"], trial=t["labels"]["trial"]))
    return list(out.values())


# CPU seconds per unit of cost() and per trial, calibrated on whole trials: the committed
# report's measured CPU per experiment (2,595 trials on a 2-core AMD EPYC with AVX-512, views at
# 0 s) and the README's two sweep jobs are 0.84 to 1.28 x cpu_seconds, all of it 1.025
# (tests/pipeline/test_sweeps.py); the report before, on an Intel Xeon with AVX-512, gave 2.0 ns a
# unit, the one before it (a loaded AMD EPYC with AVX2, older kernels) 3.1 ns and 0.05 s a trial
SECONDS_PER_COST = 1.35e-9
SECONDS_PER_TRIAL = 0.02


def cpu_seconds(units: float, trials: int) -> float:
    return SECONDS_PER_COST * units + SECONDS_PER_TRIAL * trials


def cost(trial: dict) -> float:
    """Relative run time: epochs x samples per epoch x joints x the learner's sample_cost (a
    continuation: its own epochs)."""
    start = trial.get("start")
    done = start["epoch"] / trial["spec"]["epochs"] if start else 0.0
    return _cost(canonical(trial["spec"])) * (1.0 - done)


@lru_cache(maxsize=1024)
def _cost(spec_json: str) -> float:  # per condition, not per trial: a body is built for it
    spec = gbmodel.TrialSpec.from_dict(json.loads(spec_json))
    learner, params = spec.make_learner()
    body = spec.make_body()
    per = learner.sample_cost(params) if hasattr(learner, "sample_cost") else 1.0
    return float(spec.epochs) * learner.samples_per_epoch(params, body) * body.m * per
