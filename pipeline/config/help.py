"""What `--help` prints for a stage: its groups and their options, and its config."""
from __future__ import annotations

from .compose import compose, initialized, overrides_of

# config groups a user does not choose: body_learner follows body and learner; paths and
# trials have one option each (their values are overridden key by key)
_INTERNAL_GROUPS = ("body_learner", "hydra", "paths", "trials")


def user_groups(overrides: list[str] = ()) -> dict[str, list[str]]:
    """group -> the options a user can choose (conf/ and the folders of hydra.searchpath among
    `overrides`): no internal group, no generated `<learner>_schema` a learner's file extends."""
    from hydra import compose as hydra_compose
    from hydra.core.global_hydra import GlobalHydra

    search = [o for o in overrides if o.startswith("hydra.searchpath=")]
    with initialized():  # the stages' configs: a checkout's conf/ or the installed package
        hydra_compose(config_name="config", overrides=search)
        loader = GlobalHydra.instance().config_loader()
        return {g: [o for o in sorted(loader.get_group_options(g)) if not o.endswith("_schema")]
                for g in sorted(loader.list_groups("")) if g not in _INTERNAL_GROUPS}


def help_text(stage: str, argv: list[str]) -> str:
    """What `--help` prints: the stage, the groups and their options a user can choose, and the
    config the command line composes to (Hydra's own help listed the internal schemas too)."""
    from omegaconf import OmegaConf

    overrides = overrides_of(argv)
    lines = [f"python -m {stage} [group=option ...] [key=value ...] [-m for a sweep]", "",
             "== Configuration groups (group=option) ==", ""]
    lines += [f"{g}: {', '.join(opts)}" for g, opts in user_groups(overrides).items()]
    lines += ["", "A body's learner settings (body_learner) follow body= and learner=; "
              "hydra.searchpath=[file:///abs/my_conf] adds your own folder of bodies.", "",
              "== Config (override any key: foo.bar=value) ==", ""]
    try:
        cfg = compose(overrides)
    except Exception:  # a bad override: the defaults (the stage itself names the problem)
        cfg = compose([])
    lines.append(OmegaConf.to_yaml(cfg).rstrip())
    lines += ["", "Hydra's own flags: --hydra-help"]
    return "\n".join(lines) + "\n"
