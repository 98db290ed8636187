"""Planned runs: paths.out/planned/<digest>.json keeps a command's jobs (plan_digest: its config,
overrides and every file a plan is made from), checked like a cache (misplanned); a command line
that planned without error leaves a note (checked_marker) so that its next run skips the check,
unless a body file it read changed since."""
from __future__ import annotations

import hashlib
import json
import os
import sys
from functools import lru_cache
from pathlib import Path

import gbmodel.bodies
from omegaconf import DictConfig, OmegaConf

from .keys import canonical, trial_key

PLANNED = "planned"  # paths.out/planned/<digest>.json: a command's jobs (the cache holds trials)
_PLAN_SOURCES = (("conf", ("*.yaml",)), ("pipeline", ("*.py",)),
                 ("gbmodel", ("*.py", "*.yaml", "*.urdf", "*.json")))


def _hash_files(h, base: Path, folder: Path, patterns) -> None:
    for p in sorted({p for pat in patterns for p in folder.rglob(pat)
                     if "__pycache__" not in p.parts}):
        h.update(str(p.relative_to(base)).encode() + b"\0" + p.read_bytes() + b"\0")


@lru_cache(maxsize=1)
def planning_sources() -> str:
    """The hash of every file a plan is made from (conf/, pipeline's and gbmodel's code and
    data) and of the versions of Hydra, OmegaConf and Python (whose syntax trees the code
    fingerprint hashes: the same files may give another fingerprint in another Python)."""
    import hydra
    import omegaconf

    root = Path(__file__).resolve().parents[1]
    python = f"{sys.implementation.name} {sys.version_info[0]}.{sys.version_info[1]}"
    h = hashlib.sha256(f"{hydra.__version__} {omegaconf.__version__} {python}".encode())
    for folder, patterns in _PLAN_SOURCES:
        _hash_files(h, root, root / folder, patterns)
    return h.hexdigest()


def covers_code() -> bool:
    """Whether planning_sources hashed every file of every learner's code fingerprint: this
    process imported the gbmodel it hashes and registered no learner (one registered may shadow
    a file, or be imported by one; unregistered, each learner is files of this gbmodel). A plan
    saved where this held, taken where it holds, has this process's fingerprints by its digest
    (simulate.still_planned)."""
    import gbmodel.learners

    root = Path(__file__).resolve().parents[1]
    return (Path(gbmodel.__file__).resolve().parent == root / "gbmodel"
            and not gbmodel.learners.registered())


def config_sources() -> str | None:
    """The hash of the config files outside the checkout's conf/ a plan may be composed from
    (the installed package's, ./conf, hydra.searchpath's folders: `experiments=[mine]` composes
    files the resolved config does not hold); None when there are none. Read on every call."""
    from .experiments import config_folders

    checkout = (Path(__file__).resolve().parents[1] / "conf").resolve()
    here = Path.cwd() / "conf"
    folders = [*config_folders(), *([here.resolve()] if here.is_dir() else [])]
    folders = [f for f in dict.fromkeys(folders) if f != checkout and f.is_dir()]
    if not folders:
        return None
    h = hashlib.sha256()
    for folder in folders:
        h.update(str(folder).encode() + b"\0")
        _hash_files(h, folder, folder, ("*.yaml",))
    return h.hexdigest()


def plan_digest(cfg: DictConfig, overrides) -> str:
    """The hash of what a command's plan is made of: the same digest, the same trials."""
    body = dict(config=OmegaConf.to_container(cfg, resolve=True), overrides=list(overrides),
                sources=planning_sources())
    own = config_sources()
    if own is not None:
        body["config_sources"] = own
    return hashlib.sha256(canonical(body).encode()).hexdigest()[:24]


def checked_marker(cfg: DictConfig, overrides) -> Path | None:
    """paths.out/planned/checked/<digest>.json, the note that this command line planned without
    error; None when the config does not resolve outside Hydra's run."""
    try:
        digest = plan_digest(cfg, ["checked", list(overrides)])
    except Exception:  # an interpolation only Hydra's own run resolves
        return None
    return Path(cfg.paths.out) / PLANNED / "checked" / f"{digest}.json"


def _body_files(trials: list[dict]) -> list[list]:
    """(section, its description, sha256) of every file the trials' bodies read (outside
    plan_digest: a URDF, an MJCF model, a body in the loop's function)."""
    seen, out = set(), []
    for t in trials:
        if id(t["spec"]) in seen:
            continue
        seen.add(id(t["spec"]))
        for section in gbmodel.bodies.READS:
            value = t["spec"]["body"].get(section)
            if isinstance(value, dict) and "sha256" in value:
                entry = [section, {k: v for k, v in value.items() if k != "sha256"},
                         value["sha256"]]
                if entry not in out:
                    out.append(entry)
    return out


def was_checked(marker: Path | None, root=None) -> bool:
    """Whether `marker` says the config planned without error and every body file it read is
    unchanged; not through a link leaving `root` (a planted note)."""
    if marker is None:
        return False
    from . import io

    try:
        with io.confined(root):
            io.check_inside(marker)
        fd = os.open(marker, os.O_RDONLY | os.O_NOFOLLOW)
        with os.fdopen(fd, "rb") as fh:
            note = json.loads(fh.read())
        return all(gbmodel.bodies.source_digest(section, value) == sha
                   for section, value, sha in note["body_files"])
    except (OSError, ValueError, TypeError, KeyError):
        return False


def mark_checked(marker: Path | None, trials: list[dict], root=None) -> None:
    """Keep `marker`, confined to `root` (paths.root); a folder that cannot be written (or leads
    outside) leaves it out."""
    if marker is None:
        return
    from . import io

    try:
        with io.confined(root):
            io.write_json(marker, dict(trials=len(trials), body_files=_body_files(trials)),
                          compact=True)
    except (OSError, io.UnsafeName):
        pass


def misplanned(specs: list[dict], jobs: list[dict]) -> str | None:
    """What is wrong with a saved plan's trials (specs once, trials naming theirs by index);
    None when each trial's spec, seed and code hash to its key and its condition is its spec's.
    Each spec's canonical JSON is made once (trial_key and condition_id, by hand)."""
    canon = [canonical(spec) for spec in specs]
    conds = {}
    for job in jobs:
        for t in job["trials"]:
            ix, seed, code = t["spec"], t["seed"], t["code"]
            body = f'{{"code":{canonical(code)},"seed":{canonical(seed)},"spec":{canon[ix]}}}'
            if "start" in t:  # a continuation: its base and its base's key are its content
                b = t["base"]
                body = canonical(dict(spec=specs[ix], seed=seed, code=code, start=t["start"]))
                if b["key"] != t["start"]["key"] or trial_key(
                        b["spec"], b["seed"], b["code"]) != b["key"]:
                    return f"trial {t['key']}: its base does not hash to the key it names"
            if hashlib.sha256(body.encode()).hexdigest()[:20] != t["key"]:
                return f"trial {t['key']}: its spec, seed and code do not hash to its key"
            root = seed["entropy"]
            if (ix, root) not in conds:
                conds[ix, root] = hashlib.sha256(
                    f'{{"root_seed":{canonical(root)},"spec":{canon[ix]}}}'.encode()
                ).hexdigest()[:16]
            if conds[ix, root] != t["condition"]:
                return f"trial {t['key']}: its condition is not its spec's"
    return None
