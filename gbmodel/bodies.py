"""Bodies as data: a description (conf/body/<name>.yaml, docs/bodies.md) read into a Body."""
from __future__ import annotations

import importlib.util
import re
from dataclasses import MISSING, dataclass, field, fields
from pathlib import Path
from types import SimpleNamespace
from typing import Any, Optional

import numpy as np
import yaml

from .body import Body, _grid, cell_centres, grid_points, unreachable  # noqa: F401 (the face)
from .spec import Choice, Flag, Free, Maybe, Members, Record, Text, check_fields
from .urdf import MAX_MAGNITUDE


@dataclass(frozen=True)
class Grid:
    lo: list[float]
    hi: list[float]
    num: list[int]


@dataclass(frozen=True, kw_only=True)
class Description:
    """The fields of conf/body/<name>.yaml (the pipeline's BodyConf is generated from them)."""

    name: str  # what the trials are labelled with
    description: str = ""
    units: str = "rad"  # rad | deg: of alpha, theta offset and limits
    dh: Optional[list[Any]] = None  # per joint (a [m], d [m], alpha, theta offset)
    urdf: Optional[dict[str, Any]] = None  # or a URDF's chain: {file, root, tip, joints, hold}
    mjcf: Optional[dict[str, Any]] = None  # or an MJCF model's: {file, root, tip, joints, hold}
    callable: Optional[dict[str, Any]] = None  # or a forward function: {factory, args, ...}
    base: list[Any] = field(default_factory=lambda: [[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0],
                                                     [0.0, 0.0, 1.0, 0.0]])
    hand: list[float] = field(default_factory=lambda: [0.0, 0.0, 0.0])
    outputs: list[int]  # controlled hand coordinates (0 x, 1 y, 2 z)
    limits: Optional[list[Any]] = None  # per joint [min, max]
    normalise: bool = False  # commands in [-1, 1] onto the limits (true) or radians (false)
    saturate: bool = True  # normalised commands clipped at the limits
    home: list[float]  # the home posture, command units
    grid: Grid  # the target grid at full size
    grows: Optional[list[bool]] = None  # per segment: grows under non-proportional growth
    # a third-party model's credit, {model, source, licence}, listed in the reports using it
    credits: Optional[dict[str, str]] = None


FIELDS = tuple(f.name for f in fields(Description))
CHAINS = ("dh", "urdf", "mjcf", "callable")  # the fields of which a body gives exactly one
CREDITS = ("model", "source", "licence")  # the fields of a body's credits
UNITS = {"rad": 1.0, "deg": None}  # deg: np.deg2rad (the same bits as the tables' conversion)
# body_from checks the Free ones against the chain
LIMITS = dict(
    name=Text(), units=Choice(*UNITS), description=Free("any text"),
    base=Free("3 x 4 numbers"), hand=Free("3 numbers"),
    dh=Free("m rows of 4"), urdf=Free("{file, root, tip, ...}"),
    mjcf=Free("{file, root, tip, ...}"), callable=Free("{factory, ...}"),
    outputs=Members(0, 1, 2, what="hand coordinates"), normalise=Flag(),
    limits=Free("m rows [min, max]"), saturate=Flag(), home=Free("m numbers"),
    grid=Free("{lo, hi, num}"), grows=Free("m values true/false"),
    credits=Maybe(Record(*CREDITS)))
CONF_PACKAGE = "gbgrowth_conf"  # conf/ installed from a wheel (pyproject.toml: package-dir)


def conf_dir() -> Path:
    """conf/ of the checkout beside this package, else the installed gbgrowth_conf."""
    checkout = Path(__file__).resolve().parents[1]
    if (checkout / "pyproject.toml").is_file() and (checkout / "conf" / "config.yaml").is_file():
        return checkout / "conf"
    spec = importlib.util.find_spec(CONF_PACKAGE)
    if spec is None or not spec.submodule_search_locations:  # neither: no body is shipped
        return checkout / "conf"
    return Path(list(spec.submodule_search_locations)[0])


CONF_DIR = conf_dir()
SHIPPED = CONF_DIR / "body"  # the shipped descriptions


class _Loader(yaml.SafeLoader):
    """YAML 1.2 floats (1e-3 without a dot), as Hydra reads the same files."""


_Loader.add_implicit_resolver(
    "tag:yaml.org,2002:float",
    re.compile(r"""^(?:[-+]?(?:[0-9][0-9_]*)\.[0-9_]*(?:[eE][-+]?[0-9]+)?
                   |[-+]?(?:[0-9][0-9_]*)(?:[eE][-+]?[0-9]+)
                   |\.[0-9_]+(?:[eE][-+][0-9]+)?
                   |[-+]?\.(?:inf|Inf|INF)|\.(?:nan|NaN|NAN))$""", re.X),
    list("-+0123456789."))


def shipped() -> tuple:
    return tuple(sorted(p.stem for p in SHIPPED.glob("*.yaml")))


def read_description(name: str) -> dict:
    path = SHIPPED / f"{name}.yaml"
    if not isinstance(name, str) or "/" in name or not path.is_file():
        raise ValueError(f"body.name={name!r}: unknown body; choose one of {list(shipped())} "
                         "or give the whole description (docs/bodies.md)")
    try:
        data = yaml.load(path.read_text(), Loader=_Loader)
    except (OSError, yaml.YAMLError) as err:
        raise ValueError(f"body.name={name!r}: cannot read {path}: {err}".splitlines()[0]) from None
    if not isinstance(data, dict):
        raise ValueError(f"body.name={name!r}: {path} does not hold a mapping")
    return data


def _bad(key, value, why):
    return ValueError(f"body.{key}={value!r}: {why}")


def _matrix(desc, key, rows, cols, default=None):
    value = desc.get(key, default)
    try:
        arr = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise _bad(key, value, "must be a list of numbers") from None
    if arr.ndim != (1 if cols is None else 2) or (rows is not None and len(arr) != rows) or (
            cols is not None and arr.shape[1] != cols) or not np.all(np.abs(arr) <= MAX_MAGNITUDE):
        shape = f"{rows if rows is not None else 'm'} rows of {cols}" if cols else f"{rows} values"
        raise _bad(key, value, f"needs {shape} finite numbers within +-{MAX_MAGNITUDE:g} "
                   "(metres, angles)")
    return arr


def body_from(desc: dict) -> Body:
    """A Body from a whole description; ValueError naming `body.<key>`."""
    unknown = sorted(set(desc) - set(FIELDS))
    if unknown:
        raise _bad(unknown[0], desc[unknown[0]], f"unknown key; a body has {list(FIELDS)}")
    desc = {**{f.name: None if f.default is MISSING and f.default_factory is MISSING
                else f.default if f.default_factory is MISSING else f.default_factory()
                for f in fields(Description)},
            **desc}  # the defaults of the fields not given (None: a field that must be given)
    check_fields(SimpleNamespace(**desc), "body", LIMITS)
    name, units, outputs = desc["name"], desc["units"], desc["outputs"]
    normalise, saturate = desc["normalise"], desc["saturate"]
    angle = np.deg2rad if units == "deg" else (lambda x: x)
    base = _matrix(desc, "base", 3, 4, np.hstack([np.eye(3), np.zeros((3, 1))]).tolist())
    hand = _matrix(desc, "hand", 3, None, [0.0, 0.0, 0.0])
    chains = [k for k in CHAINS if desc.get(k) is not None]
    if len(chains) != 1:
        raise _bad(chains[1] if chains else "dh", desc.get(chains[1] if chains else "dh"),
                   "a body needs its chain, one of: dh rows (a, d, alpha, theta offset), "
                   "urdf: {file, root, tip}, mjcf: {file, root, tip} or callable: {factory}")
    general, loop = {}, {}
    if chains[0] in ("urdf", "mjcf"):
        general, urdf_limits = _file_chain(chains[0], desc[chains[0]], base, hand)
        m = len(general["frames"])
        dh = np.zeros((m, 4))
    elif chains[0] == "callable":
        m = len(_matrix(desc, "home", None, None))  # a function's joints: home's length
        if m < 1:
            raise _bad("home", desc["home"], "needs at least one joint")
        loop = _loop(desc["callable"], m, base, hand)
        dh = np.zeros((m, 4))
    else:
        dh = _matrix(desc, "dh", None, 4)
        m = len(dh)
        if m < 1:
            raise _bad("dh", desc["dh"], "needs at least one joint")
        if np.any(hand != 0):
            raise _bad("hand", desc["hand"], "a DH body's hand is the last frame's origin: fold "
                       "the offset into the last row's a (along x) and d (along z)")
    q_min = q_max = None
    if normalise:
        if desc.get("limits") is None and general and np.all(np.isfinite(urdf_limits)):
            limits = urdf_limits  # the URDF's own [[lower, upper]] [rad]
        elif desc.get("limits") is None:
            raise _bad("limits", None, "normalise: true maps commands onto the joint limits; "
                       "give [min, max] per joint" + (f" (the {chains[0].upper()} has none for "
                                                      "some joints)" if general else ""))
        else:
            limits = angle(_matrix(desc, "limits", m, 2))
        if np.any(limits[:, 1] <= limits[:, 0]):
            raise _bad("limits", desc.get("limits"), "need min < max per joint")
        q_min, q_max = limits[:, 0].copy(), limits[:, 1].copy()
    elif desc.get("limits") is not None:
        raise _bad("limits", desc["limits"], "only normalise: true uses joint limits; set it, or "
                   "limits: null")
    home = _matrix(desc, "home", m, None)
    grid = desc.get("grid")
    if not isinstance(grid, dict) or set(grid) != {"lo", "hi", "num"}:
        raise _bad("grid", grid, "needs {lo, hi, num}, one entry per controlled coordinate")
    try:
        targets = grid_points(**grid)
    except (TypeError, ValueError) as err:
        raise _bad("grid", grid, str(err)) from None
    if targets.shape[1] != len(outputs):
        raise _bad("grid", grid, f"{name} controls {len(outputs)} coordinate(s)")
    grows = desc.get("grows")
    grows = [True] * m if grows is None else grows  # default: every segment grows
    if (not isinstance(grows, (list, tuple)) or len(grows) != m
            or not all(isinstance(g, bool) for g in grows)):
        raise _bad("grows", grows, f"needs {m} values true/false, one per segment")
    return Body(
        name=name, a=dh[:, 0].copy(), d=dh[:, 1].copy(), alpha=angle(dh[:, 2]),
        theta_offset=angle(dh[:, 3]), base=base, outputs=tuple(int(k) for k in outputs),
        home=home, targets=targets, growing=np.asarray(grows, bool), q_min=q_min, q_max=q_max,
        saturates=saturate, description=str(desc.get("description", "")), **general, **loop,
    )


def _file_chain(kind, section, base, hand) -> tuple[dict, np.ndarray]:
    """(frames, tool) of a URDF's or MJCF's chain after `base`, `hand` the tool; its limits."""
    from . import mjcf, urdf

    keys = ("file", "root", "tip", "joints", "hold", "sha256")
    if not isinstance(section, dict) or not {"file", "root", "tip"} <= set(section) <= set(keys):
        raise _bad(kind, section, "needs file, root, tip (and optionally joints, hold, sha256)")
    chain = {"urdf": urdf, "mjcf": mjcf}[kind].read_chain(**section)
    frames = chain["frames"].copy()
    frames[0] = base[:, :3] @ frames[0] + np.hstack([np.zeros((3, 3)), base[:, 3:]])
    tool = chain["tool"] + chain["rest"] @ hand
    return dict(frames=frames, tool=tool), chain["limits"]


def _loop(section, m, base, hand) -> dict:
    from . import body_loop

    body_loop.check(section)
    if np.any(hand != 0) or not np.array_equal(base, np.hstack([np.eye(3), np.zeros((3, 1))])):
        raise _bad("hand", hand.tolist(), "a body in the loop's positions are its function's: "
                   "leave base and hand at their defaults")
    given = section.get("lengths")
    try:
        lengths = np.ones(m) if given is None else np.asarray(given, np.float64)
    except (TypeError, ValueError):
        lengths = np.full(1, np.nan)
    if (lengths.shape != (m,) or not np.all((lengths >= 0) & (lengths <= MAX_MAGNITUDE))
            or not lengths.sum() > 0):
        raise _bad("callable.lengths", given, f"needs {m} lengths [m] (one per joint of home) "
                   f"within [0, {MAX_MAGNITUDE:g}], not all 0")
    return dict(loop=body_loop.Deferred(section), lengths=lengths)  # built at its first call


READS = ("urdf", "mjcf", "callable")  # the sections whose source_digest joins the cache key


def source_digest(section: str, value) -> str | None:
    """The SHA-256 of what `section` (of READS) reads beyond the description, which planning
    adds to the key as `<section>.sha256`; None when it reads nothing."""
    from . import body_loop, mjcf, urdf

    if not isinstance(value, dict):
        return None
    if section in ("urdf", "mjcf") and "file" in value:
        return {"urdf": urdf, "mjcf": mjcf}[section].digest(value["file"])
    if section == "callable" and "factory" in value:
        return body_loop.digest(value)
    return None


def make_body(description: str | dict | None = None, **fields) -> Body:
    """The body of a description (a dict, or a shipped body's name), `fields` replacing single
    fields; one without a chain starts from the shipped body of its name (make_body("icub",
    saturate=False)); None keeps a field. ValueError naming `body.<field>`."""
    desc = {"name": description} if isinstance(description, str) else dict(description or {})
    desc.update(fields)
    if not any(k in desc for k in CHAINS):
        given = {k: v for k, v in desc.items() if v is not None}
        desc = {**read_description(desc.get("name")), **given}
    return body_from(desc)

