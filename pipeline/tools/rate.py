"""The rule that fixed the paper's plain-step rates, for any body and setting.

    python -m pipeline.tools.rate body=icub                       # W and eta = 1 / W for the iCub
    python -m pipeline.tools.rate body=arm5 learner.variations=40 # at other V, K, L, R
    python -m pipeline.tools.rate 'hydra.searchpath=[file:///my/conf]' body=my_arm \
      learner.solver=lstsq learner.radius=0.1 learner.targets_per_epoch=30 learner.steps=10 --write

It prints the body's learner settings file (destination): the settings given on the command
line that differ from the core's defaults and eta = 1 / W (weight_sum); --write writes it. With
solver=lstsq there is no rate.
"""
from __future__ import annotations

import dataclasses
import os
import sys
from pathlib import Path

import hydra
import numpy as np
from omegaconf import DictConfig, OmegaConf

from gbmodel.features import exponents
from gbmodel.learners import goal_babbling as gb
from gbmodel.learners.goal_babbling import reference
from gbmodel.trial import TrialSpec, run_trial

from .. import cli
from ..config import CONF_DIR, CONFIG_PATH, IN_CHECKOUT, ConfigError

EPOCHS, SEEDS, PROBE = 20_000, (0, 1, 2), 50  # the rule, as it was fixed before the runs
WRITE = "--write"  # write the settings file where it goes, instead of printing it
_WRITE = [False]


def weight_sum(body: dict, params: dict, seeds=SEEDS, epochs: int = EPOCHS,
               probe: int = PROBE) -> float:
    """W: the median sum of the weights per epoch at full size after `epochs` epochs of the
    normalised step at rate 1.0 (a trial per seed, then `probe` epochs of new draws, not learned
    from): the plain step at eta = 1 / W equals the normalised one at full-size convergence
    (arm5 W = 1142, iCub W = 1791, arm2 W = 1931 when the rates were fixed)."""
    params = {**params, "step": "normalised", "learning_rate": 1.0}
    sums = []
    for seed in seeds:
        spec = TrialSpec(body=body, learner={"name": "goal_babbling", **params}, epochs=epochs)
        M = run_trial(spec, np.random.default_rng(seed)).M
        b, p = spec.make_body(), gb.Params(**params)
        idx, raw = gb.draw(p, b, probe, np.random.default_rng(1000 + seed))[:2]
        exps = exponents(b.n, p.degree)
        for e in range(probe):
            _, (_, _, _, w) = reference.epoch(M, b, 1.0, np.ones(b.m), exps, idx[e], raw[e],
                                              p.radius, p.steps, 0.0)
            sums.append(float(w.sum()))
    return float(np.median(sums))


def rate(cfg: DictConfig, epochs: int = EPOCHS, seeds=SEEDS) -> dict:
    """W, eta = 1 / W and the samples per epoch it holds for, for cfg's body and Goal Babbling."""
    params = OmegaConf.to_container(cfg.learner)
    for k in ("name", "epochs", "evals_per_decade"):
        params.pop(k)
    W = weight_sum(OmegaConf.to_container(cfg.body), params, seeds, epochs, PROBE)
    p = gb.Params(**params)
    return dict(body=cfg.body.name, W=W, learning_rate=1.0 / W, current=p.rate(),
                rate_samples=p.variations * (p.targets_per_epoch * p.steps + 1))


def destination(cfg: DictConfig) -> Path:
    """body_learner/<body>_goal_babbling.yaml in the config folder that holds the body's file (a
    folder of hydra.searchpath, or conf/: the checkout's, or installed, the working directory's)."""
    from hydra.core.hydra_config import HydraConfig

    folders = [Path(s.path) for s in HydraConfig.get().runtime.config_sources
               if s.schema == "file"] if HydraConfig.initialized() else []
    home = next((f for f in folders if (f / "body" / f"{cfg.body.name}.yaml").is_file()),
                CONF_DIR if IN_CHECKOUT else Path.cwd() / "conf")
    return home / "body_learner" / f"{cfg.body.name}_goal_babbling.yaml"


def settings_file(cfg: DictConfig, path: Path, r: dict | None) -> str:
    """The file at `path`: the package line, cfg's settings that differ from the core's defaults
    (Params; the rate aside) and (r given: the plain step) its rate."""
    defaults = dataclasses.asdict(gb.Params())
    lines = ["# @package learner", f"# {path}: Goal Babbling's settings for {cfg.body.name}"]
    lines += [f"{k}: {v}" for k, v in OmegaConf.to_container(cfg.learner).items()
              if k in defaults and v != defaults[k] and k not in ("learning_rate", "rate_samples")]
    if r is not None:
        lines += [f"learning_rate: {r['learning_rate']:.3g}   # 1 / W, W = {r['W']:.0f}",
                  f"rate_samples: {r['rate_samples']}"]
    return "\n".join(lines) + "\n"


def write_settings(path: Path, text: str) -> Path | None:
    """Put the settings file at `path` in one rename; ConfigError for a file without a setting.
    A file that was there with other settings is kept as `.<name>.previous` (Hydra reads no
    such file), which is returned; an empty one (left by `rate > file`) is simply replaced."""
    if not [ln for ln in text.splitlines() if ln.strip() and not ln.startswith("#")]:
        raise ConfigError(f"{path}: no setting to write (these are the core's defaults); give "
                          "the learner's settings on the command line, e.g. learner.solver=lstsq")
    path.parent.mkdir(parents=True, exist_ok=True)
    old = path.read_text() if path.is_file() else ""
    kept = path.with_name(f".{path.name}.previous") if old.strip() and old != text else None
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    try:
        tmp.write_text(text)
        if kept is not None:
            kept.write_text(old)
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)
    return kept


def run(cfg: DictConfig, write: bool | None = None) -> int:
    """Print the body's learner settings file, or (`--write`) write it where it goes."""
    from ..plan import SECONDS_PER_COST, cost, plan
    from ..progress import fmt_duration

    if cfg.learner.name != "goal_babbling":  # before its settings: another has no `solver`
        raise ConfigError(f"learner={cfg.learner.name}: the rate rule is Goal Babbling's plain "
                          "step (learner=goal_babbling)")
    path, r = destination(cfg), None
    if cfg.learner.solver == "gradient":
        cpu = len(SEEDS) * cost(dict(spec={**plan(cfg)[0]["spec"], "epochs": EPOCHS}))
        print(f"computing W for {cfg.body.name}: {len(SEEDS)} trials of {EPOCHS:,} epochs of "
              f"the normalised step, about {fmt_duration(cpu * SECONDS_PER_COST)} of CPU time "
              "(the cost model) ...", file=sys.stderr, flush=True)
        r = rate(cfg)
        print(f"{r['body']}: W = {r['W']:.0f}, eta = 1 / W = {r['learning_rate']:.6g} at "
              f"{r['rate_samples']} samples per epoch (this config's eta: {r['current']:.6g})",
              file=sys.stderr)
    text = settings_file(cfg, path, r)
    if _WRITE[0] if write is None else write:
        kept = write_settings(path, text)
        print(f"wrote {path}" + (f" (its previous settings kept in {kept})" if kept else "")
              + ":", file=sys.stderr)
    else:
        print(f"put these lines into {path} (or run this again with {WRITE}):", file=sys.stderr)
    print(text, end="")
    return 0


@hydra.main(config_path=CONFIG_PATH, config_name="config", version_base="1.3")
def main(cfg: DictConfig) -> None:
    cli.finish(run, cfg)


def take_flags(argv: list[str]) -> list[str]:
    """argv without --write (Hydra's parser would refuse it), noted."""
    _WRITE[0] = _WRITE[0] or WRITE in argv
    return [a for a in argv if a != WRITE]


if __name__ == "__main__":
    sys.argv = [sys.argv[0], *take_flags(sys.argv[1:])]
    cli.main(main)
