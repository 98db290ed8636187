"""What each experiment declares (conf/experiment/<name>.yaml), read from the files themselves.

An experiment is its YAML file: the conditions it runs, the report section that reports it
(`paper.study`), and a `declares` block that says where it belongs:

    declares:
      group: paper        # paper | choices | explain | studies: the Makefile's list it is in
      order: 4            # its place in those lists and in the committed report
      reads: fig4         # the paper figure a study reads (the readings study: readings_fig4)
      conventions: true   # the reporting conventions are measured on this figure
      explains: boundary  # the explanation it feeds (pipeline/studies/explain.py)

The Makefile's lists (pipeline.tools.experiments), report.paper_experiments (the resolver
`${experiments:...}`) and the studies' registries (readings, baselines, conventions, explain)
are derived from these declarations: a study is its module and its experiment files. The files
are read as YAML, not composed: a declaration is plain data, the same under every profile, and
an experiment's own (not inherited through its defaults list).
"""
from __future__ import annotations

import dataclasses
import sys
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path
from typing import Optional

GROUPS = ("paper", "choices", "explain", "studies")  # make reproduce runs the first three


@dataclass
class Declares:
    """The `declares` block of an experiment file (the schema: pipeline.config.Config)."""

    group: Optional[str] = None
    order: Optional[int] = None
    reads: Optional[str] = None
    conventions: bool = False
    explains: Optional[str] = None


@dataclass(frozen=True)
class Experiment:
    name: str
    study: str  # paper.study: the report section that reports it
    declares: Declares


def _yaml(text: str):
    """The YAML document `text` as plain data, by libyaml's safe loader where PyYAML has it (a
    tenth of the pure-Python parser's CPU; OmegaConf.load took 0.34 s for conf/'s 22 files, read
    by every stage). What is read here (declares, paper.study) is strings, integers and flags,
    which both parsers read alike; Hydra composes the files with its own loader."""
    import yaml

    return yaml.load(text, Loader=getattr(yaml, "CSafeLoader", yaml.SafeLoader))


def _read(path: Path) -> Experiment:
    raw = _yaml(path.read_text()) or {}
    if not isinstance(raw, dict):
        raise ValueError(f"{path}: not a mapping of keys to values")
    given = raw.get("declares") or {}
    known = {f.name for f in dataclasses.fields(Declares)}
    unknown = sorted(set(given) - known)
    if unknown:
        raise ValueError(f"{path}: declares.{unknown[0]}: unknown key (known: {', '.join(sorted(known))})")
    d = Declares(**given)
    if d.group is not None and d.group not in GROUPS:
        raise ValueError(f"{path}: declares.group={d.group!r}: choose one of {', '.join(GROUPS)}")
    return Experiment(path.stem, (raw.get("paper") or {}).get("study") or "figures", d)


def config_folders() -> tuple[Path, ...]:
    """The config folders whose experiment files the project's lists are read from: conf/ (the
    checkout's, or the installed package's) and, in a running stage, every folder of Hydra's
    search path (an experiment of one's own, a config package of gbgrowth.conf)."""
    import importlib.util

    from gbmodel.bodies import CONF_DIR

    folders = [Path(CONF_DIR)]
    hydra = sys.modules.get("hydra.core.hydra_config")  # not imported: no stage runs (a tool)
    running = hydra is not None and hydra.HydraConfig.initialized()
    for s in hydra.HydraConfig.get().runtime.config_sources if running else ():
        if s.schema == "file":
            folders.append(Path(s.path))
        elif s.schema == "pkg" and s.provider.startswith("gbgrowth:"):  # a declared package
            spec = importlib.util.find_spec(s.path.replace("/", "."))
            folders += [Path(p) for p in (spec.submodule_search_locations or [])] if spec else []
    return tuple(dict.fromkeys(f.resolve() for f in folders))


@lru_cache(maxsize=8)
def declared(folders: tuple[Path, ...]) -> dict[str, Experiment]:
    """name -> Experiment for every experiment file of `folders` (config folders: conf/ and any
    of hydra.searchpath; the first holding a name wins), ordered by declares.order (those
    without one last), then by name."""
    found = {}
    for folder in folders:
        for path in sorted((Path(folder) / "experiment").glob("*.yaml")):
            found.setdefault(path.stem, _read(path))
    key = lambda e: (e.declares.order is None, e.declares.order or 0, e.name)  # noqa: E731
    return {e.name: e for e in sorted(found.values(), key=key)}


def listed(folders: tuple[Path, ...], *groups: str) -> list[str]:
    """The experiments of `groups` (all of GROUPS when none given), in their declared order."""
    groups = groups or GROUPS
    return [n for n, e in declared(folders).items() if e.declares.group in groups]
