"""How a body grows (docs/bodies.md, "Growth of a body"): a schedule gives the size factor S(e)
(1.0 = the full body; the targets scale with it, paper sec. 3.1), a pattern (a row of
PATTERN_TABLE) turns S into per-joint length factors by `segment_factors` or `rate_factors`.

Schedules, with u = (e - 1) / T_G clipped to [0, 1]: linear, S = start + (end - start) u (the
paper's); infant, (1 - exp(-k u)) / (1 - exp(-k)) in place of u, k = INFANT_RATE fitted to the
WHO length-for-age of boys (median, 0 ... 24 months: the first half brings f = 0.694 of the
growth, so k = 2 ln(f / (1 - f)) = 1.63, not a free parameter); table, measured sizes, rows
[t, size] or [t, f_1, ..., f_m], linear in time (two rows: the linear schedule to the bit), a
per-segment table's rows linear in the body size (their length-weighted mean) too.
"""
from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Any, Callable, Optional

import numpy as np

from .spec import (MAX_INT64, MAX_SIZE, Choice, Free, Int, Number, SpecError, check_choice,
                   check_fields)

SCHEDULES = ("linear", "infant", "table")
MAX_TABLE_ROWS = 10_000
MAX_TABLE_TIME = 1e12  # |t| of a growth table's rows: their differences stay exact enough

# WHO Child Growth Standards (2006), length-for-age, boys, median [cm]: birth, 12 and 24 months
WHO_LENGTH_CM = (49.9, 75.7, 87.1)
# k = 2 ln(f / (1 - f)), written out: numpy's log may round a last bit differently on another CPU
INFANT_RATE = 1.6335222730542454  # tests/core/test_growth.py checks it against the formula


def _expm1(x):
    """exp(x) - 1 for |x| <= 2 from + - * / alone, the same on every CPU (numpy's expm1 differs
    in a last bit between AVX-512 and AVX2): Taylor of exp(x / 16) - 1 to the 14th power, then
    4 doublings e(2y) = e(y) (e(y) + 2); within a few ulp."""
    y = np.asarray(x, dtype=np.float64) / 16.0
    p = np.ones_like(y)
    for k in range(14, 1, -1):
        p = 1.0 + y * p / k
    e = y * p
    for _ in range(4):
        e = e * (e + 2.0)
    return e


def progress(u, schedule: str = "linear"):
    u = np.clip(np.asarray(u, dtype=np.float64), 0.0, 1.0)
    if schedule == "linear":
        return u
    if schedule == "infant":
        return _expm1(-INFANT_RATE * u) / _expm1(-INFANT_RATE)
    if schedule == "table":
        raise ValueError("growth.schedule='table': the sizes come from growth.table "
                         "(Growth.sizes), not from a progress curve")
    raise ValueError(f"growth.schedule={schedule!r}: choose one of {list(SCHEDULES)}")


def segment_factors(seg, grows, leads, sizes, start_size: float = 0.5, end_size: float = 1.0,
                    fixed: float = 1.0) -> np.ndarray:
    """Per-joint length factors (..., m) at body sizes `sizes`: the one growth mechanism. With
    growth done to p = (S - start) / (end - start), segment i (lead c_i) has done p + c_i p (1 -
    p) of its own (|c_i| <= 1: monotonic; a length-weighted mean of 0 keeps the total S times
    the full). Segments that do not grow (`grows` false) stay at `fixed` times their length, the
    others share the factor that keeps the total (sec. 3.2); not together with leads."""
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
    """proximal_first's leads (paper sec. 1, after Wells et al. 2002): c_i = lead (1 - 2 u_i) /
    max_j |1 - 2 u_j|, u_i segment i's midpoint along the chain; length-weighted mean 0."""
    seg = np.asarray(seg, np.float64)
    u = (np.cumsum(seg) - 0.5 * seg) / seg.sum()
    spread = np.where(seg > 0, 1.0 - 2.0 * u, 0.0)  # segments of no length carry no weight
    return lead * spread / (np.abs(spread).max() or 1.0)


def check_table(table, m: int) -> tuple[np.ndarray, np.ndarray]:
    """(times (n,), sizes (n, k)) of a growth table, k = 1 (the body) or m; else SpecError."""
    key = "growth.table"
    if (not isinstance(table, (list, tuple)) or len(table) < 2
            or not all(isinstance(r, (list, tuple)) for r in table)):
        raise SpecError(key, table, "needs at least two rows [t, size] or [t, f_1, ..., f_m]")
    widths = {len(r) for r in table}
    if len(widths) != 1 or widths.pop() not in (2, m + 1):
        raise SpecError(key, table, f"every row must be [t, size] or [t, f_1, ..., f_{m}] "
                        f"({m} segment factors)")
    if len(table) > MAX_TABLE_ROWS:
        raise SpecError(key, f"<{len(table):,} rows>", f"at most {MAX_TABLE_ROWS:,} rows")
    if not all(Number().ok(x) for r in table for x in r):
        raise SpecError(key, table, "every entry must be a finite number")
    arr = np.asarray(table, np.float64)
    if np.any(np.abs(arr[:, 0]) > MAX_TABLE_TIME):
        raise SpecError(key, table, f"times within +-{MAX_TABLE_TIME:g} (any unit; their span "
                        "is mapped onto the growth period)")
    if np.any(arr[:, 1:] > MAX_SIZE):
        raise SpecError(key, table, f"sizes must be <= {MAX_SIZE:g} (the size factors' limit)")
    bad = np.flatnonzero(np.diff(arr[:, 0]) <= 0)
    if bad.size:
        raise SpecError(key, table, f"the times must rise strictly (row {bad[0] + 1}: "
                        f"{arr[bad[0], 0]:g}, then {arr[bad[0] + 1, 0]:g})")
    if np.any(arr[:, 1:] <= 0):
        raise SpecError(key, table, "sizes must be > 0")
    return arr[:, 0], arr[:, 1:]


def interpolate(x, xs, ys) -> np.ndarray:
    """Piecewise-linear ys (n, k) over rising xs at x: y_j + (y_j+1 - y_j) ((x - x_j) / (x_j+1 -
    x_j)), the end rows beyond the ends."""
    x = np.asarray(x, np.float64)
    j = np.clip(np.searchsorted(xs, x, side="right") - 1, 0, len(xs) - 2)
    w = np.clip((x - xs[j]) / (xs[j + 1] - xs[j]), 0.0, 1.0)[..., None]
    return ys[j] + (ys[j + 1] - ys[j]) * w


def table_body_sizes(sizes: np.ndarray, seg) -> np.ndarray:
    """The body size of each table row: its size, or its factors' length-weighted mean."""
    if sizes.shape[1] == 1:
        return sizes[:, 0]
    seg = np.asarray(seg, np.float64)
    return sizes @ seg / seg.sum()


def table_factors(seg, table, sizes) -> np.ndarray:
    """A per-segment table's factors at body sizes `sizes` (ValueError outside its range)."""
    _, f = check_table(table, len(seg))
    body = table_body_sizes(f, seg)
    order = np.argsort(body)
    s = np.asarray(sizes, np.float64)
    lo, hi = body[order[0]], body[order[-1]]
    if np.any(s < lo - 1e-12) or np.any(s > hi + 1e-12):
        raise ValueError(f"size {float(np.min(s)) if np.any(s < lo) else float(np.max(s)):g} "
                         f"is outside the growth table's body sizes {lo:g} ... {hi:g}")
    return interpolate(s, body[order], f[order])


def rate_factors(seg, rates, sizes, start_size: float = 0.5, end_size: float = 1.0) -> np.ndarray:
    """Factors when segment i grows at r_i times a common rate: f_i = end - r_i c (1 - p), c =
    (end - start) L / sum_j r_j l_j, so the total length is S L throughout."""
    seg, r = np.asarray(seg, np.float64), np.asarray(rates, np.float64)
    sizes = np.asarray(sizes, np.float64)[..., None]
    if end_size == start_size:
        return np.broadcast_to(sizes, sizes.shape[:-1] + (len(seg),)).copy()
    c = (end_size - start_size) * seg.sum() / (r @ seg)
    p = (sizes - start_size) / (end_size - start_size)
    return end_size - r * c * (1.0 - p)


@dataclass(frozen=True)
class Growth:
    """Size from start_size (epoch 1) to end_size (epoch period + 1) along `schedule`, constant
    after; period 0: constant end_size. proximal_lead: the paper gives only the direction, so
    the most that keeps every segment monotonic (arm5 halfway: 75 ... 25 % base to hand)."""

    pattern: str = "proportional"
    start_size: float = 0.5
    end_size: float = 1.0
    period: int = 0  # T_G [epochs]
    schedule: str = "linear"
    proximal_lead: float = 1.0
    # non-proportional growth holds the other segments at this fraction of their length: 1.0,
    # the full-size arm is the common end (our reading of Fig. 3c); 0.5, the common start
    fixed_scale: float = 1.0
    # per_segment: each segment's lead c_i (-1 ... 1; segment_factors), base to hand
    leads: Optional[list[float]] = None
    # per_segment: or each segment's relative growth rate r_i >= 0 (rate_factors)
    rates: Optional[list[float]] = None
    # schedule table: rows [t, size] or [t, f_1, ..., f_m] (module docstring)
    table: Optional[list] = None

    def validate(self, body) -> "Growth":
        check_fields(self, "growth", LIMITS)
        self._validate_table(body)  # before the sizes are mapped through the table
        pattern = PATTERN_TABLE[self.pattern]
        for name in ("rates", "leads"):
            if getattr(self, name) is not None and name not in pattern.uses:
                raise SpecError(f"growth.{name}", getattr(self, name),
                                f"only growth=per_segment uses {name}")
        if pattern.holds:  # segments may be held: each end size must be reachable
            for name in ("start_size", "end_size"):
                try:
                    self.scales(body, getattr(self, name))
                except ValueError as err:
                    raise SpecError(f"growth.{name}", getattr(self, name),
                                    f"body {body.name!r}: {err}") from None
        pattern.check(self, body)
        return self

    def _validate_rates(self, body: "Body") -> None:
        r = self.rates
        if self.leads is not None:
            raise SpecError("growth.rates", r, "give growth.leads or growth.rates, not both")
        if not _per_segment(r, body.m, Number(0.0)) or not np.dot(r, body.segment_lengths) > 0:
            raise SpecError("growth.rates", r, f"per_segment growth needs {body.m} rates >= 0, "
                            f"one per segment of {body.name}, not all zero")
        first = rate_factors(body.segment_lengths, r, self.start_size, self.start_size,
                             self.end_size)
        if self.start_size != self.end_size and np.any(first <= 0):
            i = int(np.argmin(first))
            raise SpecError("growth.rates", r, f"segment {i + 1} would start at length factor "
                            f"{first[i]:.3g} <= 0: its rate is too large for growth from "
                            f"{self.start_size:g} to {self.end_size:g}")

    def _validate_table(self, body: "Body") -> None:
        if self.schedule != "table":
            if self.table is not None:
                raise SpecError("growth.table", self.table, "only schedule=table uses a table")
            return
        if self.table is None:
            raise SpecError("growth.table", None, "schedule=table needs growth.table: rows "
                            "[t, size] or [t, f_1, ..., f_m]")
        _, f = check_table(self.table, body.m)
        sizes = table_body_sizes(f, body.segment_lengths)
        if f.shape[1] > 1:
            if self.pattern != "proportional":
                raise SpecError("growth.pattern", self.pattern, "a per-segment table gives "
                                "every segment's factor; use growth=proportional")
            steps = np.diff(sizes)
            if not (np.all(steps > 0) or np.all(steps < 0)):
                raise SpecError("growth.table", self.table, "the body sizes of a per-segment "
                                "table (length-weighted means of its rows) must rise, or fall, "
                                "strictly")
        if not self.period and f.shape[1] > 1 and not (
                sizes.min() - 1e-12 <= self.end_size <= sizes.max() + 1e-12):
            raise SpecError("growth.end_size", self.end_size, f"a constant body under a "
                            f"per-segment table needs a size in its range {sizes.min():.6g} "
                            f"... {sizes.max():.6g}")
        if self.period and (not np.isclose(sizes[0], self.start_size, rtol=0, atol=1e-9)
                            or not np.isclose(sizes[-1], self.end_size, rtol=0, atol=1e-9)):
            raise SpecError("growth.table", self.table, f"its body sizes run from {sizes[0]:.6g} "
                            f"to {sizes[-1]:.6g}: set growth.start_size={sizes[0]:.6g} "
                            f"growth.end_size={sizes[-1]:.6g}")

    def sizes(self, epochs, body: "Body | None" = None) -> np.ndarray:
        e = np.asarray(epochs)
        if self.period == 0:
            return np.full(e.shape, float(self.end_size))
        if self.schedule == "table":
            t, f = check_table(self.table, len(self.table[0]) - 1)
            if f.shape[1] > 1 and body is None:
                raise ValueError("a per-segment growth table needs the body for its sizes")
            rows = table_body_sizes(f, None if body is None else body.segment_lengths)
            # the times as growth progress 0 ... 1, so that any time unit gives the same sizes
            return interpolate((e - 1) / self.period, (t - t[0]) / (t[-1] - t[0]),
                               rows[:, None])[..., 0]
        done = progress((e - 1) / self.period, self.schedule)
        return self.start_size + (self.end_size - self.start_size) * done

    def segments(self, body) -> tuple[np.ndarray, np.ndarray]:
        return PATTERN_TABLE[self.pattern].segments(self, body)

    def scales(self, body, sizes) -> np.ndarray:
        if self.table is not None and len(self.table[0]) > 2:
            return table_factors(body.segment_lengths, self.table, sizes)
        if self.rates is not None:
            return rate_factors(body.segment_lengths, self.rates, sizes, self.start_size,
                                self.end_size)
        grows, leads = self.segments(body)
        return segment_factors(body.segment_lengths, grows, leads, sizes, self.start_size,
                               self.end_size, self.fixed_scale)

    def to_dict(self) -> dict:
        return asdict(self)


def _per_segment(value, m: int, number: Number) -> bool:
    return isinstance(value, (list, tuple)) and len(value) == m and all(map(number.ok, value))


def _needs_held_segments(growth: Growth, body) -> None:
    if body.growing.all():
        raise SpecError("growth.pattern", growth.pattern,
                        f"every segment of {body.name} grows, so non-proportional growth "
                        "would equal proportional growth; use growth=proportional")


def _needs_two_segments(growth: Growth, body) -> None:
    if np.count_nonzero(body.segment_lengths) < 2:
        raise SpecError("growth.pattern", growth.pattern,
                        f"{body.name} has fewer than two segments of non-zero length")


def _needs_leads_or_rates(growth: Growth, body) -> None:
    if growth.rates is not None:
        growth._validate_rates(body)
        return
    c = growth.leads
    if not _per_segment(c, body.m, Number(-1.0, 1.0)):
        raise SpecError("growth.leads", c, f"per_segment growth needs {body.m} leads "
                        "in -1 ... 1, one per segment of " + body.name)


@dataclass(frozen=True)
class Pattern:
    """A growth pattern: (grows, leads) for segment_factors, its check of a body and config,
    the fields only it uses, whether it holds segments (end sizes checked reachable)."""
    segments: Callable[[Growth, Any], tuple[np.ndarray, np.ndarray]]
    check: Callable[[Growth, Any], None] = lambda growth, body: None
    uses: tuple = ()
    holds: bool = False


# the growth patterns: a new one is a row here and a conf/growth/<name>.yaml
PATTERN_TABLE = {
    "proportional": Pattern(lambda g, b: (np.ones(b.m, bool), np.zeros(b.m)), holds=True),
    "nonproportional": Pattern(lambda g, b: (b.growing, np.zeros(b.m)),
                               check=_needs_held_segments, holds=True),
    "proximal_first": Pattern(lambda g, b: (np.ones(b.m, bool),
                                            proximal_leads(b.segment_lengths, g.proximal_lead)),
                              check=_needs_two_segments),
    "per_segment": Pattern(lambda g, b: (np.ones(b.m, bool),
                                         np.asarray(g.leads, np.float64)),
                           check=_needs_leads_or_rates, uses=("leads", "rates")),
}
PATTERNS = tuple(PATTERN_TABLE)  # the names, in the table's order


LIMITS = dict(
    pattern=Choice(*PATTERNS), schedule=Choice(*SCHEDULES),
    period=Int(0, MAX_INT64, " epochs (int64)"),
    proximal_lead=Number(0.0, 1.0, why=" (beyond, distal segments would shrink for a while)"),
    fixed_scale=Number(0.0, MAX_SIZE, lo_open=True),
    start_size=Number(0.0, MAX_SIZE, lo_open=True), end_size=Number(0.0, MAX_SIZE, lo_open=True),
    leads=Free("per_segment: one per segment, -1 ... 1"),
    rates=Free("per_segment: one per segment, >= 0"),
    table=Free("rows [t, size...]: check_table"))


def factors(body, size, pattern="proportional") -> np.ndarray:
    """Per-segment length factors (..., m) of `body` at `size` grown by `pattern` (a Growth or
    a pattern's name): what Body.forward, chain and frame_points take."""
    growth = pattern if isinstance(pattern, Growth) else Growth(pattern=pattern)
    check_choice("growth.pattern", growth.pattern, PATTERNS)
    try:
        return growth.scales(body, size)
    except ValueError as err:
        raise ValueError(f"body {body.name!r}: {err}") from None
