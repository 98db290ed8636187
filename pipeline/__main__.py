"""The `gbgrowth` command (= python -m pipeline): `gbgrowth simulate experiment=fig4` is
`python -m pipeline.simulate experiment=fig4`; also `gbgrowth models fig4`, `--version`."""
from __future__ import annotations

import importlib
import sys

from . import __version__

STAGES = {  # subcommand -> the module whose @hydra.main it runs
    "simulate": "pipeline.simulate",
    "aggregate": "pipeline.aggregate",
    "report": "pipeline.report",
    "rate": "pipeline.tools.rate",
    "body": "pipeline.tools.body",
    "bench": "pipeline.tools.bench",
}
USAGE = f"""usage: gbgrowth COMMAND [HYDRA OVERRIDES ...]

commands:
  simulate    run the trials of a config that are not cached (paths.cache)
  aggregate   the cache into curves and summaries per figure (paths.aggregate)
  report      figures, tables and report.md (paths.report)
  rate        rate a body's learning rate for Goal Babbling (body=NAME; --write: into its file)
  body        a body's chain, joints, limits, reach and a reachable target grid (body=NAME)
  bench       time the fast path against the numpy reference
  models      FIGURE|PATH [AGGREGATE_DIR]: the trained models of a figure, one line per condition
              (models seal FILE...: verify a report's models file against its curves, seal it)

  gbgrowth COMMAND --help    a command's help (its options, an example; --help-all: its config)
  gbgrowth --version

Outputs go under paths.root: the working directory outside a checkout (docs/install.md)."""


MODELS_HELP = """usage: gbgrowth models FIGURE|PATH [AGGREGATE_DIR]
       gbgrowth models seal FILE...

Lists the trained models of a figure (pipeline.models.load): one line per condition, with its
body, its trials, the body's size and the epochs it learned for.

  FIGURE|PATH     a figure's name (its aggregate, or a report's models/<figure>.json), or
                  the path of a models file or of a figure's aggregate folder
  AGGREGATE_DIR   look for FIGURE under this aggregate folder only
  seal FILE...    verify each report models file against the report's curves, then seal it

Example:
  gbgrowth models fig4"""


def models(args: list[str]) -> int:
    """`gbgrowth models` (MODELS_HELP); `models seal` is `python -m pipeline.models seal`."""
    from . import models as loader

    if args[:1] == ["seal"]:  # python -m pipeline.models seal FILE...
        return loader.main(args)
    if args[:1] in (["-h"], ["--help"]):
        print(MODELS_HELP)
        return 0
    if not args or len(args) > 2 or args[0].startswith("-"):
        print("usage: gbgrowth models FIGURE|PATH [AGGREGATE_DIR]", file=sys.stderr)
        return 2
    try:
        fig = loader.load(*args)
    except (FileNotFoundError, ValueError) as err:  # io.DamagedFile too
        print(f"error: {err}", file=sys.stderr)
        return 2
    print(f"{fig.name}: {len(fig)} condition(s)")
    for label, m in fig.items():
        print(f"  {label}: {m.body.name}, {len(m.M)} trial(s), size {m.size:g} at epoch "
              f"{m.spec.epochs}")
    return 0


def main(argv: list[str] | None = None) -> None:
    argv = list(sys.argv[1:] if argv is None else argv)
    if not argv or argv[0] in ("-h", "--help", "help"):
        print(USAGE)
        sys.exit(0 if argv else 2)
    command, rest = argv[0], argv[1:]
    if command in ("--version", "-V", "version"):
        print(f"gbgrowth {__version__}")
        sys.exit(0)
    if command == "models":
        sys.exit(models(rest))
    if command not in STAGES:
        print(f"error: {command!r} is not a command; choose one of "
              f"{', '.join([*STAGES, 'models'])} (gbgrowth --help)", file=sys.stderr)
        sys.exit(2)
    from . import cli

    module = importlib.import_module(STAGES[command])
    if hasattr(module, "take_flags"):  # a tool's own flags (rate --write), before Hydra's parser
        rest = module.take_flags(rest)
    sys.argv = [f"gbgrowth {command}", *rest]  # what Hydra and the stage read
    cli.main(module.main)


if __name__ == "__main__":
    main()
