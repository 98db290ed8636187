"""The command line's check: every configuration it can produce (each value of a sweep) is
composed and planned first, and a failure is one line (exit 2) before anything is written, where
Hydra would print several lines, or fail a sweep's second job after the first ran.
"""
from __future__ import annotations

import itertools
import math
import re
import sys
from pathlib import Path

from hydra.core.override_parser.overrides_parser import OverridesParser

from .config import (CONF_DIR, ConfigError, check_choices, check_experiments, check_hydra,
                     check_keys, check_run, compose, config_notes, declared, overrides_of,
                     without_hydra)
from .config.hydra_run import MODE, compose_as_run
from .labels import condition_labels
from .plan import plan, plan_conditions
from .planned import checked_marker, was_checked
from .searchpath import shadowed

# a sweep's jobs planned up front: the first, then each other value of each swept key (the
# others at their first), at most this many; every value with a declared range is checked
_MAX_COMBINATIONS = 8
MAX_SWEEP_JOBS = 10_000  # jobs of one multirun: each is a Hydra job with its own folder
PASSED: list = []  # [(marker, trials, root)] of a one-job command line, kept by cli.finish
SWEEP: list = []  # [(n_jobs, each planned job's trials, cache, workers)]: simulate.before_sweep


def check_sweep_size(parsed) -> str | None:
    """One line when the sweeps make too many jobs (counted without building their values)."""
    from hydra.core.override_parser.types import ChoiceSweep, RangeSweep

    total = 1
    for o in parsed:
        if o.is_sweep_override():
            v = o.value()  # a glob's size depends on the config: counted as 1
            if isinstance(v, RangeSweep):
                total *= max(0, math.ceil((v.stop - v.start) / v.step)) if v.step else 0
            elif isinstance(v, ChoiceSweep):
                total *= len(v.list)
            if total > MAX_SWEEP_JOBS:
                return (f"{o.input_line}: the sweep makes more than {MAX_SWEEP_JOBS:,} jobs; "
                        "sweep fewer values (or list the conditions in one experiment)")
    return None


def _one_line(err: BaseException) -> str:
    """The innermost message of an exception chain, in one line naming the key."""
    while err.__cause__ is not None and str(err.__cause__):
        err = err.__cause__
    text = str(err)
    missing = re.search(r"Could not find '([^']+)/([^']+)'", text)
    if missing:  # an unknown option of a config group
        group, value = missing.groups()
        listing = text.split(f"Available options in '{group}':", 1)[-1]
        listing = listing.split("Config search path", 1)[0]
        options = [ln.strip() for ln in listing.splitlines() if ln.startswith("\t")]
        return f"{group}={value}: unknown option; choose one of: {', '.join(options)}"
    lines = [ln.strip() for ln in text.splitlines() if ln.strip()]
    key = next((ln.split(":", 1)[1].strip() for ln in lines if ln.startswith("full_key:")), None)
    lines = [ln for ln in lines if not ln.startswith(
        ("full_key:", "object_type=", "reference_type=", "Set the environment"))]
    message = "; ".join(lines) or type(err).__name__
    return f"{key}: {message}" if key else message


def _folders(searchpath) -> list[Path]:
    """The `file://` folders of a hydra.searchpath value."""
    return [Path(str(e)[len("file://"):]) for e in
            (searchpath if isinstance(searchpath, list) else [searchpath])
            if str(e).startswith("file://")]


def renamed_group(override: str) -> str | None:
    """One line for an override of the group `executor` (now `engine`): what to write instead."""
    bare = override.lstrip("+~")
    key, _, value = bare.partition("=")
    if key.split(".", 1)[0] != "executor":
        return None
    rest = key.removeprefix("executor").removeprefix(".").removeprefix("slurm").removeprefix(".")
    new = "engine" if rest in ("", "backend") else f"engine.{rest}"
    return (f"{override}: the group executor is named engine now; write "
            f"{override[:len(override) - len(bare)]}{new}={value} (docs/engines.md)")


def empty_config_file(err: BaseException, overrides: list[str]) -> str | None:
    """One line when composing failed on an empty config file (a failed `tool > file`)."""
    found = re.search(r"In '([\w./-]+)'", str(err))
    if not found:
        return None
    folders = [CONF_DIR, Path.cwd() / "conf", *searchpath_folders(overrides)]
    for folder in folders:
        path = folder / f"{found.group(1)}.yaml"
        if path.is_file() and not path.read_text().strip():
            return (f"{path}: the file is empty; write it with `python -m pipeline.tools.rate "
                    "... --write` (a shell redirect `> file` leaves it empty when the command "
                    "fails), or remove it")
    return None


# Hydra's flags that read config files the check does not compose, or a pickled config (code)
_UNCHECKED_FLAGS = {"--config-path", "-cp", "--config-name", "-cn", "--config-dir", "-cd",
                    "--experimental-rerun"}


def searchpath_folders(overrides: list[str]) -> list[Path]:
    return [f for o in overrides if o.startswith("hydra.searchpath=")
            for f in _folders(OverridesParser.create().parse_override(o).value())]


def check(argv: list[str], stage=None) -> str | None:
    """None when every configuration of the command line composes and plans, else one line
    saying why. `stage`: the @hydra.main function, whose run is then given the config composed
    here (config.hydra_run)."""
    PASSED.clear()
    SWEEP.clear()
    try:
        overrides, parsed, multirun = _parsed(argv)
        choices, sweeps, hydra_own = _choices(parsed, multirun)
        n_jobs = math.prod(len(c) for c in choices)
        planned, growing, ignored, jobs = {}, False, None, []
        notes = shadowed(CONF_DIR, [Path.cwd() / "conf", *searchpath_folders(overrides)])
        combinations = itertools.islice(_one_at_a_time(choices), _MAX_COMBINATIONS)
        for n, combination in enumerate(combinations):
            given = list(combination)
            try:  # values too: every sweep job is checked up front
                if n == 0:
                    one = stage is not None and n_jobs == 1 and not multirun
                    cfg = _first(given, hydra_own, stage if one else None, overrides)
                    check_experiments(cfg, given)
                    check_sweep_values(sweeps, cfg)
                else:
                    cfg = compose(given)
                trials = _planned(cfg, given, notes, n_jobs == 1, hydra_own)
                planned.setdefault(cfg.figure, []).extend(trials)
                jobs.append(trials)
                growing = growing or cfg.growth.pattern != "none"
                if cfg.growth.pattern == "none" and cfg.growth.period:
                    ignored = ignored or (cfg, given)
            except ConfigError:
                raise
            except Exception as err:
                return empty_config_file(err, given) or _one_line(err)
        if ignored and not growing:  # a period every job ignores: refused as in one run
            check_choices(*ignored)
        for trials in planned.values():  # a sweep's jobs make one figure: their labels differ
            condition_labels(plan_conditions(trials))
    except ConfigError as err:
        return str(err)
    for note in notes:
        print(note, file=sys.stderr)
    if n_jobs > 1:
        SWEEP[:] = [(n_jobs, jobs, cfg.paths.cache, cfg.workers)]  # (the last job's place)
    return None


def _parsed(argv: list[str]) -> tuple[list[str], list, bool]:
    """(the overrides, Hydra's parse of them, whether -m), or a ConfigError."""
    for arg in argv:
        if arg.split("=", 1)[0] in _UNCHECKED_FLAGS:
            raise ConfigError(f"{arg}: the stages read the project's config and the folders of "
                              "hydra.searchpath=[file://...] only (where every file is checked)")
    overrides = overrides_of(argv)
    try:
        parsed = OverridesParser.create().parse_overrides(overrides)
    except Exception as err:  # a syntax error in an override
        for o in (o for o in overrides if not o.isascii()):  # one Hydra's lexer refuses alone
            try:
                OverridesParser.create().parse_overrides([o])
            except Exception as bad:
                if "LexerNoViableAlt" in type(bad.__cause__ or bad).__name__ + str(bad):
                    key, value = o.split("=", 1)[0], o.split("=", 1)[-1]
                    raise ConfigError(f"{o}: Hydra reads characters beyond ASCII only inside "
                                      f"quotes; write '{key}=\"{value}\"'") from None
        raise ConfigError(_one_line(err)) from None
    problem = check_sweep_size(parsed)
    for o in parsed:  # callbacks, launchers, the searchpath: composed and checked once
        if o.is_hydra_override() and o.is_sweep_override():
            problem = problem or (f"{o.input_line}: Hydra's own settings take one value per "
                                  "command; sweep the stage's keys only")
        problem = problem or renamed_group(o.input_line)
    if problem:
        raise ConfigError(problem)
    return overrides, parsed, "-m" in argv or "--multirun" in argv


def _choices(parsed, multirun: bool) -> tuple[list[list[str]], list, list[str]]:
    """(each override's values as overrides, the sweeps, Hydra's own overrides but the
    searchpath), or a ConfigError."""
    choices, sweeps = [], []
    for o in parsed:
        if o.is_hydra_override():
            if o.get_key_element() == "hydra.searchpath":  # where config groups (a body) live
                for folder in _folders(o.value()):  # (Hydra skips a missing one silently)
                    if not folder.is_dir():
                        raise ConfigError(f"hydra.searchpath: {folder} is not a folder; give the "
                                          "absolute path of your config folder (the one that "
                                          "holds body/)")
                choices.append([o.input_line])
            continue  # hydra/launcher=... and hydra.*: checked on the composed config
        if o.is_sweep_override():
            if not multirun:
                raise ConfigError(f"{o.input_line}: a sweep over several values needs -m "
                                  "(--multirun)")
            values = itertools.islice(o.sweep_string_iterator(), _MAX_COMBINATIONS)
            choices.append([f"{o.get_key_element()}={v}" for v in values])
            sweeps.append(o)
        else:
            choices.append([o.input_line])
    hydra_own = [o.input_line for o in parsed if o.is_hydra_override()
                 and o.get_key_element() != "hydra.searchpath"]
    return choices, sweeps, hydra_own


def _first(given: list[str], hydra_own: list[str], stage, overrides: list[str]):
    """The first job's config, composed once with Hydra's section, which is checked, then
    dropped."""
    full = None
    if stage is not None and given + hydra_own == overrides:
        full = compose_as_run(stage, overrides)
    if full is None:
        full = compose(given + hydra_own, hydra=True)
    check_hydra(full)
    MODE[:] = [full.hydra.mode]  # a sweep's values leave it as it is
    return without_hydra(full) if not hydra_own else compose(given)


def _planned(cfg, given: list[str], notes: list[str], one_job: bool,
             hydra_own: list[str]) -> list[dict]:
    """The trials of one job's config, its notes added to `notes`. one_job: the stage takes this
    plan, and a command line checked before (planned.checked_marker) plans nothing: []."""
    check_keys(cfg)
    notes += [n for n in config_notes(cfg) if n not in notes]
    marker = checked_marker(cfg, given + hydra_own) if one_job else None
    if was_checked(marker, cfg.paths.root):
        check_run(cfg)
        return []
    trials = plan(cfg, remember=one_job)  # checks the values, the limits
    note = check_choices(cfg, given, sweep=not one_job)  # what plan accepts but a user did
    if note and note not in notes:  # not mean; in a sweep, a key some jobs ignore: one line
        notes.append(note)
    keeps_experiment(given, trials)
    if one_job:  # kept when the stage has run (cli.finish): a refused run writes nothing
        PASSED[:] = [(marker, trials, cfg.paths.root)]
    return trials


def _one_at_a_time(choices: list[list[str]]):
    """The first combination, then each other value of each choice, the rest at their first."""
    first = [c[0] for c in choices]
    yield tuple(first)
    for i, c in enumerate(choices):
        for v in c[1:]:
            yield tuple(first[:i] + [v] + first[i + 1:])


def _sweep_values(o):
    from hydra.core.override_parser.types import ChoiceSweep, RangeSweep

    v = o.value()
    if isinstance(v, RangeSweep):
        x = v.start
        while (x < v.stop) if v.step > 0 else (x > v.stop):
            yield x
            x += v.step
    elif isinstance(v, ChoiceSweep):
        yield from v.list


def check_sweep_values(sweeps, cfg) -> None:
    """ConfigError for the first value of any sweep outside its key's declared range."""
    groups = {o.get_key_element() for o in sweeps}
    for o in sweeps:
        key = o.get_key_element().lstrip("+~")
        if key.split(".")[0] in groups:  # swept with its group (learner=a,b): a range each
            continue
        constraint = declared(key, cfg)
        if constraint is None:
            continue
        for value in _sweep_values(o):
            if not constraint.ok(value):
                raise ConfigError(f"{key}={value!r} (a value of the sweep {o.input_line}): "
                                  f"must be {constraint.describe()}")


# Overrides that leave an experiment's conditions as they are (where, how and how many)
_KEEPS_CONDITIONS = ("profile", "paths.", "workers", "engine", "trials.count", "report.",
                     "aggregate.", "bench.", "experiments")


def keeps_experiment(overrides: list[str], trials: list[dict]) -> None:
    """ConfigError when `experiment=E` with other settings would replace E's figure."""
    keys = {o.lstrip("+~").split("=", 1)[0]: o for o in overrides}
    if "experiment" not in keys or "figure" in keys or not trials:
        return
    own = [o for k, o in keys.items() if k == "experiment" or k.startswith(_KEEPS_CONDITIONS)]
    if len(own) == len(keys) or {t["condition"] for t in plan(compose(own))} == {
            t["condition"] for t in trials}:
        return
    changed = " ".join(o for k, o in keys.items() if o not in own)
    figure = trials[0]["figure"]
    raise ConfigError(f"{keys['experiment']} with {changed} would replace figure {figure} (the "
                      f"experiment's own settings) with other settings; name this run: "
                      f"figure={figure}_custom (any plain name)")
