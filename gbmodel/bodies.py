"""Bodies as data: a body is a description (conf/body/<name>.yaml, docs/bodies.md) over shared
kinematics, DH rows or a URDF's chain (gbmodel/urdf.py); this module holds the generic code and
no body's numbers.

A body knows its full-size chain, its joint limits, its home posture, its target set and which
segments grow. Growth is a new description (per-segment length factors, which gbmodel.growth
computes), never new kinematics code.

Commands q are what the inverse estimate outputs. For the planar arms they are joint angles in
radians. For the iCub they are normalised (paper sec. 3.3): q_i in [-1, 1] maps linearly onto
[min_i, max_i] of the joint's limits, and a command outside [-1, 1] saturates at the limit, as
the real robot's position controller does. The example learned from is the posture actually
taken (the saturated one): that is the only posture whose outcome was observed.
"""
from __future__ import annotations

import importlib.util
import math
import re
from dataclasses import MISSING, dataclass, field, fields
from pathlib import Path
from types import SimpleNamespace
from typing import Any, Optional

import numpy as np
import yaml

from .kinematics import chain_position, hand_position
from .spec import Choice, Flag, Free, Maybe, Members, Record, Text, check_fields
from .urdf import MAX_MAGNITUDE


@dataclass(frozen=True)
class Body:
    name: str
    a: np.ndarray  # (m,) DH link lengths at full size [m]
    d: np.ndarray  # (m,) DH link offsets at full size [m]
    alpha: np.ndarray  # (m,) DH link twists [rad]
    theta_offset: np.ndarray  # (m,) added to every joint angle [rad]
    base: np.ndarray  # (3, 4) root transform H0 (rotation | translation)
    outputs: tuple  # which hand coordinates are controlled (n of x, y, z)
    home: np.ndarray  # (m,) home posture, in command units
    targets: np.ndarray  # (N, n) target set at full size [m]
    growing: np.ndarray  # (m,) bool: segments that grow under non-proportional growth
    q_min: np.ndarray | None = None  # (m,) joint limits [rad] of normalised commands
    q_max: np.ndarray | None = None
    saturates: bool = True  # normalised commands are clipped to [-1, 1] (False: limits ignored)
    description: str = ""
    # a general serial chain (a URDF's, gbmodel/urdf.py) instead of the DH rows: per joint a
    # fixed 3x4 transform, then a rotation about local z; the tool point in the last frame
    frames: np.ndarray | None = None  # (m, 3, 4)
    tool: np.ndarray | None = None  # (3,)
    # or a body in the loop (gbmodel/body_loop.py): a Python forward function, its segments'
    # lengths (what growth patterns weigh)
    loop: Any = None  # body_loop.Forward
    lengths: np.ndarray | None = None  # (m,)
    _cos_alpha: np.ndarray = field(init=False, repr=False)
    _sin_alpha: np.ndarray = field(init=False, repr=False)

    def __post_init__(self):
        object.__setattr__(self, "_cos_alpha", np.round(np.cos(self.alpha), 15))
        object.__setattr__(self, "_sin_alpha", np.round(np.sin(self.alpha), 15))

    @property
    def m(self) -> int:
        return len(self.a)

    @property
    def general(self) -> bool:
        """A chain of fixed transforms and rotations about z (a URDF's), not DH rows."""
        return self.frames is not None

    @property
    def segment_lengths(self) -> np.ndarray:
        """Full length of each segment (m,): what growth scales. DH: hypot(a_i, d_i); a general
        chain: the translation after joint i (to the next joint, or to the tool); a body in the
        loop: its description's `callable.lengths`."""
        if self.loop is not None:
            return self.lengths
        if not self.general:
            return np.hypot(self.a, self.d)
        after = np.vstack([self.frames[1:, :, 3], self.tool[None]])
        return np.linalg.norm(after, axis=1)

    @property
    def n(self) -> int:
        return len(self.outputs)

    @property
    def normalized(self) -> bool:
        return self.q_min is not None

    @property
    def limited(self) -> bool:
        """Whether a command stops at the joint limits: normalised to [-1, 1] and saturating
        (the clip of `saturate`; the solver's limit pull and decaying anchor need it too)."""
        return self.normalized and self.saturates

    # ---- commands -> joint angles ------------------------------------------------------------
    def saturate(self, q: np.ndarray) -> np.ndarray:
        """The posture actually taken for command q (clipped to [-1, 1] when normalised)."""
        if self.limited:
            return np.clip(q, -1.0, 1.0)
        return np.asarray(q, dtype=np.float64)

    def joint_angles(self, q: np.ndarray) -> np.ndarray:
        """DH joint angles [rad] for (saturated) commands q."""
        q = self.saturate(q)
        if self.normalized:
            q = self.q_min + 0.5 * (q + 1.0) * (self.q_max - self.q_min)
        return q + self.theta_offset

    # ---- kinematics ------------------------------------------------------------------------------
    def _factors(self, factors) -> np.ndarray:
        """Per-segment length factors (m,) or (..., m): the full-size body's ones when None
        (gbmodel.growth.factors maps a size and a growth pattern to them)."""
        return np.ones(self.m) if factors is None else np.asarray(factors, np.float64)

    def chain(self, factors=None) -> dict:
        """Arrays describing the DH chain with per-segment length factors `factors` (m,):
        a, d, cos/sin alpha, base. DH chains only."""
        if self.loop is not None:
            raise ValueError(f"body {self.name!r} is a body in the loop (a Python forward "
                             "function): only the numpy reference path takes it "
                             "(learner.fast=false)")
        if self.general:
            raise ValueError(f"body {self.name!r} is a general (URDF) chain, not DH rows: this "
                             "learner or kernel takes DH chains only so far")
        k = self._factors(factors)
        return dict(
            a=self.a * k, d=self.d * k, cos_alpha=self._cos_alpha, sin_alpha=self._sin_alpha,
            base=self.base,
        )

    def forward(self, q: np.ndarray, factors=None) -> np.ndarray:
        """Hand position (n,) or (N, n) [m] for commands q of shape (m,) or (N, m), with
        per-segment length factors `factors` (m,) (None: the full-size body; a size and a growth
        pattern give them through gbmodel.growth.factors)."""
        q = np.asarray(q, dtype=np.float64)
        if q.shape[-1] != self.m:
            raise ValueError(f"{self.name} takes {self.m} joint commands, got shape {q.shape}")
        if self.loop is not None:
            from .body_loop import positions

            p = positions(self.loop, self.joint_angles(q), self._factors(factors), self.name)
            return p[..., list(self.outputs)]
        if self.general:
            p = chain_position(self.joint_angles(q), self.frames, self.tool,
                               self._factors(factors))
            return p[..., list(self.outputs)]
        p = hand_position(self.joint_angles(q), **self.chain(factors))
        return p[..., list(self.outputs)]

    def frame_points(self, q: np.ndarray, factors=None) -> np.ndarray:
        """Root-frame points (m + 1, 3) for command q (m,), base to hand: every joint's origin,
        then the hand (the tool point, all three coordinates of what forward returns), as
        robotics-toolbox's fkine_all. For drawing a posture. A body in the loop: the hand only
        (1, 3), its joints' places are not known."""
        theta = self.joint_angles(np.asarray(q, float))
        k = self._factors(factors)
        if self.loop is not None:
            from .body_loop import positions

            return positions(self.loop, theta[None], k, self.name)
        if self.general:
            joints = [chain_position(theta[:j], self.frames[:j], self.frames[j][:, 3], k[:j])
                      for j in range(1, self.m)]
            return np.stack([self.frames[0][:, 3], *joints,
                             chain_position(theta, self.frames, self.tool, k)])
        ch = self.chain(k)
        return np.stack([hand_position(theta[:j], ch["a"][:j], ch["d"][:j], ch["cos_alpha"][:j],
                                       ch["sin_alpha"][:j], ch["base"])
                         for j in range(self.m + 1)])

    def target_set(self, size: float = 1.0) -> np.ndarray:
        """The target set scales with the body (paper sec. 3.1)."""
        return self.targets * size

    def target_box(self, size: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
        t = self.target_set(size)
        return t.min(axis=0), t.max(axis=0)


def _grid(*axes) -> np.ndarray:
    mesh = np.meshgrid(*axes, indexing="ij")
    return np.stack([g.ravel() for g in mesh], axis=-1)


MAX_GRID_POINTS = 4096  # targets of one grid (64 x 64, 16 x 16 x 16): memory grows with them


def grid_points(lo, hi, num) -> np.ndarray:
    """The regular target grid with num[j] points from lo[j] to hi[j] along axis j: (prod num, n).
    At least 2 points per axis (one point has no cells to learn between), at most
    MAX_GRID_POINTS in all, bounds finite within MAX_MAGNITUDE metres, lo < hi."""
    if not len(lo) == len(hi) == len(num):
        raise ValueError(f"grid: lo, hi and num need one entry per axis, got {lo}, {hi}, {num}")
    if any(isinstance(k, bool) or not isinstance(k, (int, np.integer)) or k < 2 for k in num):
        raise ValueError(f"grid: need num >= 2 (an integer) per axis, got {num}")
    if math.prod(int(k) for k in num) > MAX_GRID_POINTS:
        raise ValueError(f"grid: {math.prod(int(k) for k in num):,} points; at most "
                         f"{MAX_GRID_POINTS:,}")
    bounds = np.asarray([lo, hi], dtype=np.float64)
    if not np.all(np.abs(bounds) <= MAX_MAGNITUDE) or any(h <= l for l, h in zip(lo, hi)):
        raise ValueError(f"grid: need finite lo < hi within +-{MAX_MAGNITUDE:g} m per axis, got "
                         f"{lo}, {hi}")
    return _grid(*(np.linspace(l, h, int(k)) for l, h, k in zip(lo, hi, num)))


def cell_centres(targets: np.ndarray) -> np.ndarray:
    """The centres of the cells of a regular grid (off-grid points between the targets)."""
    axes = [np.unique(targets[:, j]) for j in range(targets.shape[1])]
    return _grid(*[0.5 * (a[1:] + a[:-1]) if len(a) > 1 else a for a in axes])


@dataclass(frozen=True)
class Grid:
    """The regular target grid at full size: num[j] points from lo[j] to hi[j] along axis j."""

    lo: list[float]
    hi: list[float]
    num: list[int]


@dataclass(frozen=True, kw_only=True)
class Description:
    """A body's whole description, the fields of conf/body/<name>.yaml (docs/bodies.md); a field
    without a default must be given. body_from checks the values; the pipeline's config schema
    (BodyConf) is generated from these fields."""

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
    # a third-party model's credit, {model, source, licence}: listed in every report whose trials
    # use the body (pipeline/studies/provenance.py); what the trial computes does not depend on it
    credits: Optional[dict[str, str]] = None


FIELDS = tuple(f.name for f in fields(Description))
CHAINS = ("dh", "urdf", "mjcf", "callable")  # the fields of which a body gives exactly one
CREDITS = ("model", "source", "licence")  # the fields of a body's credits
UNITS = {"rad": 1.0, "deg": None}  # deg: np.deg2rad (the same bits as the tables' conversion)
# The description's fields and what each may hold (gbmodel.spec.check_fields, in this order);
# body_from checks the rest against the chain: the joints' count m (dh, limits, home, grows), the
# grid's coordinates against outputs, the one chain of CHAINS
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
    """The config folder: conf/ of the checkout beside this package (a clone, `pip install -e`),
    else the installed package data (a wheel installs conf/ as gbgrowth_conf)."""
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
    """The names of the bodies shipped as conf/body/<name>.yaml."""
    return tuple(sorted(p.stem for p in SHIPPED.glob("*.yaml")))


def read_description(name: str) -> dict:
    """The shipped description conf/body/<name>.yaml as a plain dict (the one file gbmodel reads:
    a body's description)."""
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
    """desc[key] as a float array (rows, cols) (rows None: any number of rows)."""
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
    """A Body from a whole description (the fields of conf/body/*.yaml; docs/bodies.md).
    Raises ValueError naming the bad key as `body.<key>`."""
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
    """(frames, tool) of the URDF's or MJCF model's chain (kind: urdf, mjcf) with `base` before
    it and the hand point `hand` (in the tip's frame) as the tool, and the file's limits [rad]."""
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
    """A body in the loop's forward function and segment lengths (gbmodel/body_loop.py)."""
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
    """The SHA-256 of what a body's `section` (one of READS) reads beyond its description (a
    file's bytes, an MJCF's includes, a function's source): the part of a trial's cache key that
    planning adds as `<section>.sha256`. None when the section reads nothing (absent, or missing
    the key naming what it reads)."""
    from . import body_loop, mjcf, urdf

    if not isinstance(value, dict):
        return None
    if section in ("urdf", "mjcf") and "file" in value:
        return {"urdf": urdf, "mjcf": mjcf}[section].digest(value["file"])
    if section == "callable" and "factory" in value:
        return body_loop.digest(value)
    return None


def make_body(description: str | dict | None = None, **fields) -> Body:
    """The body a description gives: a dict of conf/body/*.yaml's fields (what the config holds),
    or the name of a shipped body; `fields` replace single fields (e.g. home=..., saturate=False,
    grid=dict(lo, hi, num)). A description without a chain (no `dh`) starts from the shipped body
    of its name, so make_body("arm5"), make_body({"name": "arm5"}) and
    make_body("icub", saturate=False) all work. Fields given as None keep the description's.
    Raises ValueError naming the bad field as `body.<field>`."""
    desc = {"name": description} if isinstance(description, str) else dict(description or {})
    desc.update(fields)
    if not any(k in desc for k in CHAINS):
        given = {k: v for k, v in desc.items() if v is not None}
        desc = {**read_description(desc.get("name")), **given}
    return body_from(desc)


def unreachable(body: Body, rng: np.random.Generator, size: float = 1.0, samples: int = 4000,
                steps: int = 30, tol: float = 1e-3, starts: int = 6) -> np.ndarray:
    """Indices of the targets (at `size`) that no posture within the limits reaches to `tol` m:
    from each of the `starts` nearest of `samples` random postures, damped Gauss-Newton steps on
    the commands (clipped to [-1, 1] where normalised, numerical Jacobian); a target counts as
    reached when any start reaches it. One start missed targets a bounded search reaches (on
    7-DOF arms, a start stuck at a joint limit); six miss none of 2,000 postures' hand positions
    on the two test arms (tests/new_robots.py). Still a local search, so callers warn, never
    refuse."""
    targets, k = body.target_set(size), np.full(body.m, float(size))  # proportional at `size`
    box = 1.0 if body.normalized else np.pi
    Q = rng.uniform(-box, box, size=(samples, body.m))
    X = body.forward(Q, k)
    nearest = np.argsort(((targets[:, None, :] - X[None]) ** 2).sum(-1), axis=1)[:, :starts]
    q = Q[nearest].reshape(-1, body.m)  # (targets x starts, m)
    goal = np.repeat(targets, nearest.shape[1], axis=0)
    eye, h = 1e-4 * np.eye(body.m), 1e-6
    for _ in range(steps):
        x = body.forward(q, k)
        J = np.stack([(body.forward(q + h * e, k) - x) / h for e in np.eye(body.m)], axis=-1)
        JT = J.transpose(0, 2, 1)
        dq = np.linalg.solve(JT @ J + eye, JT @ (goal - x)[..., None])[..., 0]
        q = np.clip(q + dq, -box, box) if body.limited else q + dq
    miss = np.linalg.norm(body.forward(q, k) - goal, axis=-1).reshape(len(targets), -1).min(1)
    return np.flatnonzero(miss > tol)
