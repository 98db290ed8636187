"""gbmodel: Goal Babbling on growing bodies (Rolf, Steil & Gienger 2010), the numerical core.

Pure functions and small classes over numpy arrays: no file I/O, no configuration system, no
printing. Every random draw comes from a numpy.random.Generator passed in.

    >>> import numpy as np, gbmodel
    >>> spec = gbmodel.TrialSpec(body={"name": "arm5"}, epochs=200)
    >>> result = gbmodel.run_trial(spec, np.random.default_rng(0))
    >>> bool(result.abs_error[-1] < result.abs_error[0])
    True
"""
from . import learners
from .bodies import Body, make_body, shipped
from .body_loop import body_factory

BODIES = shipped()  # the names of the shipped bodies (conf/body/*.yaml)
from .evaluation import eval_epochs
from .features import exponents, feature_bounds, features
from .growth import PATTERNS as GROWTH_PATTERNS, Growth
from .spec import SpecError
from .inverse import predict
from .trial import Checkpoint, Diverged, TrialResult, TrialSpec, run_trial

__all__ = [
    "BODIES", "GROWTH_PATTERNS", "Body", "Checkpoint", "Diverged", "Growth", "SpecError",
    "TrialResult", "TrialSpec", "body_factory", "eval_epochs", "exponents", "feature_bounds",
    "features", "learners", "make_body", "predict", "run_trial",
]
