"""The skew diagnostic of the scorecard's intervals (pipeline.studies.coverage): their coverage on
samples resampled from each measure's own values, written to pipeline/studies/coverage.csv (the
scorecard reads it) and printed; docs/scorecard.md shows it as the named value coverage.table.

    python -m pipeline.tools.coverage REPORT_DIR [--trials 3 5 10 20] [--draws 4000]
        [--out pipeline/studies/coverage.csv]
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

from .. import io
from ..studies.coverage import COUNTS, DRAWS, FIT, TABLE, markdown, per_trial_values, table, to_csv
from . import fail


def main(argv=None) -> int:
    p = argparse.ArgumentParser(prog="python -m pipeline.tools.coverage",
                                description=__doc__.split("\n\n")[0])
    p.add_argument("report", type=Path, help="a report folder (measures.parquet or scorecard.csv)")
    p.add_argument("--trials", type=int, nargs="+", default=list(COUNTS))
    p.add_argument("--draws", type=int, default=DRAWS)
    p.add_argument("--out", type=Path, default=TABLE)
    a = p.parse_args(argv)
    if not ((a.report / "scorecard.csv").exists() or (a.report / "measures.parquet").exists()):
        return fail(f"{a.report}: no measures.parquet or scorecard.csv")
    t = table(per_trial_values(a.report), a.trials, a.draws)
    if not len(t):
        return fail(f"{a.report}: no measure has {FIT} trials")
    io.write_text(a.out, to_csv(t))
    print(markdown(t))
    return 0


if __name__ == "__main__":
    sys.exit(main())
