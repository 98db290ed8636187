"""How a body grows: its size factor epoch by epoch, and which segments carry the growth.

A schedule gives the size factor S(e) of epochs e = 1 ... E (1.0 = the full body); the pattern
turns S into per-joint length factors: proportional scales every segment, non-proportional only
the body's growing ones (both `Body.segment_scale`), proximal_first every segment, the proximal
ones ahead of the distal ones (`proximal_first_scale`). The target set scales with S (paper
sec. 3.1).

Schedules, with the growth progress u = (e - 1) / T_G clipped to [0, 1]:
- linear: S = start + (end - start) u (the paper's);
- infant: S = start + (end - start) (1 - exp(-k u)) / (1 - exp(-k)): fast early, then slowing,
  as infants grow (paper sec. 1: "very rapidly in the first few months before it slows down").
  k = INFANT_RATE is fitted to the WHO Child Growth Standards, length-for-age of boys, median:
  49.9 cm at birth, 75.7 cm at 12 months, 87.1 cm at 24 months. Read over 0 ... 24 months, the
  first half of that time brings f = (75.7 - 49.9) / (87.1 - 49.9) = 0.694 of the growth; the
  normalised curve's value at u = 1/2 is 1 / (1 + exp(-k/2)), so k = 2 ln(f / (1 - f)) = 1.63.
  It is a constant, not a field: "infant" names this one published shape, and a free rate would
  be a parameter without a source (k -> 0 is the linear schedule).
"""
from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from .bodies import Body

PATTERNS = ("proportional", "nonproportional", "proximal_first")
SCHEDULES = ("linear", "infant")

# WHO Child Growth Standards (2006), length-for-age, boys, median [cm]: birth, 12 and 24 months
WHO_LENGTH_CM = (49.9, 75.7, 87.1)
_HALF = (WHO_LENGTH_CM[1] - WHO_LENGTH_CM[0]) / (WHO_LENGTH_CM[2] - WHO_LENGTH_CM[0])
INFANT_RATE = 2.0 * np.log(_HALF / (1.0 - _HALF))  # k = 1.6336...


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


def progress(u, schedule: str = "linear"):
    """The fraction of the growth done, 0 ... 1, at growth progress u (0 ... 1) of a schedule."""
    u = np.clip(np.asarray(u, dtype=np.float64), 0.0, 1.0)
    if schedule == "linear":
        return u
    if schedule == "infant":
        return np.expm1(-INFANT_RATE * u) / np.expm1(-INFANT_RATE)
    raise ValueError(f"growth.schedule={schedule!r}: choose one of {list(SCHEDULES)}")


def proximal_first_scale(body: Body, sizes, start_size: float, end_size: float,
                         lead: float = 1.0) -> np.ndarray:
    """Per-joint length factors (..., m) when proximal segments grow ahead of distal ones.

    The upper arm grows faster than the forearm (paper sec. 1, after Wells et al. 2002). With
    the body's growth done to the fraction p = (S - start) / (end - start), segment i has done

        p_i = p + c_i p (1 - p),   c_i = lead (1 - 2 u_i) / max_j |1 - 2 u_j|,

    u_i in (0, 1) the position of its midpoint along the chain (in fractions of the total
    length): the proximal end has c > 0 and runs ahead, the distal end c < 0 and lags. Every p_i
    rises monotonically from 0 to 1 (|c_i| <= lead <= 1), so every segment starts at start_size
    and ends at end_size; and the length-weighted mean of the c_i is zero (the mean of u is 1/2),
    so the total length is S times the full one at every epoch, as with proportional growth.
    """
    sizes = np.asarray(sizes, dtype=np.float64)[..., None]
    seg = np.hypot(body.a, body.d)
    u = (np.cumsum(seg) - 0.5 * seg) / seg.sum()
    spread = np.where(seg > 0, 1.0 - 2.0 * u, 0.0)  # segments of no length carry no weight
    c = lead * spread / (np.abs(spread).max() or 1.0)
    if end_size == start_size:  # no growth: every segment at the one size
        return np.broadcast_to(sizes, sizes.shape[:-1] + (body.m,)).copy()
    p = (sizes - start_size) / (end_size - start_size)
    return start_size + (end_size - start_size) * (p + c * p * (1.0 - p))


@dataclass(frozen=True)
class Growth:
    """Size S from start_size (epoch 1) to end_size (epoch period + 1) along `schedule`, constant
    afterwards; period 0 is a body of constant size end_size (the paper's references).
    proximal_lead (0 ... 1) is how far proximal segments run ahead under proximal_first: the
    paper gives only the direction, not the amount, so the default is the most the pattern allows
    with every segment still growing monotonically (arm5 at half its growth: the segments, base
    to hand, have done 75, 62.5, 50, 37.5 and 25 % of theirs)."""

    pattern: str = "proportional"
    start_size: float = 0.5
    end_size: float = 1.0
    period: int = 0  # T_G [epochs]
    schedule: str = "linear"
    proximal_lead: float = 1.0
    # non-proportional growth holds the non-growing segments at this fraction of their length:
    # 1.0, the full-size arm is the common end body (our reading of Fig. 3c); 0.5, the half-size
    # arm (5 x 0.1 m) is the common start body and the end body is unequal (the other reading)
    fixed_scale: float = 1.0

    def validate(self, body: Body) -> "Growth":
        check_choice("growth.pattern", self.pattern, PATTERNS)
        check_choice("growth.schedule", self.schedule, SCHEDULES)
        check_int("growth.period", self.period, 0)
        check_number("growth.proximal_lead", self.proximal_lead, 0.0)
        check_number("growth.fixed_scale", self.fixed_scale, 0.0, strict=True)
        if self.proximal_lead > 1.0:
            raise SpecError("growth.proximal_lead", self.proximal_lead,
                            "must be <= 1 (beyond, distal segments would shrink for a while)")
        for name in ("start_size", "end_size"):
            check_number(f"growth.{name}", getattr(self, name), 0.0, strict=True)
            if self.pattern in ("proportional", "nonproportional"):
                try:
                    body.segment_scale(getattr(self, name), self.pattern, self.fixed_scale)
                except ValueError as err:
                    raise SpecError(f"growth.{name}", getattr(self, name), str(err)) from None
        if self.pattern == "nonproportional" and body.growing.all():
            raise SpecError("growth.pattern", self.pattern,
                            f"every segment of {body.name} grows, so non-proportional growth "
                            "would equal proportional growth; use growth=proportional")
        if self.pattern == "proximal_first" and np.count_nonzero(np.hypot(body.a, body.d)) < 2:
            raise SpecError("growth.pattern", self.pattern,
                            f"{body.name} has fewer than two segments of non-zero length")
        return self

    def sizes(self, epochs) -> np.ndarray:
        """Size factor of each epoch in `epochs` (1-based)."""
        e = np.asarray(epochs)
        if self.period == 0:
            return np.full(e.shape, float(self.end_size))
        done = progress((e - 1) / self.period, self.schedule)
        return self.start_size + (self.end_size - self.start_size) * done

    def scales(self, body: Body, sizes) -> np.ndarray:
        """Per-joint length factors (..., m) of the body at `sizes`."""
        if self.pattern == "proximal_first":
            return proximal_first_scale(body, sizes, self.start_size, self.end_size,
                                        self.proximal_lead)
        return body.segment_scale(sizes, self.pattern, self.fixed_scale)

    def to_dict(self) -> dict:
        return asdict(self)
