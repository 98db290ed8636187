"""What a trial's spec may hold: SpecError, the one error of a bad value (one line,
`<section>.<field>=<value>: why`, which the pipeline turns into its exit 2), and the limits
every part of the core checks its fields against, each once: a class's LIMITS table names every
field's Constraint, check_fields checks them in order, its validate() adds what relates fields.
"""
from __future__ import annotations

import numpy as np

MAX_EPOCHS = 10**9  # epochs of one trial: its memory does not grow with them, its time does
MAX_SIZE = 100.0  # a growth size factor (1 = the body's full size)
MAX_INT64 = 2**63 - 1  # growth periods are stored as int64 (the curve table's growth_period)
MAX_DEGREE = 6  # a learner's polynomial degree P: p = C(n + P, P) features, 84 for the iCub's n = 3


class SpecError(ValueError):
    def __init__(self, key: str, value, why: str):
        super().__init__(f"{key}={value!r}: {why}")
        self.key = key


def check_int(key, value, minimum):
    """value is an integer >= minimum, not a bool."""
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < minimum:
        raise SpecError(key, value, "must be a positive integer" if minimum == 1
                        else f"must be an integer >= {minimum}")


def check_epochs(key, value):
    Int(1, MAX_EPOCHS).check(key, value, f"at most {MAX_EPOCHS:.0e} epochs per trial")


def check_choice(key, value, options):
    if value not in options:
        raise SpecError(key, value, f"choose one of {list(options)}")


class Constraint:
    """What one field may hold; check() raises SpecError naming the key."""

    def ok(self, value) -> bool:
        try:
            self.check("x", value)
        except SpecError:
            return False
        return True


class Int(Constraint):
    """An integer (not a bool) in lo ... hi; `why` says what the upper bound protects."""

    def __init__(self, lo: int = 1, hi: int | None = None, why: str = ""):
        self.lo, self.hi, self.why = lo, hi, why

    def check(self, key, value, above=None):
        check_int(key, value, self.lo)
        if self.hi is not None and value > self.hi:
            raise SpecError(key, value, above or f"at most {self.hi:,}{self.why}")

    def describe(self) -> str:
        return f"an integer in [{self.lo:,}, {self.hi:,}]{self.why}"


class Number(Constraint):
    """A finite number (not a bool) >= lo (> lo with lo_open) and <= hi."""

    def __init__(self, lo: float | None = None, hi: float | None = None, lo_open: bool = False,
                 why: str = ""):
        self.lo, self.hi, self.lo_open, self.why = lo, hi, lo_open, why

    def check(self, key, value):
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not np.isfinite(value):
            raise SpecError(key, value, "must be a finite number")
        lo = self.lo
        if lo is not None and (value <= lo if self.lo_open else value < lo):
            raise SpecError(key, value, f"must be {'>' if self.lo_open else '>='} {lo:g}")
        if self.hi is not None and value > self.hi:
            raise SpecError(key, value, f"must be <= {self.hi:g}{self.why}")

    def describe(self) -> str:
        return f"a number in {'(' if self.lo_open else '['}{self.lo:g}, {self.hi:g}]{self.why}"


class Choice(Constraint):
    def __init__(self, *options):
        self.options = options

    def check(self, key, value):
        check_choice(key, value, self.options)


class Flag(Constraint):
    def check(self, key, value):
        if not isinstance(value, bool):
            raise SpecError(key, value, "must be true or false")


class Maybe(Constraint):
    """None, or what `inner` allows."""

    def __init__(self, inner: Constraint):
        self.inner = inner

    def check(self, key, value):
        if value is not None:
            self.inner.check(key, value)


class Text(Constraint):
    def check(self, key, value):
        if not isinstance(value, str) or not value:
            raise SpecError(key, value, "must be a non-empty string")


class Record(Constraint):
    """A mapping of exactly these fields, each a non-empty string (a body's credits)."""

    def __init__(self, *names):
        self.names = names

    def check(self, key, value):
        if (not isinstance(value, dict) or set(value) != set(self.names)
                or not all(isinstance(v, str) and v for v in value.values())):
            raise SpecError(key, value, f"needs {list(self.names)}, each a non-empty string")


class Members(Constraint):
    """A non-empty list of distinct values out of `options` (a body's controlled coordinates)."""

    def __init__(self, *options, what: str):
        self.options, self.what = options, what

    def check(self, key, value):
        if (not isinstance(value, (list, tuple)) or not value or len(set(value)) != len(value)
                or any(isinstance(k, bool) or k not in self.options for k in value)):
            raise SpecError(key, value, f"a list of distinct {self.what} out of "
                            + ", ".join(map(str, self.options)))


class Free(Constraint):
    """A field the class's validate() checks against other fields (named, so every field is in
    the table)."""

    def __init__(self, why: str):
        self.why = why

    def check(self, key, value):
        pass


def check_fields(obj, section: str, limits: dict) -> None:
    """Check every field of `obj` against its constraint in `limits`, in the table's order."""
    for name, constraint in limits.items():
        constraint.check(f"{section}.{name}", getattr(obj, name))
