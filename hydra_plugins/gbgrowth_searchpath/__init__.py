"""Hydra plugin: gbgrowth's commands also find configs in a conf/ folder of the working directory.

A user's own bodies, learners and experiments in ./conf/body/, ./conf/experiment/, ... are found
by convention, as if named on hydra.searchpath: after the shipped configs (a shipped name wins)
and before hydra.searchpath's folders. Only for gbgrowth's own configs (the checkout's conf/ or
the installed pkg://gbgrowth_conf); other Hydra apps in the same environment are left alone.
Hydra imports every module under hydra_plugins/ when it starts: this one imports nothing of
gbgrowth.
"""
from __future__ import annotations

import os
from pathlib import Path

from hydra.core.config_search_path import ConfigSearchPath
from hydra.plugins.search_path_plugin import SearchPathPlugin

PACKAGE = "pkg://gbgrowth_conf"
CHECKOUT_CONF = Path(__file__).resolve().parents[2] / "conf"  # a checkout's conf/


def _folder(path: str) -> str:
    return path[len("file://"):] if path.startswith("file://") else path


class GbgrowthSearchPath(SearchPathPlugin):
    def manipulate_search_path(self, search_path: ConfigSearchPath) -> None:
        mains = [e.path for e in search_path.get_path() if e.provider == "main"]
        if not any(p == PACKAGE or Path(_folder(p)) == CHECKOUT_CONF for p in mains if p):
            return
        here = Path(os.getcwd()) / "conf"
        if here.is_dir() and not any(p and Path(_folder(p)).resolve() == here.resolve()
                                     for p in mains if not p.startswith("pkg://")):
            search_path.append(provider="gbgrowth: conf/ of the working directory",
                               path=f"file://{here}")
