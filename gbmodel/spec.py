"""What a trial's spec may hold: the one error type of a bad value, the checks every part of the
core (bodies, growth, learners, the trial) runs on its fields, and the limits they enforce.

A check raises SpecError with a one-line message `<section>.<field>=<value>: why`; the pipeline
turns it into its configuration error (exit 2) without a traceback.
"""
from __future__ import annotations

import numpy as np

MAX_EPOCHS = 10**9  # epochs of one trial: its memory does not grow with them, its time does


class SpecError(ValueError):
    """A bad value of a trial's spec; the message is one line, `<section>.<field>=<value>: why`."""

    def __init__(self, key: str, value, why: str):
        super().__init__(f"{key}={value!r}: {why}")
        self.key = key


def check_int(key, value, minimum):
    """value is an integer >= minimum, not a bool."""
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < minimum:
        raise SpecError(key, value, "must be a positive integer" if minimum == 1
                        else f"must be an integer >= {minimum}")


def check_epochs(key, value):
    """value is a whole number of epochs, 1 ... MAX_EPOCHS."""
    check_int(key, value, 1)
    if value > MAX_EPOCHS:
        raise SpecError(key, value, f"at most {MAX_EPOCHS:.0e} epochs per trial")


def check_number(key, value, minimum=None, strict=False):
    """value is a finite number (not a bool), >= minimum (> with strict) when given."""
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not np.isfinite(value):
        raise SpecError(key, value, "must be a finite number")
    if minimum is not None and (value <= minimum if strict else value < minimum):
        raise SpecError(key, value, f"must be {'>' if strict else '>='} {minimum:g}")


def check_choice(key, value, options):
    """value is one of options."""
    if value not in options:
        raise SpecError(key, value, f"choose one of {list(options)}")
