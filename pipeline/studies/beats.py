"""P(A < B): the probability that a trial of one learner ends below one of another, with its
interval (the baselines study's comparisons, pipeline/studies/baselines.py)."""
from __future__ import annotations

import numpy as np
from scipy import stats
from scipy.optimize import brentq


def p_beats(a, b) -> tuple[float, float, float]:
    """(P, lo, hi): P(A < B) over all n m pairs of trials (ties count half: Mann-Whitney U /
    (n m)) and its 95 % interval by Newcombe's method 5 (Statist. Med. 25: 559-573, 2006): {theta
    : (theta - P)^2 <= z^2 V(theta)}, Hanley and McNeil's V(theta) = theta (1 - theta) / (n m) [1 +
    (N - 1)(1 - theta) / (2 - theta) + (N - 1) theta / (1 + theta)], N = (n + m) / 2. At 5 trials
    a learner it stays in [0, 1] and keeps an interval at P = 1 (a bootstrap collapses to [1, 1],
    a Wald interval leaves [0, 1]). NaN where either learner has no finite trial."""
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
