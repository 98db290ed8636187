"""A body in the loop: a forward function that the project cannot compile (a simulator's step, a
robot's sensors), called with a batch of postures and the body's growth, returning positions.

The body's description names a factory and its arguments instead of a chain
(conf/body/<name>.yaml, docs/bodies.md "A body in the loop"):

    callable:
      factory: my_package.sim:make_forward   # module:attribute, importable by every worker
      args: {model: /path/to/robot.xml}      # keyword arguments of the factory (plain data)
      files: [/path/to/robot.xml]            # files it reads: their bytes join the cache key
      lengths: [0.3, 0.25, 0.1]              # per segment [m], what growth patterns weigh
      version: "1"                           # what else it depends on: change it to recompute

`factory(**args)` is called once per process and description and returns a Forward:

    forward(angles, factors) -> positions
        angles  (N, m) float64: the joint angles [rad] of N postures (the commands, normalised
                onto the limits and saturated as for every body)
        factors (m,)   float64: per-segment length factors, 1 at full size (growth)
        returns (N, 3) float64: the hand's positions [m] in the body's root frame

The body then controls `outputs` of these coordinates, as every body does. Only the numpy
reference path of a learner calls Python per batch: a callable body takes `learner.fast=false`.

What the cache key holds (`callable.sha256`, added when a run is planned): the factory's name,
the bytes of the source file of the module that defines it, and the bytes of every file in
`files`, besides the description itself (args, lengths, version). What it does not hold: other
modules the function imports, the simulator's version, a robot's state. When one of those
changes, change `version` (or clear the cache), or the old trials are reused.
"""
from __future__ import annotations

import hashlib
import importlib
import inspect
import json
from functools import lru_cache
from typing import Protocol

import numpy as np

from .urdf import read_bytes

KEYS = ("factory", "args", "files", "lengths", "version", "sha256")


class Forward(Protocol):
    """The forward function of a body in the loop (module docstring)."""

    def __call__(self, angles: np.ndarray, factors: np.ndarray) -> np.ndarray: ...


def _bad(key, value, why):
    return ValueError(f"body.callable.{key}={value!r}: {why}")


def check(section) -> dict:
    """The `callable` section with its keys checked (one line naming body.callable.<key>)."""
    if not isinstance(section, dict) or "factory" not in section or not set(section) <= set(KEYS):
        raise ValueError(f"body.callable={section!r}: needs factory (and optionally "
                         f"{', '.join(KEYS[1:])})")
    factory = section["factory"]
    if not isinstance(factory, str) or factory.count(":") != 1 or not all(factory.split(":")):
        raise _bad("factory", factory, "give module:attribute, e.g. my_robot.sim:make_forward")
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


def _object(factory: str):
    module, attr = factory.split(":")
    try:
        mod = importlib.import_module(module)
    except Exception as err:  # the user's module: any error importing it is one line
        raise _bad("factory", factory, f"cannot import {module}: {type(err).__name__}: "
                   f"{err}".splitlines()[0]) from None
    obj = mod
    for part in attr.split("."):
        obj = getattr(obj, part, None)
    if not callable(obj):
        raise _bad("factory", factory, f"{module} has no callable {attr}")
    return mod, obj


@lru_cache(maxsize=16)
def _load(factory: str, args_json: str):
    _, make = _object(factory)
    try:
        forward = make(**json.loads(args_json))
    except Exception as err:
        raise _bad("factory", factory, f"{type(err).__name__}: {err}".splitlines()[0]) from None
    if not callable(forward):
        raise _bad("factory", factory, "must return the forward function (a callable)")
    return forward


def load(section: dict) -> Forward:
    """The forward function of a checked `callable` section (one per process and description)."""
    return _load(section["factory"], json.dumps(section.get("args") or {}, sort_keys=True))


def digest(section: dict) -> str:
    """The SHA-256 of what the key holds of the function: its factory's name, the source file of
    the module defining it, and the files it declares (module docstring)."""
    check(section)
    mod, _ = _object(section["factory"])
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
    """forward(angles, factors) for angles (..., m), checked: (..., 3) finite floats."""
    flat = np.ascontiguousarray(angles, dtype=np.float64).reshape(-1, angles.shape[-1])
    out = np.asarray(forward(flat, np.array(factors, np.float64)), dtype=np.float64)
    if out.shape != (len(flat), 3):
        raise ValueError(f"body {name!r}: its forward function returned shape {out.shape} for "
                         f"{len(flat)} postures; the protocol wants ({len(flat)}, 3)")
    if not np.all(np.isfinite(out)):
        raise ValueError(f"body {name!r}: its forward function returned a non-finite position")
    return out.reshape(angles.shape[:-1] + (3,))
