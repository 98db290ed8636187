"""What made a figure: each condition's settings that differ from the defaults.

A report of one's own experiment says which settings made it (the learner's radius and rate,
the update rule, the growth schedule and leads, the body file, ...): the difference between
each condition's trial spec and the spec the default configuration gives for the same body.
"""
from __future__ import annotations

from functools import lru_cache

import pandas as pd

SKIP = ("body.",)  # the body's geometry: named by the body, its file (urdf) shown on its own


def flatten(d: dict, prefix: str = "") -> dict:
    out = {}
    for k, v in d.items():
        if isinstance(v, dict):
            out.update(flatten(v, f"{prefix}{k}."))
        else:
            out[f"{prefix}{k}"] = v
    return out


@lru_cache(maxsize=None)
def _default_spec(body: str) -> tuple:
    """The default configuration's trial spec for `body` (its own learner settings), flattened;
    the plain default's when the body does not compose by name (a body file of one's own)."""
    from ..config import compose
    from ..plan import plan

    for overrides in ([f"body={body}"], []):
        try:
            return tuple(flatten(plan(compose(overrides))[0]["spec"]).items())
        except Exception:  # a body that is not a config group: the plain default
            continue
    return ()


def differences(spec: dict) -> dict:
    """The settings of one condition's spec that differ from the defaults for its body."""
    body = spec.get("body", {}).get("name", "")
    base = dict(_default_spec(body))
    out = {}
    for k, v in flatten(spec).items():
        if k.startswith(SKIP) and k not in ("body.name", "body.urdf"):
            continue
        if k == "body.name" and v == base.get(k):
            continue
        if base.get(k, object()) != v:
            out[k] = v
    return out


def table(agg: dict) -> pd.DataFrame:
    """One row per condition: the settings that differ from the defaults, as `key=value`."""
    rows = []
    for name, cond in agg["models"]["conditions"].items():
        diff = differences(cond["spec"])
        rows.append(dict(condition=name, settings="; ".join(f"{k}={v}" for k, v in diff.items())
                         or "the defaults"))
    return pd.DataFrame(rows)


def markdown(agg: dict) -> str:
    from .choices import escape

    t = table(agg)
    lines = ["| condition | settings that differ from the defaults |", "|---|---|"]
    lines += [f"| {escape(r.condition)} | {escape(r.settings)} |" for r in t.itertuples()]
    return "\n".join(lines) + "\n"
