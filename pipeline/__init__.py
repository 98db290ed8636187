"""The pipeline around gbmodel: simulate -> aggregate -> report, configured by Hydra (conf/).

Importing the package registers the config schema (pipeline.config) with Hydra's ConfigStore.
"""
from . import config  # noqa: F401  (registers the schema)
