"""Condition labels, from what differs between the conditions of a figure; never part of a key."""
from __future__ import annotations

import json

from .config import ConfigError
from .keys import canonical

SHORT = {"learner.variations": "V", "learner.radius": "R", "learner.targets_per_epoch": "K",
         "learner.steps": "L", "learner.learning_rate": "eta", "learner.epochs": "epochs",
         "learner.name": "learner", "body.name": "body", "root_seed": "seed"}
GROWTH_AXIS = ("pattern", "period", "start_size", "end_size")  # named by the growth label


def _settings(cond: dict) -> dict:
    """A condition's settings as flat `section.field` -> value, but the growth label's axis."""
    spec = cond["spec"]
    flat = {"learner.epochs": spec["epochs"], "learner.evals_per_decade": spec["evals_per_decade"],
            "snapshots": spec["snapshots"], "root_seed": cond["root_seed"]}
    for section in ("body", "learner", "evaluation", "growth"):
        for k, v in spec[section].items():
            if not (section == "growth" and k in GROWTH_AXIS):
                flat[f"{section}.{k}"] = v
    return flat


def _fmt(v) -> str:
    if isinstance(v, float):
        return repr(v)  # the shortest text that reads back as this float: distinct stays distinct
    if isinstance(v, (list, dict)):
        return json.dumps(v, separators=(",", ":"))
    return str(v)


def varying_keys(conds: list[dict]) -> list[str]:
    """The settings that differ between conditions (a body's or learner's fields only where they
    differ between conditions of one name)."""
    flats = [_settings(c) for c in conds]
    keys = sorted({k for f in flats for k in f})
    differ = [k for k in keys if len({canonical(f.get(k)) for f in flats}) > 1]
    out = []
    for k in differ:
        section = k.split(".", 1)[0]
        if section in ("body", "learner") and k != f"{section}.name" and f"{section}.name" in differ:
            by_name = {}
            for f in flats:
                by_name.setdefault(canonical(f.get(f"{section}.name")), set()).add(
                    canonical(f.get(k)))
            if all(len(vals) == 1 for vals in by_name.values()):
                continue
        out.append(k)
    return out


def condition_labels(conds: list[dict]) -> list[str]:
    """A label per condition: `V=10`, `R=0.1, L=5`, the growth label (`TG100`, `const0.5`) where
    the growth differs, or a variant's own; a ConfigError names two that would share one."""
    keys = varying_keys([c for c in conds if not c.get("variant")])
    per_variant = {}
    for c in conds:
        if c.get("variant"):
            per_variant.setdefault(c["variant"]["label"], set()).add(c["growth_label"])
    growth_varies = len({c["growth_label"] for c in conds}) > 1
    labels = []
    for c in conds:
        if c.get("variant"):
            name = c["variant"]["label"]
            if len(per_variant[name]) > 1:
                name = f"{name} | {c['growth_label']}"
        else:
            flat = _settings(c)
            parts = [", ".join(f"{SHORT.get(k, k.split('.', 1)[-1])}={_fmt(flat.get(k))}"
                               for k in keys)] if keys else []
            if growth_varies or not parts:
                parts.append(c["growth_label"])
            name = " | ".join(parts)
        labels.append(name)
    seen = {}
    for c, name in zip(conds, labels):
        other = seen.setdefault(name, c)
        if other is not c and other["id"] != c["id"]:
            raise ConfigError(f"two different conditions share the label {name!r}: "
                              f"{_diff(other, c)}; give them different variant labels")
    return labels


def _diff(a: dict, b: dict) -> str:
    fa, fb = _settings(a), _settings(b)
    keys = [k for k in sorted(set(fa) | set(fb)) if canonical(fa.get(k)) != canonical(fb.get(k))]
    return "; ".join(f"{k}={_fmt(fa.get(k))} vs {_fmt(fb.get(k))}" for k in keys[:4]) or \
        "same settings"
