"""The measures of a learning curve that the aggregate stage and the studies share."""
from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:  # the frames come from the callers: a cached aggregate loads no pandas
    import pandas as pd


def rise(values: np.ndarray) -> tuple:
    """(index, rise) of the point rising most above the lowest value before it (0, 0 if none),
    along the last axis: the paper's "significant temporary increase" (sec. 3.1)."""
    values = np.asarray(values)
    r = values - np.minimum.accumulate(values, axis=-1)
    i = np.argmax(r, axis=-1)
    return i, np.take_along_axis(r, np.expand_dims(i, -1), -1)[..., 0]


def growth_peak(curve: pd.DataFrame) -> tuple[int, float, float]:  # (epoch, value, rise)
    c = curve.sort_values("epoch")
    err = c["abs_error_mean"].to_numpy()
    i, r = rise(err)
    return int(c["epoch"].iloc[i]), float(err[i]), float(r)


def finals(trials: pd.DataFrame) -> pd.DataFrame:
    """The rows of every condition at that condition's last epoch."""
    last = trials.groupby("condition", sort=False)["epoch"].transform("max")
    return trials[trials["epoch"] == last]
