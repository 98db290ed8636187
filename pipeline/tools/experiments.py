"""The experiments of the project's runs, from what each experiment file declares
(conf/experiment/*.yaml: declares.group, declares.order; pipeline.experiments).

    python -m pipeline.tools.experiments paper choices   # fig2 fig4 ... choices_icub
    python -m pipeline.tools.experiments --make          # paper:fig2 ... studies:baselines_icub

GROUP...: the experiments of these groups (paper, choices, explain, studies), in their order;
--make: every experiment that declares a group, as group:name. The Makefile reads its lists
(PAPER, CHOICES, EXPLAIN, STUDIES) from `--make`, once per make.
"""
from __future__ import annotations

import sys

from ..experiments import GROUPS, config_folders, declared, listed
from . import fail


def main(argv=None) -> int:
    args = list(sys.argv[1:] if argv is None else argv)
    if args[:1] in (["-h"], ["--help"]):
        print(__doc__.rstrip())
        return 0
    try:
        if args == ["--make"]:
            found = declared(config_folders())
            print(" ".join(f"{e.declares.group}:{n}" for n, e in found.items() if e.declares.group))
            return 0
        bad = [a for a in args if a not in GROUPS]
        if bad:
            return fail(f"{bad[0]}: choose groups of {', '.join(GROUPS)}, or --make")
        print(" ".join(listed(config_folders(), *args)))
    except (OSError, ValueError) as err:
        return fail(f"{err}".partition("\n")[0])
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
