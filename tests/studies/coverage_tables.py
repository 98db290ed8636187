"""Coverage tables for tests of the scorecard: every measure calibrated (or none)."""
import numpy as np
import pandas as pd

from pipeline.studies import claims, coverage


def covered(cov: float = 0.95, trials: int = 3) -> pd.DataFrame:
    """Every claim's measure with coverage `cov` of the 95 % t interval at `trials` trials:
    calibrated at 95 % where cov >= coverage.MIN_COVERAGE, else not calibrated."""
    level = coverage.LEVELS[0] if cov >= coverage.MIN_COVERAGE else np.nan
    return pd.DataFrame([dict(figure="", claim=c.id, where="", kind="", trials=trials, draws=100,
                              t95=cov, level=level, coverage=cov) for c in claims.CLAIMS],
                        columns=coverage.COLUMNS)
