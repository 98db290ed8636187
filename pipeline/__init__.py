"""The pipeline around gbmodel: simulate -> aggregate -> report, configured by Hydra (conf/).
Importing it loads nothing heavy (tests/pipeline/test_imports.py)."""
import os
import sys

__version__ = "0.1.0"  # the distribution's version (pyproject.toml reads it; CITATION.cff names it)

from . import stop

if sys.argv[:1] == ["-m"]:  # `python -m pipeline.<stage>` (argv[0] is "-m" while it is located)
    stop.install()  # a signal during the slow imports: one line, not a traceback (pipeline.stop)


def _runs_the_report(orig_argv: list, argv: list) -> bool:
    """python -m pipeline.report, python -m pipeline report, gbgrowth report."""
    if "-m" in orig_argv[:-1]:
        i = orig_argv.index("-m") + 1
        return orig_argv[i] == "pipeline.report" or orig_argv[i:i + 2] == ["pipeline", "report"]
    return os.path.basename(argv[0] if argv else "") == "gbgrowth" and argv[1:2] == ["report"]


if _runs_the_report(getattr(sys, "orig_argv", []), sys.argv):
    # the report's least squares are small: a second BLAS thread only spins (up to 35x the
    # CPU on a loaded machine); set before numpy loads, a user's own setting wins
    for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS",
                 "VECLIB_MAXIMUM_THREADS"):
        os.environ.setdefault(_var, "1")
