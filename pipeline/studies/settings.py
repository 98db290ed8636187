"""What made a figure of one's own: each condition's settings that differ from the spec the
default configuration gives for the same body."""
from __future__ import annotations

from functools import lru_cache

SKIP = ("body.",)  # the body's geometry: named by the body, its file (urdf) shown on its own


def flatten(d: dict, prefix: str = "") -> dict:
    out = {}
    for k, v in d.items():
        out.update(flatten(v, f"{prefix}{k}.") if isinstance(v, dict) else {f"{prefix}{k}": v})
    return out


@lru_cache(maxsize=None)
def _default_spec(body: str) -> tuple:
    """The default configuration's trial spec for `body`, flattened; the plain default's for a
    body that does not compose by name (a body file of one's own)."""
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
    base = dict(_default_spec(spec.get("body", {}).get("name", "")))
    return {k: v for k, v in flatten(spec).items()
            if not (k.startswith(SKIP) and k not in ("body.name", "body.urdf"))
            and base.get(k, object()) != v}


def markdown(agg: dict) -> str:
    """A row per condition: the settings that differ from the defaults, as `key=value`."""
    from .choices import escape

    lines = ["| condition | settings that differ from the defaults |", "|---|---|"]
    lines += [f"| {escape(name)} | "
              + escape("; ".join(f"{k}={v}" for k, v in differences(c["spec"]).items())
                       or "the defaults") + " |"
              for name, c in agg["models"]["conditions"].items()]
    return "\n".join(lines) + "\n"
