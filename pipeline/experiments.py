"""What each experiment file (conf/experiment/<name>.yaml) declares, read as plain YAML (not
composed: the same under every profile, not inherited): its report section (`paper.study`) and
its `declares` block, from which the Makefile's lists, report.paper_experiments and the studies'
registries are derived."""
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

    group: Optional[str] = None  # paper | choices | explain | studies: the Makefile's list
    order: Optional[int] = None  # its place in those lists and in the committed report
    reads: Optional[str] = None  # the paper figure a study reads (readings_fig4: fig4)
    conventions: bool = False  # the reporting conventions are measured on this figure
    explains: Optional[str] = None  # the explanation it feeds (pipeline/studies/explain.py)


@dataclass(frozen=True)
class Experiment:
    name: str
    study: str  # paper.study: the report section that reports it
    declares: Declares


def _read(path: Path) -> Experiment:
    """The file read by libyaml's safe loader where PyYAML has it (a tenth of the pure-Python
    parser's CPU; strings, integers and flags read alike)."""
    import yaml

    raw = yaml.load(path.read_text(), Loader=getattr(yaml, "CSafeLoader", yaml.SafeLoader)) or {}
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
    """conf/ (the checkout's or the installed package's) and, in a running stage, every folder
    of Hydra's search path (one's own experiments, a config package of gbgrowth.conf)."""
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
    """name -> Experiment of every experiment file of `folders` (the first holding a name wins),
    by declares.order (those without one last), then by name."""
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
