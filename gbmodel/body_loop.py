"""A body in the loop: a forward function the project cannot compile (a simulator, a robot),
`factory(**args)` -> forward(angles (N, m) [rad], factors (m,)) -> (N, 3) [m] (docs/bodies.md,
"A body in the loop"). Only a factory its author marked with `gbmodel.body_factory` is called;
describing or validating a body imports and calls nothing; the import and first call are tried
in a child process within TIME_LIMIT seconds first.
"""
from __future__ import annotations

import functools
import hashlib
import importlib
import inspect
import json
import os
import signal
import subprocess
import sys
import tempfile
from functools import lru_cache
from pathlib import Path
from typing import Protocol

import numpy as np

from .urdf import MAX_MAGNITUDE, _bad as _urdf_bad, read_bytes

KEYS = ("factory", "args", "files", "lengths", "version", "sha256")
_bad = functools.partial(_urdf_bad, kind="callable")


class Forward(Protocol):
    def __call__(self, angles: np.ndarray, factors: np.ndarray) -> np.ndarray: ...


def check(section) -> dict:
    if not isinstance(section, dict) or "factory" not in section or not set(section) <= set(KEYS):
        raise ValueError(f"body.callable={section!r}: needs factory (and optionally "
                         f"{', '.join(KEYS[1:])})")
    factory = section["factory"]
    if not isinstance(factory, str) or factory.count(":") != 1 or not all(factory.split(":")):
        raise _bad("factory", factory, "give module:attribute, e.g. my_robot.sim:make_forward")
    _parts(factory)
    if not isinstance(section.get("args", {}) or {}, dict):
        raise _bad("args", section["args"], "a mapping of keyword arguments")
    files = section.get("files", []) or []
    if not isinstance(files, (list, tuple)) or not all(isinstance(f, str) for f in files):
        raise _bad("files", files, "a list of paths")
    try:
        json.dumps(section.get("args", {}) or {}, sort_keys=True, allow_nan=False)
    except (TypeError, ValueError):
        raise _bad("args", section["args"], "plain data (numbers, strings, lists, mappings)") \
            from None
    return section


MARK = "__gbmodel_body_factory__"  # set by body_factory on the function its author marks
TIME_LIMIT = 60.0  # seconds: a factory's import and first call, in a child process


def body_factory(func):
    """Mark `func` (a decorator) as the one kind of function `callable.factory` may name."""
    if not callable(func):
        raise TypeError(f"body_factory marks a function, not {type(func).__name__}")
    setattr(func, MARK, True)
    return func


def _parts(factory: str) -> tuple[str, str]:
    module, attr = factory.split(":")
    if not all(p.isidentifier() for p in module.split(".") + attr.split(".")):
        raise _bad("factory", factory, "give module:attribute, e.g. my_robot.sim:make_forward")
    top = module.split(".")[0]
    if top in sys.stdlib_module_names or top in sys.builtin_module_names:
        raise _bad("factory", factory, f"{top} is the standard library; only a function marked "
                   "@gbmodel.body_factory by its author is called")
    return module, attr


def _marked(mod, attr: str, factory: str):
    """`attr` of `mod`, looked up without running code, if its author marked it."""
    obj = mod
    for part in attr.split("."):
        obj = inspect.getattr_static(obj, part, None)
    if not callable(obj):
        raise _bad("factory", factory, f"{mod.__name__} has no callable {attr}")
    if inspect.getattr_static(obj, MARK, None) is not True:
        raise _bad("factory", factory, "not marked as a body factory by its author (decorate "
                   "it with @gbmodel.body_factory); nothing was called")
    return obj


# run in a child process: import, check the mark without calling, call once, say how it went
_PROBE = """
import importlib, json, os, sys
factory, args, answer = sys.argv[1], json.loads(sys.argv[2]), sys.argv[4]
sys.path[:] = json.loads(sys.argv[3])
from gbmodel import body_loop
module, attr = body_loop._parts(factory)
def line(err):
    return (f"{type(err).__name__}: {err}".splitlines() or [""])[0][:300]
try:
    mod = importlib.import_module(module)
except BaseException as err:
    said = ["error", f"cannot import {module}: {line(err)}"]
else:
    try:
        make = body_loop._marked(mod, attr, factory)
    except ValueError as err:
        said = ["refused", str(err)]
    else:
        try:
            said = ["ok" if callable(make(**args)) else "not callable"]
        except BaseException as err:
            said = ["error", line(err)]
with open(answer + ".tmp", "w") as fh:
    fh.write(json.dumps(said))
os.replace(answer + ".tmp", answer)
os._exit(0)
"""


@lru_cache(maxsize=16)
def _probe(factory: str, args_json: str) -> None:
    """Import and call the factory once in a child process within TIME_LIMIT seconds; ValueError
    (one line) if it hangs, ends the process, raises or finds no mark."""
    gb = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))  # where gbmodel is
    with tempfile.TemporaryDirectory(prefix="gbmodel-probe-") as folder:
        answer = os.path.join(folder, "verdict.json")
        proc = subprocess.Popen([sys.executable, "-c", _PROBE, factory, args_json,
                                 json.dumps([gb, *sys.path]), answer], stdin=subprocess.DEVNULL,
                                stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                                start_new_session=True)
        try:
            proc.wait(timeout=TIME_LIMIT)
        except subprocess.TimeoutExpired:
            raise _bad("factory", factory, f"importing its module and calling it did not "
                       f"finish in {TIME_LIMIT:g} s") from None
        finally:  # the child and whatever it started (its session's group)
            try:
                os.killpg(proc.pid, signal.SIGKILL)
            except ProcessLookupError:
                pass
            proc.wait()
        said = Path(answer).read_text() if os.path.exists(answer) else ""
    if not said:
        raise _bad("factory", factory, "importing its module or calling it ended the process "
                   f"(exit status {proc.returncode}) without a word")
    verdict = json.loads(said)
    if verdict[0] == "refused":
        raise ValueError(verdict[1])
    if verdict[0] == "error":
        raise _bad("factory", factory, verdict[1])
    if verdict[0] != "ok":
        raise _bad("factory", factory, "must return the forward function (a callable)")


def _object(factory: str, args_json: str):
    module, attr = _parts(factory)
    _probe(factory, args_json)
    try:
        mod = importlib.import_module(module)
    except (Exception, SystemExit) as err:  # the user's module: any error importing it is one line
        raise _bad("factory", factory, f"cannot import {module}: {type(err).__name__}: "
                   f"{err}".splitlines()[0]) from None
    return mod, _marked(mod, attr, factory)


@lru_cache(maxsize=16)
def _load(factory: str, args_json: str):
    _, make = _object(factory, args_json)
    try:
        forward = make(**json.loads(args_json))
    except (Exception, SystemExit) as err:
        raise _bad("factory", factory, f"{type(err).__name__}: {err}".splitlines()[0]) from None
    if not callable(forward):
        raise _bad("factory", factory, "must return the forward function (a callable)")
    return forward


def _args(section: dict) -> str:
    return json.dumps(section.get("args") or {}, sort_keys=True)


class Deferred:
    """The section's forward function, loaded at its first call: a body described or loaded
    imports nothing."""

    def __init__(self, section: dict):
        self.section = section

    def __call__(self, angles: np.ndarray, factors: np.ndarray) -> np.ndarray:
        return _load(self.section["factory"], _args(self.section))(angles, factors)


def digest(section: dict) -> str:
    """The SHA-256 of the factory's name, its module's source file and its declared files."""
    check(section)
    mod, _ = _object(section["factory"], _args(section))
    h = hashlib.sha256(section["factory"].encode() + b"\0")
    try:
        source = inspect.getsourcefile(mod)
    except TypeError:  # a built-in or compiled module: no source to hash
        source = None
    if source is None:
        raise _bad("factory", section["factory"], f"module {mod.__name__} has no Python source "
                   "file to hash into the cache key; wrap the function in a module of your own")
    for path, kind in [(source, "module"), *((f, "file") for f in section.get("files") or ())]:
        try:
            data = read_bytes(path, "callable")
        except ValueError as err:
            raise _bad("files" if kind == "file" else "factory", path,
                       str(err).split(": ", 1)[-1]) from None
        h.update(kind.encode() + b"\0" + len(data).to_bytes(8, "little") + data)
    return h.hexdigest()


def positions(forward: Forward, angles: np.ndarray, factors: np.ndarray, name: str) -> np.ndarray:
    flat = np.ascontiguousarray(angles, dtype=np.float64).reshape(-1, angles.shape[-1])
    out = np.asarray(forward(flat, np.array(factors, np.float64)), dtype=np.float64)
    if out.shape != (len(flat), 3):
        raise ValueError(f"body {name!r}: its forward function returned shape {out.shape} for "
                         f"{len(flat)} postures; the protocol wants ({len(flat)}, 3)")
    if not np.all(np.abs(out) <= MAX_MAGNITUDE):  # NaN fails too
        bad = out[~(np.abs(out) <= MAX_MAGNITUDE)][0]
        raise ValueError(f"body {name!r}: its forward function returned the position {bad:g}; "
                         f"positions are finite metres within +-{MAX_MAGNITUDE:g}, as a URDF's")
    return out.reshape(angles.shape[:-1] + (3,))
