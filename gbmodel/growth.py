"""How a body grows: its size factor epoch by epoch, and which segments carry the growth.

A schedule gives the size factor S(e) of epochs e = 1 ... E (1.0 = the full body); the pattern
turns S into per-joint length factors through one mechanism, `segment_factors`: per segment,
whether it grows (the body's `grows`) and its lead c_i, how far its growth runs ahead of (c > 0)
or behind (c < 0) the body's. Every pattern is data for it: proportional (every segment grows,
no lead), non-proportional (only the body's growing segments, no lead), proximal_first (every
segment, leads falling from base to hand) and per_segment (leads stated in the config,
`growth.leads`: "the upper arm grows faster than the forearm" at stated rates). The target set
scales with S (paper sec. 3.1).

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
from typing import Optional

import numpy as np

from .spec import SpecError, check_choice, check_int, check_number

PATTERNS = ("proportional", "nonproportional", "proximal_first", "per_segment")
SCHEDULES = ("linear", "infant")

# WHO Child Growth Standards (2006), length-for-age, boys, median [cm]: birth, 12 and 24 months
WHO_LENGTH_CM = (49.9, 75.7, 87.1)
_HALF = (WHO_LENGTH_CM[1] - WHO_LENGTH_CM[0]) / (WHO_LENGTH_CM[2] - WHO_LENGTH_CM[0])
INFANT_RATE = 2.0 * np.log(_HALF / (1.0 - _HALF))  # k = 1.6336...


def progress(u, schedule: str = "linear"):
    """The fraction of the growth done, 0 ... 1, at growth progress u (0 ... 1) of a schedule."""
    u = np.clip(np.asarray(u, dtype=np.float64), 0.0, 1.0)
    if schedule == "linear":
        return u
    if schedule == "infant":
        return np.expm1(-INFANT_RATE * u) / np.expm1(-INFANT_RATE)
    raise ValueError(f"growth.schedule={schedule!r}: choose one of {list(SCHEDULES)}")


def segment_factors(seg, grows, leads, sizes, start_size: float = 0.5, end_size: float = 1.0,
                    fixed: float = 1.0) -> np.ndarray:
    """Per-joint length factors (..., m) at body sizes `sizes`: the one growth mechanism.

    seg (m,): the segments' full lengths; grows (m,) bool: which segments grow; leads (m,): each
    growing segment's lead c_i. With the body's growth done to the fraction
    p = (S - start) / (end - start), segment i has done p_i = p + c_i p (1 - p) of its own, so
    |c_i| <= 1 keeps every segment growing monotonically from start_size to end_size, and a
    length-weighted mean of zero keeps the total length S times the full one (proximal_first).
    Segments that do not grow stay at `fixed` times their full length and the growing ones change
    by the common factor that makes the total length S times the full one (non-proportional
    growth, sec. 3.2; `fixed` 1.0: the full-size body is the common end of every size, 0.5: the
    half-size body is the common start). Leads and held segments together are refused.
    """
    sizes = np.asarray(sizes, dtype=np.float64)[..., None]
    seg, grows = np.asarray(seg, np.float64), np.asarray(grows, bool)
    leads = np.asarray(leads, np.float64)
    if not grows.all():
        if np.any(leads):
            raise ValueError("segment leads need every segment growing")
        grow, held = seg[grows].sum(), fixed * seg[~grows].sum()
        if grow <= 0:
            raise ValueError("the body has no growing segment of non-zero length")
        gamma = (sizes * seg.sum() - held) / grow
        if np.any(gamma <= 0):
            raise ValueError(
                f"size {sizes.min()} is too small for non-proportional growth: the fixed "
                f"segments alone are {held / seg.sum():.2f} of the full length")
        return np.where(grows, gamma, fixed)
    if not np.any(leads) or end_size == start_size:  # every segment at the one size S
        return np.broadcast_to(sizes, sizes.shape[:-1] + (len(seg),)).copy()
    p = (sizes - start_size) / (end_size - start_size)
    return start_size + (end_size - start_size) * (p + leads * p * (1.0 - p))


def proximal_leads(seg, lead: float = 1.0) -> np.ndarray:
    """The leads of proximal_first: the upper arm grows faster than the forearm (paper sec. 1,
    after Wells et al. 2002). c_i = lead (1 - 2 u_i) / max_j |1 - 2 u_j|, u_i in (0, 1) the
    position of segment i's midpoint along the chain (in fractions of the total length): the
    proximal end has c > 0 and runs ahead, the distal end c < 0 and lags; the length-weighted
    mean of the c_i is zero (the mean of u is 1/2), so the total length is S times the full one
    at every epoch, as with proportional growth."""
    seg = np.asarray(seg, np.float64)
    u = (np.cumsum(seg) - 0.5 * seg) / seg.sum()
    spread = np.where(seg > 0, 1.0 - 2.0 * u, 0.0)  # segments of no length carry no weight
    return lead * spread / (np.abs(spread).max() or 1.0)


def proximal_first_scale(body, sizes, start_size: float, end_size: float,
                         lead: float = 1.0) -> np.ndarray:
    """Per-joint length factors (..., m) when proximal segments grow ahead of distal ones."""
    seg = body.segment_lengths
    return segment_factors(seg, np.ones(body.m, bool), proximal_leads(seg, lead), sizes,
                           start_size, end_size)


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
    # per_segment: each segment's lead c_i (-1 ... 1; segment_factors), base to hand, e.g.
    # [0.5, 0.25, 0, -0.25, -0.5]: the upper arm grows ahead of the forearm
    leads: Optional[list[float]] = None

    def validate(self, body) -> "Growth":
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
                    self.scales(body, getattr(self, name))
                except ValueError as err:
                    raise SpecError(f"growth.{name}", getattr(self, name),
                                    f"body {body.name!r}: {err}") from None
        if self.pattern == "nonproportional" and body.growing.all():
            raise SpecError("growth.pattern", self.pattern,
                            f"every segment of {body.name} grows, so non-proportional growth "
                            "would equal proportional growth; use growth=proportional")
        if self.pattern == "per_segment":
            c = self.leads
            if (not isinstance(c, (list, tuple)) or len(c) != body.m
                    or not all(isinstance(x, (int, float)) and not isinstance(x, bool)
                               and np.isfinite(x) and abs(x) <= 1 for x in c)):
                raise SpecError("growth.leads", c, f"per_segment growth needs {body.m} leads "
                                "in -1 ... 1, one per segment of " + body.name)
        elif self.leads is not None:
            raise SpecError("growth.leads", self.leads, "only growth=per_segment uses leads")
        if self.pattern == "proximal_first" and np.count_nonzero(body.segment_lengths) < 2:
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

    def segments(self, body) -> tuple[np.ndarray, np.ndarray]:
        """(grows, leads) per segment of `body`: the pattern as data for segment_factors."""
        seg, every = body.segment_lengths, np.ones(body.m, bool)
        if self.pattern == "nonproportional":
            return body.growing, np.zeros(body.m)
        if self.pattern == "proximal_first":
            return every, proximal_leads(seg, self.proximal_lead)
        if self.pattern == "per_segment":
            return every, np.asarray(self.leads, np.float64)
        return every, np.zeros(body.m)

    def scales(self, body, sizes) -> np.ndarray:
        """Per-joint length factors (..., m) of the body at `sizes` (any slice of epochs)."""
        grows, leads = self.segments(body)
        return segment_factors(body.segment_lengths, grows, leads, sizes, self.start_size,
                               self.end_size, self.fixed_scale)

    def to_dict(self) -> dict:
        return asdict(self)


def factors(body, size, pattern="proportional") -> np.ndarray:
    """Per-segment length factors (..., m) of `body` at size `size` (scalar or array) grown by
    `pattern`: a Growth, or a pattern's name with its default settings. The one place where a
    growth pattern becomes the factors Body.forward, Body.chain and Body.frame_points take."""
    growth = pattern if isinstance(pattern, Growth) else Growth(pattern=pattern)
    check_choice("growth.pattern", growth.pattern, PATTERNS)
    try:
        return growth.scales(body, size)
    except ValueError as err:
        raise ValueError(f"body {body.name!r}: {err}") from None
