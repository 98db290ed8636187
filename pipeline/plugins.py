"""Engines and studies kept outside the repository, found through standard entry points: a
distribution declares `[project.entry-points."gbgrowth.engines"] toy = "my_package.toy"` (or
"gbgrowth.studies") and its module registers itself when imported. Nothing else on the Python
path is imported."""
from __future__ import annotations

from importlib.metadata import entry_points

ENGINES, STUDIES = "gbgrowth.engines", "gbgrowth.studies"  # the groups (pyproject.toml)


def load_plugins(group: str, broken: dict[str, str]) -> None:
    """Import every entry point of `group`; one that fails costs no other command: broken[name]
    says why, for the one that asks for it by name."""
    for ep in entry_points(group=group):
        try:
            ep.load()
        except Exception as err:
            why = str(err).splitlines()[0] if str(err) else ""
            broken[ep.name] = f"{ep.value}: {type(err).__name__}: {why}"
