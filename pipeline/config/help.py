"""What a stage's `--help` prints (`--help-all`: with the whole config it composes to)."""
from __future__ import annotations

import textwrap

from .compose import compose, initialized, overrides_of

# config groups a user does not choose: body_learner follows body and learner; paths and
# trials have one option each (their values are overridden key by key)
_INTERNAL_GROUPS = ("body_learner", "hydra", "paths", "trials")

_RUN = ("profile=smoke", "2 trials of 1,000 epochs, in outputs/smoke/")
_SEARCH = ("hydra.searchpath=[file:///DIR]", "a folder of your own bodies and experiments")
# stage -> (what it does, its main options: (option, what it does), one example)
STAGES = {
    "pipeline.simulate": (
        "Runs every trial of the config that is not cached yet (paths.cache), longest first; "
        "an interrupted run resumes where it stopped.",
        [("experiment=NAME", "a figure's conditions (the experiment group below)"),
         ("figure=NAME", "name this run's trials: its aggregate and report folder"), _RUN,
         ("body= growth= learner=", "the body, its growth pattern, the learner (groups below)"),
         ("learner.epochs=N trials.count=N", "epochs per trial, trials per condition"),
         ("growth.period=N", "T_G: the epochs over which the body grows"),
         ("workers=N", "worker processes (default 2)"),
         ("engine=NAME", "where trials run: local, ray, slurm, submitit_local"),
         ("-m KEY=A,B", "a sweep: a job per value, one figure (its estimate first)"),
         ("'experiments=[fig2,fig4]'", "several experiments in one process"), _SEARCH],
        "python -m pipeline.simulate -m learner.radius=0.1,0.2 growth.period=100,1000 "
        "figure=grid"),
    "pipeline.aggregate": (
        "Turns the cache into each figure's learning curves, summary and trained models "
        "(paths.aggregate/<figure>/); a figure whose trials did not change is left as it is.",
        [("figure=NAME", "one figure (default: every figure in the cache)"),
         ("experiment=NAME", "the figure of an experiment"), _RUN,
         ("aggregate.fail_factor=F", "a trial failed when its final error is > F x the median"),
         ("paths.root=DIR", "where outputs/ lies (default: the checkout or the working folder)")],
        "python -m pipeline.aggregate figure=grid"),
    "pipeline.report": (
        "Draws the figures and tables of the aggregated figures and ties them together in "
        "report.md (paths.report); runs no trial.",
        [("figure=NAME", "one figure's report, in outputs/latest/NAME/"),
         ("experiment=NAME", "the figure of an experiment"), _RUN,
         ("report.title=TEXT", "the learning curves' title line"),
         ("report.error_unit=mm", "errors in millimetres (default m)"),
         ("report.log_error_axis=false", "a linear error axis (default log)"),
         ("report.log_epoch_axis=false", "a linear epoch axis (default log)"),
         ("report.dpi=N", "the figures' resolution"), ("report.animate=false", "no GIFs")],
        "python -m pipeline.report figure=grid report.error_unit=mm"),
    "pipeline.tools.rate": (
        "Rates a body's plain-step learning rate for Goal Babbling (eta = 1 / W) and prints the "
        "body's learner settings file.",
        [("body=NAME", "the body"), ("learner.KEY=VALUE", "at other V, K, L, R or solver"),
         ("--write", "write the file itself: body_learner/<body>_goal_babbling.yaml"),
         _SEARCH],
        "python -m pipeline.tools.rate body=icub --write"),
    "pipeline.tools.body": (
        "Prints a body's chain, joints, limits and reach, whether its target grid is reachable, "
        "and a grid that is; writes nothing.",
        [("body=NAME", "the body"), _SEARCH,
         ("figure=NAME --within PCT", "after a run: each trial's held-out error against PCT % "
          "of the reach; the trials above it named (exit 1)")],
        "python -m pipeline.tools.body body=arm5"),
    "pipeline.tools.bench": (
        "Times whole trials of the compiled kernel against the numpy reference (make bench) "
        "into paths.bench/bench.json.",
        [("bench.repeats=N", "timed trials per body and path (default 5)"),
         ("bench.parallel=false", "skip the timing on 1 and 2 workers"),
         ("compare DIR", "[ROUNDS] [REPEATS] [LEARNER]: against the checkout in DIR"),
         ("costs", "every learner's CPU time per sample against Goal Babbling's")],
        "python -m pipeline.tools.bench bench.repeats=3"),
}


def user_groups(overrides: list[str] = ()) -> dict[str, list[str]]:
    """group -> the options a user can choose (no internal group, no generated schema)."""
    from hydra import compose as hydra_compose
    from hydra.core.global_hydra import GlobalHydra

    search = [o for o in overrides if o.startswith("hydra.searchpath=")]
    with initialized():  # the stages' configs: a checkout's conf/ or the installed package
        hydra_compose(config_name="config", overrides=search)
        loader = GlobalHydra.instance().config_loader()
        return {g: [o for o in sorted(loader.get_group_options(g)) if not o.endswith("_schema")]
                for g in sorted(loader.list_groups("")) if g not in _INTERNAL_GROUPS}


def _wrapped(text: str, indent: str = "") -> list[str]:
    return textwrap.wrap(text, 99, subsequent_indent=indent, break_on_hyphens=False)


def help_text(stage: str, argv: list[str]) -> str:
    overrides = overrides_of(argv)
    what, options, example = STAGES.get(stage, ("", [], f"python -m {stage}"))
    sweep = " [-m for a sweep]" if stage.count(".") == 1 else ""  # a stage's, not a tool's
    lines = [f"usage: python -m {stage} [group=option ...] [key=value ...]{sweep}"]
    lines += ["", *_wrapped(what)] if what else []
    if options:
        width = max(len(o) for o, _ in options)
        lines += ["", "Main options:"] + [f"  {o:<{width}}  {d}" for o, d in options]
    lines += ["", "Example:", f"  {example}", "", "== Configuration groups (group=option) ==", ""]
    for g, opts in user_groups(overrides).items():
        lines += _wrapped(f"{g}: {', '.join(opts)}", "    ")
    lines += ["", "A body's learner settings (body_learner) follow body= and learner=.", ""]
    if "--help-all" not in argv:
        lines += _wrapped(f"Every config key and its value: --help-all; this command line's "
                          f"config: python -m {stage} ... --cfg job; Hydra's own flags: "
                          "--hydra-help")
        return "\n".join(lines) + "\n"
    from omegaconf import OmegaConf

    lines += ["== Config (override any key: foo.bar=value) ==", ""]
    try:
        cfg = compose(overrides)
    except Exception:  # a bad override: the defaults (the stage itself names the problem)
        cfg = compose([])
    lines.append(OmegaConf.to_yaml(cfg).rstrip())
    lines += ["", "Hydra's own flags: --hydra-help"]
    return "\n".join(lines) + "\n"
