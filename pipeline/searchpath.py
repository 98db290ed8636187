"""A Hydra plugin: ./conf of the working directory, then the config packages declared as entry
points of `gbgrowth.conf` (`mine = "my_package.conf"`), on the search path after the shipped
configs, for gbgrowth's primary config only. A shipped name wins; a user's file it hides is
named in one line (shadowed). pipeline.config registers the plugin when imported."""
from __future__ import annotations

import os
from pathlib import Path

from hydra.core.config_search_path import ConfigSearchPath
from hydra.core.plugins import Plugins
from hydra.plugins.search_path_plugin import SearchPathPlugin

PROVIDER = "gbgrowth: conf/ of the working directory"
CONF_GROUP = "gbgrowth.conf"  # entry points naming config packages (pyproject.toml)


def _folder(path: str) -> str:
    return path[len("file://"):] if path.startswith("file://") else path


class WorkingDirConf(SearchPathPlugin):
    config_path = None  # the stages' primary config (register)

    def manipulate_search_path(self, search_path: ConfigSearchPath) -> None:
        mains = [e.path for e in search_path.get_path() if e.provider == "main" and e.path]
        if self.config_path not in {_folder(p) for p in mains} | set(mains):
            return  # another app's config
        here = Path(os.getcwd()) / "conf"
        if here.is_dir() and not any(Path(_folder(p)).resolve() == here.resolve()
                                     for p in mains if not p.startswith("pkg://")):
            search_path.append(provider=PROVIDER, path=f"file://{here}")
        for package in declared():
            search_path.append(provider=f"gbgrowth: {CONF_GROUP}", path=f"pkg://{package}")


def declared() -> list[str]:  # the config packages of CONF_GROUP (named, never imported)
    from importlib.metadata import entry_points

    return sorted({ep.value for ep in entry_points(group=CONF_GROUP)})


def register(config_path: str) -> None:  # for the stages' primary config `config_path`
    WorkingDirConf.config_path = config_path
    Plugins.instance().register(WorkingDirConf)


def shadowed(shipped: Path, folders: list[Path]) -> list[str]:
    """A line for each config file of `folders` that a shipped one of its group and name hides."""
    out = []
    for folder in folders:
        if not folder.is_dir() or folder.resolve() == shipped.resolve():
            continue
        for path in sorted(folder.rglob("*.yaml")):
            rel = path.relative_to(folder)
            if (shipped / rel).is_file():
                out.append(f"note: {path} is ignored: the shipped config "
                           f"{rel.with_suffix('').as_posix()} has that name (Hydra reads the "
                           f"shipped one); give yours another name")
    return out
