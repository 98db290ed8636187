"""The command line of every stage: check what the overrides compose to, then hand over to Hydra.

Hydra reports a bad override (an unknown option, a value of the wrong type, an unknown key) in
several lines with hints about stack traces, and a bad value in the second job of a sweep only
after the first job ran. Each stage therefore first composes and plans every configuration its
command line can produce (each value of a sweep) with the compose API; a failure is reported as
one line, `error: ...`, with exit status 2, before Hydra or the stage has written anything.
A one-job command line that planned without error, and whose stage then ran, leaves a note (pipeline.planned.checked_marker,
keyed by its config, overrides, config files and code); the same command line again plans
nothing, only the run's own settings (paths, engine) are checked.
"""
from __future__ import annotations

import errno
import itertools
import math
import re
import sys
from contextlib import contextmanager
from pathlib import Path

from hydra.core.override_parser.overrides_parser import OverridesParser

from . import io, stop
from .fingerprint import CodeChanged
from .io import BadInput
from .config import (ConfigError, check_choices, check_experiments, check_hydra, check_keys,
                     compose, config_notes, without_hydra)
from .labels import condition_labels
from .plan import check_run, plan, plan_conditions
from .planned import checked_marker, mark_checked, was_checked

# Hydra's command-line flags that take a value as the next argument
_FLAGS_WITH_VALUE = {"--cfg", "-c", "--config-path", "-cp", "--config-name", "-cn",
                     "--config-dir", "-cd", "--package", "-p", "--info", "-i",
                     "--experimental-rerun"}
# a sweep's jobs composed and planned up front: the first job, then each other value of each
# swept key in turn (the others at their first), at most this many (each compose takes about a
# second); every value of a swept key with a declared range (config.declared) is checked by it
_MAX_COMBINATIONS = 8
MAX_SWEEP_JOBS = 10_000  # jobs of one multirun: each is a Hydra job with its own folder


def sweep_size(override) -> int | None:
    """How many values a sweep override has, counted without building them (a range of 10^8
    values would fill the memory); None for a glob (its size depends on the config)."""
    from hydra.core.override_parser.types import ChoiceSweep, RangeSweep

    v = override.value()
    if isinstance(v, RangeSweep):
        if not v.step:
            return 0
        return max(0, math.ceil((v.stop - v.start) / v.step))
    if isinstance(v, ChoiceSweep):
        return len(v.list)
    return None


def check_sweep_size(parsed) -> str | None:
    """One line when the sweeps of a command line make more than MAX_SWEEP_JOBS jobs."""
    total = 1
    for o in parsed:
        if o.is_sweep_override():
            n = sweep_size(o)
            total *= 1 if n is None else n
            if total > MAX_SWEEP_JOBS:
                return (f"{o.input_line}: the sweep makes more than {MAX_SWEEP_JOBS:,} jobs; "
                        "sweep fewer values (or list the conditions in one experiment)")
    return None


def _overrides(argv: list[str]) -> list[str]:
    out, skip = [], False
    for arg in argv:
        if skip:
            skip = False
        elif arg.startswith("-"):
            skip = arg in _FLAGS_WITH_VALUE
        else:
            out.append(arg)
    return out


def _one_line(err: BaseException) -> str:
    """The innermost message of an exception chain, folded into one line that names the key."""
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


def missing_folder(searchpath) -> str | None:
    """One line when a `file://` folder of hydra.searchpath does not exist (Hydra skips it, and
    the body it should hold surfaces as `body=my_arm: unknown option`)."""
    for entry in searchpath if isinstance(searchpath, list) else [searchpath]:
        entry = str(entry)
        if entry.startswith("file://"):
            folder = Path(entry[len("file://"):])
            if not folder.is_dir():
                return (f"hydra.searchpath: {folder} is not a folder; give the absolute path of "
                        "your config folder (the one that holds body/)")
    return None


def renamed_group(override: str) -> str | None:
    """One line for an override of the group `executor`, which is `engine` now (one name for
    one thing), saying what to write instead; None for any other override."""
    bare = override.lstrip("+~")
    key, _, value = bare.partition("=")
    if key.split(".", 1)[0] != "executor":
        return None
    rest = key.removeprefix("executor").removeprefix(".").removeprefix("slurm").removeprefix(".")
    new = "engine" if rest in ("", "backend") else f"engine.{rest}"
    return (f"{override}: the group executor is named engine now; write "
            f"{override[:len(override) - len(bare)]}{new}={value} (docs/engines.md)")


def empty_config_file(err: BaseException, overrides: list[str]) -> str | None:
    """One line when composing failed on a config file that is empty (a body's learner settings
    from a shell redirect `tool > file` whose command failed: Hydra then says "Key
    'body_learner' not in 'Config'")."""
    from .config import CONF_DIR

    found = re.search(r"In '([\w./-]+)'", str(err))
    if not found:
        return None
    folders = [CONF_DIR, Path.cwd() / "conf"] + [Path(str(e)[len("file://"):]) for o in overrides
                            if o.startswith("hydra.searchpath=")
                            for e in OverridesParser.create().parse_override(o).value()
                            if str(e).startswith("file://")]
    for folder in folders:
        path = folder / f"{found.group(1)}.yaml"
        if path.is_file() and not path.read_text().strip():
            return (f"{path}: the file is empty; write it with `python -m pipeline.tools.rate "
                    "... --write` (a shell redirect `> file` leaves it empty when the command "
                    "fails), or remove it")
    return None


_PASSED: list = []  # (note, trials) of the command line check() passed, for finish() to keep
_MODE: list = []  # [hydra.mode] of the command line check() composed with Hydra's section
_COMPOSED: list = []  # [(what it was composed from, the config)] for Hydra's run (composed_once)


# Hydra's flags that would read config files the check does not compose (a config dir or
# name of one's own: hydra.searchpath is the checked way) or a pickled config (code)
_UNCHECKED_FLAGS = {"--config-path", "-cp", "--config-name", "-cn", "--config-dir", "-cd",
                    "--experimental-rerun"}


def check(argv: list[str], stage=None) -> str | None:
    """None when every configuration of the command line composes, else one line saying why.
    `stage`: the stage's @hydra.main function; a one-job command line is then composed as
    Hydra's run of it composes it (compose_as_run), and the run is given that config instead of
    composing it again (composed_once)."""
    for arg in argv:
        flag = arg.split("=", 1)[0]
        if flag in _UNCHECKED_FLAGS:
            return (f"{arg}: the stages read the project's config and the folders of "
                    "hydra.searchpath=[file://...] only (where every file is checked)")
    overrides = _overrides(argv)
    for o in overrides:
        if not o.isascii() and "LexerNoViableAlt" in (_parse_error(o) or ""):
            key = o.split("=", 1)[0]
            return (f"{o}: Hydra reads characters beyond ASCII only inside quotes; write "
                    f"'{key}=\"{o.split('=', 1)[-1]}\"'")
    try:
        parsed = OverridesParser.create().parse_overrides(overrides)
    except Exception as err:  # a syntax error in an override
        return _one_line(err)
    multirun = "-m" in argv or "--multirun" in argv
    too_many = check_sweep_size(parsed)
    if too_many:
        return too_many
    for o in parsed:  # callbacks, launchers, the searchpath: composed and checked once
        if o.is_hydra_override() and o.is_sweep_override():
            return (f"{o.input_line}: Hydra's own settings take one value per command; "
                    "sweep the stage's keys only")
    for o in parsed:
        renamed = renamed_group(o.input_line)
        if renamed:
            return renamed
    choices, sweeps = [], []
    for o in parsed:
        if o.is_hydra_override():
            if o.get_key_element() == "hydra.searchpath":  # where config groups (a body) live
                missing = missing_folder(o.value())
                if missing:
                    return missing
                choices.append([o.input_line])
            continue  # hydra/launcher=... and hydra.*: Hydra's own settings, checked by Hydra
        if o.is_sweep_override():
            if not multirun:
                return f"{o.input_line}: a sweep over several values needs -m (--multirun)"
            choices.append(itertools.islice(o.sweep_string_iterator(), _MAX_COMBINATIONS))
            choices[-1] = [f"{o.get_key_element()}={v}" for v in choices[-1]]
            sweeps.append(o)
        else:
            choices.append([o.input_line])
    hydra_own = [o.input_line for o in parsed if o.is_hydra_override()
                 and o.get_key_element() != "hydra.searchpath"]
    planned, notes = {}, []
    n_jobs = math.prod(len(c) for c in choices)
    for n, combination in enumerate(itertools.islice(_one_at_a_time(choices),
                                                     _MAX_COMBINATIONS)):
        try:  # values too: every sweep job is checked up front
            if n == 0:  # Hydra's own section: callbacks, launcher, logging, folders (also
                # for a checked command line: a note is never a reason to skip it)
                full = None
                if (stage is not None and n_jobs == 1 and not multirun
                        and list(combination) + hydra_own == overrides):
                    full = compose_as_run(stage, overrides)
                if full is None:
                    full = compose(list(combination) + hydra_own, hydra=True)
                check_hydra(full)
                _MODE[:] = [full.hydra.mode]  # a sweep's values leave it as it is
            # without Hydra's own overrides the config is that composition without its section
            # (what Hydra's compose API returns): one compose, not two (each about 0.2 s CPU)
            cfg = without_hydra(full) if n == 0 and not hydra_own else compose(list(combination))
            # one job checked before with the same config, overrides, config files and code:
            # only the run's own settings (paths, engine) are checked again
            marker = checked_marker(cfg, list(combination) + hydra_own) if n_jobs == 1 else None
            known = was_checked(marker, cfg.paths.root)
            if n == 0:
                check_experiments(cfg, list(combination))
                check_sweep_values(sweeps, cfg)
            check_keys(cfg)
            notes += [n for n in config_notes(cfg) if n not in notes]
            if known:
                check_run(cfg)
                continue
            trials = plan(cfg, remember=n_jobs == 1)  # checks the values, the limits; one job:
            # its stage takes this plan instead of planning again
            check_choices(cfg, list(combination))  # what plan accepts but a user did not mean
            keeps_experiment(list(combination), trials)
            planned.setdefault(cfg.figure, []).extend(trials)
        except ConfigError as err:
            return str(err)
        except Exception as err:
            return empty_config_file(err, list(combination)) or _one_line(err)
    try:
        for trials in planned.values():  # a sweep's jobs make one figure: their labels must differ
            condition_labels(plan_conditions(trials))
    except ConfigError as err:
        return str(err)
    if n_jobs == 1 and not known:  # kept when the stage has run (finish): a refused run writes nothing
        _PASSED[:] = [(marker, trials, cfg.paths.root)]
    for note in notes:
        print(note, file=sys.stderr)
    return None


def _load_key(loader, config_name, overrides, run_mode, from_shell, validate) -> tuple:
    """Everything a Hydra config loader's load_configuration reads that may differ between two
    calls in one process: its arguments, its search path, the job's name, the version base,
    the working directory and the environment (hydra.job.env_copy)."""
    import os

    from hydra import version
    from hydra.core.utils import JobRuntime

    return (config_name, tuple(overrides), run_mode, from_shell, validate,
            tuple((e.provider, e.path) for e in loader.config_search_path.get_path()),
            JobRuntime().get("name"), version.getbase(), os.getcwd(),
            tuple(sorted(os.environ.items())))


def compose_as_run(stage, overrides: list[str]):
    """The config (with Hydra's section) that Hydra's run of `stage` (a @hydra.main function)
    composes for `overrides`: the same Hydra, search path, job name and loader call as
    hydra.main's, so that the run can be given this config instead of a second compose
    (composed_once; about 0.2 s CPU). None where the stage's module cannot be told (then
    compose() is used and the run composes again)."""
    import copy

    from hydra._internal.hydra import Hydra
    from hydra._internal.utils import (create_automatic_config_search_path,
                                       detect_calling_file_or_module_from_task_function,
                                       detect_task_name)
    from hydra.core.global_hydra import GlobalHydra
    from hydra.types import RunMode
    from omegaconf import OmegaConf

    from .config import CONFIG_PATH

    task = getattr(stage, "__wrapped__", None)
    if task is None:
        return None
    calling_file, calling_module = detect_calling_file_or_module_from_task_function(task)
    if calling_file is None and calling_module is None:
        return None
    GlobalHydra.instance().clear()
    try:
        hydra = Hydra.create_main_hydra2(
            task_name=detect_task_name(calling_file, calling_module),
            config_search_path=create_automatic_config_search_path(
                calling_file, calling_module, CONFIG_PATH))
        cfg = hydra.compose_config(config_name="config", overrides=list(overrides),
                                   run_mode=RunMode.RUN, from_shell=True)
        run, given = copy.deepcopy(cfg), list(overrides)  # before the check changes cfg
        if cfg.hydra.mode is None:  # Hydra's run (_run_app) adds hydra.mode=RUN to the
            # overrides, which sets that key and is listed last among Hydra's own overrides
            given.append("hydra.mode=RUN")
            OmegaConf.update(run, "hydra.mode", "RUN", merge=True)
            run.hydra.overrides.hydra.append("hydra.mode=RUN")
        key = _load_key(hydra.config_loader, "config", given, RunMode.RUN, True, True)
    finally:
        GlobalHydra.instance().clear()
    _COMPOSED[:] = [(key, run)]
    return cfg


@contextmanager
def composed_once(composed: list):
    """Hydra's run is given the config check() composed (compose_as_run) when its loader is
    asked for the same thing (_load_key: arguments, search path, job name, working directory,
    environment), once; any other load composes as Hydra does. The run then works on the very
    config that was checked (before, a file saved between the two composes was run unchecked)."""
    from hydra._internal.config_loader_impl import ConfigLoaderImpl

    if not composed:
        yield
        return
    real = ConfigLoaderImpl.load_configuration

    def load(self, config_name, overrides, run_mode, from_shell=True,
             validate_sweep_overrides=True):
        if composed and composed[0][0] == _load_key(self, config_name, overrides, run_mode,
                                                     from_shell, validate_sweep_overrides):
            return composed.pop()[1]
        return real(self, config_name=config_name, overrides=overrides, run_mode=run_mode,
                    from_shell=from_shell, validate_sweep_overrides=validate_sweep_overrides)

    ConfigLoaderImpl.load_configuration = load
    try:
        yield
    finally:
        ConfigLoaderImpl.load_configuration = real
        composed.clear()


def _one_at_a_time(choices: list[list[str]]):
    """The first combination, then each other value of each choice with the rest at their
    first: every value is in some combination (the product's first ones hold one value of the
    first key only)."""
    first = [c[0] for c in choices]
    yield tuple(first)
    for i, c in enumerate(choices):
        for v in c[1:]:
            yield tuple(first[:i] + [v] + first[i + 1:])


def _sweep_values(o):
    """The typed values of sweep override `o`, lazily (a range's numbers are computed)."""
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
    """ConfigError for the first value of a sweep outside its key's declared range
    (config.declared): every job's value is checked, not only the composed ones'."""
    from .config import declared

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
    """ConfigError when `experiment=E` with other settings would replace E's figure: the run
    must then name its own figure (figure=NAME), so that E's stays as the experiment made it."""
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


def hydra_run() -> tuple[list[str], str | None, int]:
    """(the command line's overrides, the multirun group, the job's number) of the running Hydra
    job; ([], None, 0) outside @hydra.main. A multirun's jobs share its sweep folder, so their
    plan records make one figure together."""
    import hashlib

    from hydra.core.hydra_config import HydraConfig
    from hydra.types import RunMode

    try:
        hc = HydraConfig.get()
    except ValueError:
        return [], None, 0
    overrides = list(hc.overrides.task)
    if hc.mode != RunMode.MULTIRUN:
        return overrides, None, 0
    group = "sweep-" + hashlib.sha256(str(hc.sweep.dir).encode()).hexdigest()[:16]
    return overrides, group, int(hc.job.num)


def _parse_error(override: str) -> str | None:
    try:
        OverridesParser.create().parse_overrides([override])
    except Exception as err:
        return type(err.__cause__ or err).__name__ + str(err)
    return None


# what a full disk, a read-only folder or a missing permission raise: a fault of the place, named
DISK_ERRNOS = (errno.ENOSPC, errno.EROFS, errno.EACCES, errno.EPERM, errno.EDQUOT)


def finish(run, cfg, record: bool = True) -> None:
    """Run a stage on its composed config and exit with its status (record=False: a tool that
    only reads and prints leaves no config snapshot and no checked-plan note behind). What every stage can meet
    is one line: a bad value (ConfigError), missing or damaged input (FileNotFoundError,
    pipeline.io's BadInput: DamagedFile, UnsafeName), gbmodel code edited since the import
    (CodeChanged) or a full, read-only or forbidden folder (OSError) exits 2; Ctrl-C, SIGTERM and SIGHUP stop the workers, release the claims (the stage's
    `finally`) and exit 130, 143, 129 (finished trials are cached: the same command resumes)."""
    with stop.armed():
        try:  # no write or delete through a link leading elsewhere
            io.confine(cfg.paths.root if cfg is not None else None)
            rc = run(cfg)
            if rc in (0, 1) and record:  # it ran (1: some trials failed or inputs are missing)
                snapshot(cfg)
        except (ConfigError, FileNotFoundError, NotADirectoryError) as err:
            print(f"error: {err}", file=sys.stderr)
            rc = 2
        except (BadInput, CodeChanged) as err:  # a damaged file or unsafe name; edited code
            print(f"error: {err}", file=sys.stderr)
            rc = 2
        except OSError as err:
            if err.errno not in DISK_ERRNOS:
                raise
            print(f"error: {disk_message(err)}", file=sys.stderr)
            rc = 2
        except MemoryError:
            print("error: out of memory; run fewer workers or shorter trials", file=sys.stderr)
            rc = 2
        except KeyboardInterrupt as err:
            from . import execute  # (its process pools: not imported by a stage that has none)

            execute.stop_pools()
            how = "interrupted" if not isinstance(err, stop.Stopped) else f"stopped by {err}"
            print(f"{how}: finished work is cached; run the same command again to resume",
                  file=sys.stderr, flush=True)
            rc = stop.exit_status(err)
        finally:
            io.confine(None)
    if rc in (0, 1) and record:  # the stage ran (1: some trials failed or inputs are missing)
        for marker, trials, root in _PASSED:
            mark_checked(marker, trials, root)
    _PASSED.clear()
    if rc:
        sys.exit(rc)


def snapshot(cfg):
    """Keep the config this run composed (resolved: every path as used) and its command-line
    overrides, Hydra's layout: .hydra/config.yaml and .hydra/overrides.yaml under
    paths.out/logs/<stage>/<time>_<tag>/, a multirun job's in its folder of the sweep. Written
    after the stage ran, so a refused run writes nothing; None outside @hydra.main (the API)."""
    import time

    from hydra.core.hydra_config import HydraConfig
    from hydra.types import RunMode
    from omegaconf import OmegaConf

    from .config import sweep_tag

    if cfg is None or not HydraConfig.initialized():
        return None
    hc = HydraConfig.get()
    folder = Path(hc.runtime.output_dir).resolve()
    if hc.mode != RunMode.MULTIRUN or not folder.is_relative_to(Path(cfg.paths.root).resolve()):
        folder = (Path(cfg.paths.out) / "logs" / hc.job.name
                  / f"{time.strftime('%Y-%m-%d_%H-%M-%S')}_{sweep_tag()}")
    try:
        text = OmegaConf.to_yaml(cfg, resolve=True)
    except Exception:  # an interpolation only a later stage can resolve: kept as written
        text = OmegaConf.to_yaml(cfg)
    io.write_text(folder / ".hydra" / "config.yaml", text)
    io.write_text(folder / ".hydra" / "overrides.yaml",
                  OmegaConf.to_yaml(list(hc.overrides.task)))
    return folder


def disk_message(err: OSError) -> str:
    """One line for an OSError of the file system, naming the path."""
    where = err.filename if err.filename is not None else "a file"
    why = {errno.ENOSPC: "no space left on the device", errno.EDQUOT: "disk quota exceeded",
           errno.EROFS: "read-only file system", errno.EACCES: "permission denied",
           errno.EPERM: "operation not permitted"}[err.errno]
    return f"{where}: {why}; free space or choose a writable paths.root"


# config groups a user does not choose: body_learner follows body and learner; paths and
# trials have one option each (their values are overridden key by key)
_INTERNAL_GROUPS = ("body_learner", "hydra", "paths", "trials")


def user_groups(overrides: list[str] = ()) -> dict[str, list[str]]:
    """group -> the options a user can choose (conf/ and the folders of hydra.searchpath among
    `overrides`): no internal group, no generated `<learner>_schema` a learner's file extends."""
    from hydra import compose as hydra_compose
    from hydra.core.global_hydra import GlobalHydra

    from .config import initialized

    search = [o for o in overrides if o.startswith("hydra.searchpath=")]
    with initialized():  # the stages' configs: a checkout's conf/ or the installed package
        hydra_compose(config_name="config", overrides=search)
        loader = GlobalHydra.instance().config_loader()
        return {g: [o for o in sorted(loader.get_group_options(g)) if not o.endswith("_schema")]
                for g in sorted(loader.list_groups("")) if g not in _INTERNAL_GROUPS}


def help_text(stage: str, argv: list[str]) -> str:
    """What `--help` prints: the stage, the groups and their options a user can choose, and the
    config the command line composes to (Hydra's own help listed the internal schemas too)."""
    from omegaconf import OmegaConf

    overrides = _overrides(argv)
    lines = [f"python -m {stage} [group=option ...] [key=value ...] [-m for a sweep]", "",
             "== Configuration groups (group=option) ==", ""]
    lines += [f"{g}: {', '.join(opts)}" for g, opts in user_groups(overrides).items()]
    lines += ["", "A body's learner settings (body_learner) follow body= and learner=; "
              "hydra.searchpath=[file:///abs/my_conf] adds your own folder of bodies.", "",
              "== Config (override any key: foo.bar=value) ==", ""]
    try:
        cfg = compose(overrides)
    except Exception:  # a bad override: the defaults (the stage itself names the problem)
        cfg = compose([])
    lines.append(OmegaConf.to_yaml(cfg).rstrip())
    lines += ["", "Hydra's own flags: --hydra-help"]
    return "\n".join(lines) + "\n"


def main(hydra_main) -> None:
    """Run a stage's @hydra.main function after checking its command line. A signal before the
    stage runs ends the process with one line (pipeline.stop). `--help` prints help_text."""
    stop.install()
    if "--help" in sys.argv[1:] or "-h" in sys.argv[1:]:
        import __main__

        spec = getattr(__main__, "__spec__", None)
        stage = spec.name if spec else "pipeline"
        if getattr(hydra_main, "__module__", "__main__") != "__main__":  # `gbgrowth <stage>`
            stage = hydra_main.__module__
        text = help_text(stage, sys.argv[1:])
        if sys.argv[0].startswith("gbgrowth "):  # as typed (pipeline.__main__ sets argv[0])
            text = text.replace(f"python -m {stage}", sys.argv[0], 1)
        sys.stdout.write(text)
        sys.exit(0)
    _COMPOSED.clear()
    problem = check(sys.argv[1:], hydra_main)
    if problem is not None:
        print(f"error: {problem}", file=sys.stderr)
        sys.exit(2)
    with known_mode(_MODE), composed_once(_COMPOSED):
        hydra_main()


@contextmanager
def known_mode(mode: list):
    """Hydra's start composes the whole config once only to read hydra.mode (Hydra.get_mode),
    then again to run it. check() composed the same command line with Hydra's section (hydra.*
    overrides included; a sweep's values cannot change the mode): Hydra is given that mode
    instead of a third compose (about 0.2 s CPU per stage). `mode` empty: Hydra composes."""
    from hydra._internal.hydra import Hydra

    if not mode:
        yield
        return
    real = Hydra.get_mode
    Hydra.get_mode = lambda self, config_name, overrides: mode[0]
    try:
        yield
    finally:
        Hydra.get_mode = real
