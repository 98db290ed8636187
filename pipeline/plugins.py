"""Modules named <prefix><name> anywhere on the Python path: the engines' (gbgrowth_engine_) and
the studies' (gbgrowth_study_) way in from outside the repository."""
from __future__ import annotations

import importlib
import pkgutil


def import_plugins(prefix: str, broken: dict[str, str]) -> None:
    """Import every module on the Python path whose name starts with `prefix` (each registers
    itself when imported). Someone else's module that fails to import costs no other command:
    broken[name] says why, for the one that asks for it by name."""
    for m in pkgutil.iter_modules():
        if m.name.startswith(prefix):
            try:
                importlib.import_module(m.name)
            except Exception as err:
                why = str(err).splitlines()[0] if str(err) else ""
                broken[m.name[len(prefix):]] = f"{m.name}: {type(err).__name__}: {why}"
