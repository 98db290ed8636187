"""P(A < B): the probability that a trial of one learner ends below one of another, with its
interval (the baselines study's comparisons, pipeline/studies/baselines.py)."""
from __future__ import annotations

import numpy as np
from scipy import stats
from scipy.optimize import brentq


def p_beats(a, b) -> tuple[float, float, float]:
    """(P, lo, hi): the probability that a trial of learner A ends below one of learner B, P(A <
    B), estimated over all n m pairs of their trials (ties count half: the Mann-Whitney U / (n m)),
    with its 95 % interval by Newcombe's method 5 (Newcombe 2006, Statist. Med. 25: 559-573): the
    score-type interval {theta : (theta - P)^2 <= z^2 V(theta)} with Hanley and McNeil's variance
    V(theta) = theta (1 - theta) / (n m) [1 + (N - 1)(1 - theta) / (2 - theta) + (N - 1) theta
    / (1 + theta)], N = (n + m) / 2.

    Why this method at the study's 5 trials a learner: it stays inside [0, 1], it does not collapse
    to a point when the samples do not overlap (P = 1 still has an interval, whose lower end says
    how far 5 against 5 trials can go), it needs no random numbers, and Newcombe measured its
    coverage near 95 % down to small samples. A bootstrap over trials collapses there (every
    resample of two separated samples is separated: [1, 1]) and is too narrow at n = 5; a Wald
    interval leaves [0, 1]. NaN where either learner has no finite trial."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    a, b = a[np.isfinite(a)], b[np.isfinite(b)]
    n, m = len(a), len(b)
    if not n or not m:
        return np.nan, np.nan, np.nan
    d = a[:, None] - b[None, :]
    p = float(((d < 0) + 0.5 * (d == 0)).mean())
    z2, k = stats.norm.ppf(0.975) ** 2, (n + m) / 2 - 1

    def w(x):  # V(x) n m / (x (1 - x))
        return (1 + k * (1 - x) / (2 - x) + k * x / (1 + x)) / (n * m)

    def far(q):  # the limit away from q in {0, 1}: (x - q)^2 = z^2 V(x), divided by |x - q|
        return lambda x: abs(x - q) - z2 * (1 - abs(x - q)) * w(x)

    if p == 1.0:
        return p, brentq(far(1.0), 0.0, 1.0), 1.0
    if p == 0.0:
        return p, 0.0, brentq(far(0.0), 0.0, 1.0)

    def f(x):
        return (x - p) ** 2 - z2 * x * (1 - x) * w(x)

    return p, brentq(f, 0.0, p), brentq(f, p, 1.0)
