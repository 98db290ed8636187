"""A serial chain out of a URDF, compiled into hand = F_0 Rz(q_0) ... F_{m-1} Rz(q_{m-1}) tool
(fixed and held joints folded into the F_i; docs/bodies.md, "A body from a URDF"). The file: a
regular file of at most MAX_BYTES, read once; its SHA-256 makes an edited file another body.
Every number read is finite within MAX_MAGNITUDE (metres, radians).
"""
from __future__ import annotations

import hashlib
import importlib.metadata
import os
import re
import stat
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np

REVOLUTE = ("revolute", "continuous")
MAX_BYTES = 16 * 2**20  # a URDF's size: the largest robot descriptions are a few hundred kB
MAX_MAGNITUDE = 1e3  # |origin|, |rpy|, |limit|, |held angle|: metres and radians


def _bad(key, value, why, kind="urdf"):
    return ValueError(f"body.{kind}.{key}={value!r}: {why}")


def resolve(file, kind="urdf") -> Path:
    """The file's path: a path, or {package, path} for a file an installed package holds (e.g.
    icub-models'); kind: the section named in errors."""
    if isinstance(file, dict):
        package, tail = file.get("package"), file.get("path")
        if set(file) != {"package", "path"} or not isinstance(tail, str):
            raise _bad("file", file, "give a path, or {package, path}", kind=kind)
        try:
            dist = importlib.metadata.distribution(package)
        except (importlib.metadata.PackageNotFoundError, ValueError, TypeError):
            raise _bad("file", file, f"package {package!r} is not installed",
                       kind=kind) from None
        hits = [f for f in dist.files or () if f.as_posix().endswith(tail.lstrip("/"))]
        if len(hits) != 1:
            raise _bad("file", file, f"{len(hits)} files of {package} end with {tail!r}",
                       kind=kind)
        return Path(dist.locate_file(hits[0])).resolve()
    if not isinstance(file, str) or not file:
        raise _bad("file", file, "give a path, or {package, path}", kind=kind)
    return Path(file).expanduser()


def read_bytes(file, kind="urdf", limit: int | None = None) -> bytes:
    """The bytes of a regular file of at most `limit` (MAX_BYTES) bytes, else ValueError."""
    limit = MAX_BYTES if limit is None else limit
    path = resolve(file, kind)
    what = kind.upper()
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK)  # a FIFO: opened, never waited on
    except OSError as err:
        raise _bad("file", str(file), f"cannot read the {what}: {err.strerror}",
                   kind=kind) from None
    try:
        info = os.fstat(fd)
        if not stat.S_ISREG(info.st_mode):
            raise _bad("file", str(file), "not a regular file (a FIFO, device or folder)",
                       kind=kind)
        if info.st_size > limit:
            raise _bad("file", str(file), f"{info.st_size:,} bytes; a {what} is at most "
                       f"{MAX_BYTES:,}" if limit == MAX_BYTES else f"{info.st_size:,} bytes, "
                       f"more than the {limit:,} left of the {MAX_BYTES:,} that a model and "
                       "its includes may hold in all", kind=kind)
        with os.fdopen(os.dup(fd), "rb") as fh:
            data = fh.read(limit + 1)
    finally:
        os.close(fd)
    if len(data) > limit:
        raise _bad("file", str(file), f"more than {limit:,} bytes", kind=kind)
    return data


def digest(file) -> str:
    return hashlib.sha256(read_bytes(file)).hexdigest()


# a number as C's strtod reads it (float() would take 1_0 and other scripts' digits); nan and
# inf are read to be refused
NUMBER = re.compile(r"[+-]?(?:(?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:[eE][+-]?[0-9]+)?|inf|infinity|nan)",
                    re.IGNORECASE)


def _floats(text, n, what):
    words = (text or "").split()
    bad = [w for w in words if not NUMBER.fullmatch(w)]
    if bad:
        raise ValueError(f"{what} {text!r} ({bad[0]!r} is not a number)")
    vals = [float(x) for x in words]
    if len(vals) != n:
        raise ValueError(what)
    arr = np.array(vals)
    if not np.all(np.isfinite(arr)) or np.any(np.abs(arr) > MAX_MAGNITUDE):
        raise ValueError(f"{what} {text!r} (finite numbers within +-{MAX_MAGNITUDE:g} wanted)")
    return arr


def _rpy(r, p, y) -> np.ndarray:
    cr, sr, cp, sp, cy, sy = np.cos(r), np.sin(r), np.cos(p), np.sin(p), np.cos(y), np.sin(y)
    return np.array([[cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
                     [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
                     [-sp, cp * sr, cp * cr]])


def _z_onto(axis) -> np.ndarray:
    z = np.array([0.0, 0.0, 1.0])
    c = float(axis @ z)
    if c > 1.0 - 1e-15:
        return np.eye(3)
    if c < -1.0 + 1e-15:
        return np.diag([1.0, -1.0, -1.0])  # half a turn about x
    v = np.cross(z, axis)
    K = np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]])
    return np.eye(3) + K + K @ K / (1.0 + c)


def _rot_axis(axis, angle) -> np.ndarray:
    R = _z_onto(axis)
    c, s = np.cos(angle), np.sin(angle)
    return R @ np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]]) @ R.T


def chosen(movable, joints, hold, what, kind="urdf") -> tuple[list, dict]:
    """(commanded joints, held angles), checked (default: every movable one, chain order)."""
    joints = list(movable if joints is None else joints)
    unknown = [n for n in joints if n not in movable]
    if unknown or len(set(joints)) != len(joints) or not joints:
        raise _bad("joints", joints, f"choose distinct {what} joints of the chain, {movable}",
                   kind=kind)
    if [n for n in movable if n in joints] != joints:
        order = [n for n in movable if n in joints]
        raise _bad("joints", joints, f"name them in chain order, {order}", kind=kind)
    hold = dict(hold or {})
    extra = sorted(map(str, set(hold) - (set(movable) - set(joints))))
    if extra:
        raise _bad("hold", hold, f"{extra} are not held joints of the chain", kind=kind)
    for name, angle in hold.items():
        if (isinstance(angle, bool) or not isinstance(angle, (int, float))
                or not abs(angle) <= MAX_MAGNITUDE):
            raise _bad(f"hold.{name}", angle, f"a finite angle [rad] within +-{MAX_MAGNITUDE:g}",
                       kind=kind)
    return joints, hold


def read_chain(file, root: str, tip: str, joints=None, hold=None, sha256=None) -> dict:
    """The chain from link `root` to `tip`: dict(frames (m, 3, 4), tool, rest, names, limits
    (m, 2) [rad], NaN where none). hold: {joint: angle} of the uncommanded (default 0); sha256:
    the digest the file must have. ValueError naming `body.urdf.<key>`."""
    path = resolve(file)
    data = read_bytes(file)
    if sha256 is not None and hashlib.sha256(data).hexdigest() != sha256:
        raise _bad("file", str(file), "changed since this body was planned (its SHA-256 "
                   "differs); run the command again")
    try:
        tree = ET.fromstring(data)
    except ET.ParseError as err:
        raise _bad("file", str(file), f"cannot read the URDF: {err}".splitlines()[0]) from None
    links = {l.get("name") for l in tree.findall("link")}
    for key, name in (("root", root), ("tip", tip)):
        if name not in links:
            raise _bad(key, name, f"no link of that name in {path.name}")
    by_child = {}
    for j in tree.findall("joint"):
        child = j.find("child").get("link")
        if child in by_child:
            raise _bad("file", str(file), f"link {child!r} has two parent joints: not a tree")
        by_child[child] = j
    chain, link = [], tip
    while link != root:
        j = by_child.get(link)
        if j is None:
            raise _bad("tip", tip, f"link {root!r} is not on the path from {tip!r} to the "
                       "URDF's root: root -> tip is not a serial chain")
        chain.append(j)
        link = j.find("parent").get("link")
    chain.reverse()
    movable = [j.get("name") for j in chain if j.get("type") in REVOLUTE]
    for j in chain:
        if j.get("type") not in REVOLUTE + ("fixed",):
            raise _bad("root", root, f"joint {j.get('name')!r} on the chain is "
                       f"{j.get('type')}: only revolute, continuous and fixed joints are taken")
    joints, hold = chosen(movable, joints, hold, "revolute")
    T = np.eye(4)
    frames, limits = [], []
    for j in chain:
        o = j.find("origin")
        try:
            xyz = _floats(o.get("xyz", "0 0 0") if o is not None else "0 0 0", 3, "xyz")
            rpy = _floats(o.get("rpy", "0 0 0") if o is not None else "0 0 0", 3, "rpy")
            ax = j.find("axis")
            axis = _floats(ax.get("xyz") if ax is not None else "1 0 0", 3, "axis")
        except ValueError as err:
            raise _bad("file", str(file), f"joint {j.get('name')!r}: bad {err}") from None
        step = np.eye(4)
        step[:3, :3], step[:3, 3] = _rpy(*rpy), xyz
        T = T @ step
        if j.get("type") == "fixed":
            continue
        if not np.linalg.norm(axis) > 1e-9:
            raise _bad("file", str(file), f"joint {j.get('name')!r}: its axis {axis.tolist()} "
                       "is zero")
        axis = axis / np.linalg.norm(axis)
        if j.get("name") not in joints:  # held at a stated angle
            R = np.eye(4)
            R[:3, :3] = _rot_axis(axis, float(hold.get(j.get("name"), 0.0)))
            T = T @ R
            continue
        Rz = np.eye(4)
        Rz[:3, :3] = _z_onto(axis)
        frames.append((T @ Rz)[:3].copy())
        T = np.eye(4)
        T[:3, :3] = Rz[:3, :3].T
        lim = j.find("limit")
        lo = lim.get("lower") if lim is not None and j.get("type") == "revolute" else None
        hi = lim.get("upper") if lim is not None and j.get("type") == "revolute" else None
        try:
            pair = [_floats(v, 1, "limit")[0] if v is not None else np.nan for v in (lo, hi)]
        except ValueError as err:
            raise _bad("file", str(file), f"joint {j.get('name')!r}: bad {err}") from None
        limits.append(pair)
    return dict(frames=np.array(frames), tool=T[:3, 3].copy(), rest=T[:3, :3].copy(),
                names=joints, limits=np.array(limits, float))
