"""How a body grows: its size factor epoch by epoch, and which segments carry the growth.

A schedule gives the size factor S(e) of epochs e = 1 ... E (1.0 = the full body); the pattern
turns S into per-joint length factors (`Body.segment_scale`): proportional scales every segment,
non-proportional only the body's growing ones. The target set scales with S (paper sec. 3.1).
"""
from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from .bodies import Body

PATTERNS = ("proportional", "nonproportional")
SCHEDULES = ("linear",)


class SpecError(ValueError):
    """A bad value of a trial's spec; the message is one line, `<section>.<field>=<value>: why`."""

    def __init__(self, key: str, value, why: str):
        super().__init__(f"{key}={value!r}: {why}")
        self.key = key


def check_int(key, value, minimum):
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < minimum:
        raise SpecError(key, value, "must be a positive integer" if minimum == 1
                        else f"must be an integer >= {minimum}")


def check_number(key, value, minimum=None, strict=False):
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not np.isfinite(value):
        raise SpecError(key, value, "must be a finite number")
    if minimum is not None and (value <= minimum if strict else value < minimum):
        raise SpecError(key, value, f"must be {'>' if strict else '>='} {minimum:g}")


def check_choice(key, value, options):
    if value not in options:
        raise SpecError(key, value, f"choose one of {list(options)}")


@dataclass(frozen=True)
class Growth:
    """Size S from start_size (epoch 1) to end_size (epoch period + 1), constant afterwards;
    period 0 is a body of constant size end_size (the paper's references)."""

    pattern: str = "proportional"
    start_size: float = 0.5
    end_size: float = 1.0
    period: int = 0  # T_G [epochs]
    schedule: str = "linear"

    def validate(self, body: Body) -> "Growth":
        check_choice("growth.pattern", self.pattern, PATTERNS)
        check_choice("growth.schedule", self.schedule, SCHEDULES)
        check_int("growth.period", self.period, 0)
        for name in ("start_size", "end_size"):
            check_number(f"growth.{name}", getattr(self, name), 0.0, strict=True)
            try:
                body.segment_scale(getattr(self, name), self.pattern)
            except ValueError as err:
                raise SpecError(f"growth.{name}", getattr(self, name), str(err)) from None
        if self.pattern == "nonproportional" and body.growing.all():
            raise SpecError("growth.pattern", self.pattern,
                            f"every segment of {body.name} grows, so non-proportional growth "
                            "would equal proportional growth; use growth=proportional")
        return self

    def sizes(self, epochs) -> np.ndarray:
        """Size factor of each epoch in `epochs` (1-based)."""
        e = np.asarray(epochs)
        if self.period == 0:
            return np.full(e.shape, float(self.end_size))
        frac = np.clip((e - 1) / self.period, 0.0, 1.0)
        return self.start_size + (self.end_size - self.start_size) * frac

    def scales(self, body: Body, sizes) -> np.ndarray:
        """Per-joint length factors (..., m) of the body at `sizes`."""
        return body.segment_scale(sizes, self.pattern)

    def to_dict(self) -> dict:
        return asdict(self)
