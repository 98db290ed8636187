"""The command line of every stage: check what the overrides compose to, then hand over to Hydra.

Hydra reports a bad override (an unknown option, a value of the wrong type, an unknown key) in
several lines with hints about stack traces, and a bad value in the second job of a sweep only
after the first job ran. Each stage therefore first composes and plans every configuration its
command line can produce (each value of a sweep) with the compose API; a failure is reported as
one line, `error: ...`, with exit status 2, before Hydra or the stage has written anything.
"""
from __future__ import annotations

import itertools
import re
import sys

from hydra.core.override_parser.overrides_parser import OverridesParser

from .config import ConfigError, compose
from .plan import plan

# Hydra's command-line flags that take a value as the next argument
_FLAGS_WITH_VALUE = {"--cfg", "-c", "--config-path", "-cp", "--config-name", "-cn",
                     "--config-dir", "-cd", "--package", "-p", "--info", "-i",
                     "--experimental-rerun"}
_MAX_COMBINATIONS = 256  # a sweep larger than this is checked on its first combinations only


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


def check(argv: list[str]) -> str | None:
    """None when every configuration of the command line composes, else one line saying why."""
    try:
        parsed = OverridesParser.create().parse_overrides(_overrides(argv))
    except Exception as err:  # a syntax error in an override
        return _one_line(err)
    multirun = "-m" in argv or "--multirun" in argv
    choices = []
    for o in parsed:
        if o.is_hydra_override():
            if o.get_key_element() == "hydra.searchpath":  # where config groups (a body) live
                choices.append([o.input_line])
            continue  # hydra/launcher=... and hydra.*: Hydra's own settings, checked by Hydra
        if o.is_sweep_override():
            if not multirun:
                return f"{o.input_line}: a sweep over several values needs -m (--multirun)"
            choices.append([f"{o.get_key_element()}={v}" for v in o.sweep_string_iterator()])
        else:
            choices.append([o.input_line])
    for combination in itertools.islice(itertools.product(*choices), _MAX_COMBINATIONS):
        try:
            plan(compose(list(combination)))  # values too: every sweep job is checked up front
        except ConfigError as err:
            return str(err)
        except Exception as err:
            return _one_line(err)
    return None


def finish(run, cfg) -> None:
    """Run a stage on its composed config and exit with its status. What every stage can meet
    is one line: a bad value (ConfigError) or missing input (FileNotFoundError) exits 2, Ctrl-C
    exits 130 (finished trials are cached, so the same command resumes)."""
    try:
        rc = run(cfg)
    except (ConfigError, FileNotFoundError, NotADirectoryError) as err:
        print(f"error: {err}", file=sys.stderr)
        rc = 2
    except MemoryError:
        print("error: out of memory; run fewer workers or shorter trials", file=sys.stderr)
        rc = 2
    except KeyboardInterrupt:
        print("interrupted: finished work is cached; run the same command again to resume",
              file=sys.stderr)
        rc = 130
    if rc:
        sys.exit(rc)


def main(hydra_main) -> None:
    """Run a stage's @hydra.main function after checking its command line."""
    problem = check(sys.argv[1:])
    if problem is not None:
        print(f"error: {problem}", file=sys.stderr)
        sys.exit(2)
    hydra_main()
