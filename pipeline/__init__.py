"""The pipeline around gbmodel: simulate -> aggregate -> report, configured by Hydra (conf/).

Importing the package registers the config schema (pipeline.config) with Hydra's ConfigStore.
"""
import sys

from . import stop

if sys.argv[:1] == ["-m"]:  # `python -m pipeline.<stage>` (argv[0] is "-m" while it is located)
    stop.install()  # a signal during the slow imports: one line, not a traceback (pipeline.stop)

from . import config  # noqa: E402,F401  (registers the schema)
