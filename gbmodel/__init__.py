"""gbmodel: Goal Babbling on growing bodies (Rolf, Steil & Gienger 2010), the numerical core.

Pure functions and small classes over numpy arrays: no file I/O, no configuration system, no
printing. Every random draw comes from a numpy.random.Generator passed in.

    >>> import numpy as np, gbmodel
    >>> body = gbmodel.make_body("arm5")
    >>> spec = gbmodel.TrialSpec(body="arm5", epochs=200)
    >>> result = gbmodel.run_trial(spec, np.random.default_rng(0))
    >>> result.abs_error[-1] < result.abs_error[0]
    True
"""
from .bodies import BODIES, GROWTH_PATTERNS, Body, make_body
from .features import exponents, feature_bounds, features
from .learner import predict
from .trial import TrialResult, TrialSpec, eval_epochs, run_trial, size_schedule

__all__ = [
    "BODIES", "GROWTH_PATTERNS", "Body", "make_body", "exponents", "feature_bounds", "features",
    "predict", "TrialResult", "TrialSpec", "eval_epochs", "run_trial", "size_schedule",
]
