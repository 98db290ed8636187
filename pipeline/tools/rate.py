"""The rule that fixed the paper's plain-step rates, for any body and setting.

    python -m pipeline.tools.rate body=icub                       # W and eta = 1 / W for the iCub
    python -m pipeline.tools.rate body=arm5 learner.variations=40 # at other V, K, L, R

W is the median sum of the weights per epoch at full size after 20,000 epochs of the normalised
step at rate 1.0 (3 seeds; gbmodel.learners.goal_babbling.weight_sum): the plain step at
eta = 1 / W equals the normalised step at full-size convergence. It prints W, eta and the two
lines that set them for the body (conf/body_learner/<body>_goal_babbling.yaml).
"""
from __future__ import annotations

import sys

import hydra
from omegaconf import DictConfig, OmegaConf

from gbmodel.learners import goal_babbling as gb

from .. import cli

EPOCHS, SEEDS, PROBE = 20_000, (0, 1, 2), 50  # the rule, as it was fixed before the runs


def rate(cfg: DictConfig, epochs: int = EPOCHS, seeds=SEEDS) -> dict:
    """W, eta = 1 / W and the samples per epoch it holds for, for cfg's body and learner."""
    if cfg.learner.name != "goal_babbling":
        from ..config import ConfigError

        raise ConfigError(f"learner={cfg.learner.name}: the rate rule is Goal Babbling's plain "
                          "step (learner=goal_babbling)")
    params = OmegaConf.to_container(cfg.learner)
    for k in ("name", "epochs", "evals_per_decade"):
        params.pop(k)
    W = gb.weight_sum(OmegaConf.to_container(cfg.body), params, seeds, epochs, PROBE)
    p = gb.Params(**params)
    samples = p.variations * (p.targets_per_epoch * p.steps + 1)
    return dict(body=cfg.body.name, W=W, learning_rate=1.0 / W, rate_samples=samples,
                current=p.rate())


def run(cfg: DictConfig) -> int:
    print(f"computing W for {cfg.body.name}: {len(SEEDS)} trials of {EPOCHS} epochs of the "
          "normalised step ...", file=sys.stderr, flush=True)
    r = rate(cfg)
    print(f"{r['body']}: W = {r['W']:.0f}, eta = 1 / W = {r['learning_rate']:.6g} at "
          f"{r['rate_samples']} samples per epoch (this config's eta: {r['current']:.6g})\n"
          f"# conf/body_learner/{r['body']}_goal_babbling.yaml\n"
          f"learning_rate: {r['learning_rate']:.3g}\nrate_samples: {r['rate_samples']}")
    return 0


@hydra.main(config_path="../conf", config_name="config", version_base="1.3")
def main(cfg: DictConfig) -> None:
    cli.finish(run, cfg)


if __name__ == "__main__":
    cli.main(main)
