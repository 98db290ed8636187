"""A serial chain out of an MJCF file (MuJoCo's format) in urdf.py's chain form, read with the
standard library as MuJoCo's compiler reads it (docs/bodies.md, "A body from an MJCF file": what
is read, what refused). Includes come from the model's folder only, at most urdf.MAX_BYTES in
all; the digest covers every file read.
"""
from __future__ import annotations

import functools
import hashlib
import xml.etree.ElementTree as ET

import numpy as np

from . import urdf
from .urdf import _floats, _rot_axis, _z_onto, chosen, read_bytes, resolve

MAX_FILES = 64  # the model and its includes
MAX_DEPTH = 200  # elements nested in one another (the deepest shipped model nests a dozen)
ORIENTATIONS = ("quat", "axisangle", "euler", "xyaxes", "zaxis")
ELEMENTS = ("body", "frame", "site")  # what the path from root to tip may pass through
_bad = functools.partial(urdf._bad, kind="mjcf")


def _parse(data: bytes, file, name: str) -> ET.Element:
    try:
        tree = ET.fromstring(data)
    except ET.ParseError as err:
        raise _bad("file", str(file), f"cannot read {name} as XML: {err}".splitlines()[0]) from None
    if tree.tag != "mujoco":
        raise _bad("file", str(file), f"{name} is not an MJCF file: its root element is "
                   f"<{tree.tag}>, not <mujoco>")
    return tree


def read_model(file) -> tuple[ET.Element, str]:
    """(the <mujoco> tree with its includes expanded, the SHA-256 of every file read)."""
    path = resolve(file, "mjcf")
    data = read_bytes(file, "mjcf")
    folder = path.resolve().parent
    h = hashlib.sha256(data)
    tree = _parse(data, file, path.name)
    count, total = [1], [len(data)]  # files read, their bytes: at most urdf.MAX_BYTES in all

    def expand(elem: ET.Element, active: tuple, depth: int = 0) -> None:
        if depth > MAX_DEPTH:
            raise _bad("file", str(file), f"{active[-1].name}: elements nested more than "
                       f"{MAX_DEPTH} deep (at a <{elem.tag}>)")
        children = []
        for child in list(elem):
            if child.tag != "include":
                expand(child, active, depth + 1)
                children.append(child)
                continue
            name = child.get("file")
            if not name:
                raise _bad("file", str(file), "an <include> without its file")
            target = (folder / name).resolve()
            if not target.is_relative_to(folder):
                raise _bad("file", str(file), f"<include file={name!r}> is outside the model's "
                           f"folder {folder}: includes are read from that folder only")
            if target in active:
                raise _bad("file", str(file), f"<include file={name!r}> includes itself")
            count[0] += 1
            if count[0] > MAX_FILES:
                raise _bad("file", str(file), f"more than {MAX_FILES} files included")
            try:
                included = read_bytes(str(target), "mjcf", limit=urdf.MAX_BYTES - total[0])
            except ValueError as err:
                raise _bad("file", str(file), f"<include file={name!r}>: "
                           + str(err).split(": ", 1)[-1]) from None
            total[0] += len(included)
            rel = target.relative_to(folder).as_posix().encode()
            h.update(b"\0" + rel + b"\0" + len(included).to_bytes(8, "little") + included)
            sub = _parse(included, file, name)
            expand(sub, active + (target,), depth)
            children.extend(list(sub))
        elem[:] = children

    expand(tree, (path.resolve(),))
    return tree, h.hexdigest()


def digest(file) -> str:
    return read_model(file)[1]


# ---- compiler settings, default classes ------------------------------------------------------
def _compiler(tree, file) -> dict:
    settings = {"angle": "degree", "eulerseq": "xyz", "autolimits": "true"}
    for c in tree.findall("compiler"):
        settings.update(c.attrib)
    if settings["angle"] not in ("degree", "radian"):
        raise _bad("file", str(file), f"<compiler angle={settings['angle']!r}>: degree or radian")
    seq = settings["eulerseq"]
    if len(seq) != 3 or any(ch not in "xyzXYZ" for ch in seq):
        raise _bad("file", str(file), f"<compiler eulerseq={seq!r}>: three of x, y, z, X, Y, Z")
    if settings.get("coordinate", "local") != "local":
        raise _bad("file", str(file), f"<compiler coordinate={settings['coordinate']!r}>: only "
                   "local coordinates are read (as MuJoCo since 2.3.3)")
    return settings


def _classes(tree, file) -> dict:
    """{class: {tag: attributes}} with what each inherits (refusing what MuJoCo refuses)."""
    classes: dict = {}

    def walk(elem, inherited, name):
        if name is None or (name in classes and elem not in tops):
            raise _bad("file", str(file), f"<default class={name!r}>: " + (
                "a nested default class needs its name" if name is None else
                "a default class of that name is defined twice"))
        own = {tag: dict(attrs) for tag, attrs in inherited.items()}
        for child in elem:
            if child.tag != "default":
                own[child.tag] = {**own.get(child.tag, {}), **child.attrib}
        classes[name] = own
        for sub in elem.findall("default"):
            walk(sub, own, sub.get("class"))

    main: dict = {}
    tops = tree.findall("default")
    for top in tops:  # the main class (several: merged in order)
        walk(top, main, "main")
        main = classes["main"]
    classes.setdefault("main", {})
    return classes


# ---- poses -----------------------------------------------------------------------------------
def _quat(q) -> np.ndarray:
    n = np.linalg.norm(q)
    if not n > 1e-12:
        raise ValueError(f"quat {q.tolist()} (a zero quaternion)")
    w, x, y, z = q / n
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                     [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                     [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])


def _unit(v, what) -> np.ndarray:
    n = np.linalg.norm(v)
    if not n > 1e-12:
        raise ValueError(f"{what} {v.tolist()} (zero)")
    return v / n


def _rotation(attrs, compiler) -> np.ndarray:
    given = [k for k in ORIENTATIONS if k in attrs]
    if len(given) > 1:
        raise ValueError(f"orientation given twice ({', '.join(given)})")
    deg = compiler["angle"] == "degree"
    if not given:
        return np.eye(3)
    kind, text = given[0], attrs[given[0]]
    if kind == "quat":
        return _quat(_floats(text, 4, "quat"))
    if kind == "axisangle":
        v = _floats(text, 4, "axisangle")
        return _rot_axis(_unit(v[:3], "axisangle axis"), np.deg2rad(v[3]) if deg else v[3])
    if kind == "euler":
        angles = _floats(text, 3, "euler")
        R = np.eye(3)
        for ch, a in zip(compiler["eulerseq"], np.deg2rad(angles) if deg else angles):
            step = _rot_axis(np.eye(3)["xyz".index(ch.lower())], a)
            R = R @ step if ch.islower() else step @ R  # rotating axes / fixed axes
        return R
    if kind == "xyaxes":
        v = _floats(text, 6, "xyaxes")
        x = _unit(v[:3], "xyaxes x")
        y = _unit(v[3:] - x * (x @ v[3:]), "xyaxes y")
        return np.column_stack([x, y, np.cross(x, y)])
    return _z_onto(_unit(_floats(text, 3, "zaxis"), "zaxis"))


def _pose(attrs, compiler) -> np.ndarray:
    T = np.eye(4)
    if "fromto" in attrs:  # a site's segment: at its middle, z from its end to its start
        v = _floats(attrs["fromto"], 6, "fromto")  # (as MuJoCo's compiler turns it)
        T[:3, :3], T[:3, 3] = _z_onto(_unit(v[:3] - v[3:], "fromto")), 0.5 * (v[:3] + v[3:])
        return T
    T[:3, :3] = _rotation(attrs, compiler)
    T[:3, 3] = _floats(attrs.get("pos", "0 0 0"), 3, "pos")
    return T


# ---- the chain -------------------------------------------------------------------------------
def _attrs(elem, tag, cls, classes, file) -> dict:
    name = elem.get("class", cls)
    if name not in classes:
        raise _bad("file", str(file), f"<{tag} name={elem.get('name')!r}> names the default "
                   f"class {name!r}, which the model does not define")
    own = elem.attrib
    drop = ORIENTATIONS + ("pos",) if "fromto" in own else \
        ORIENTATIONS if any(k in own for k in ORIENTATIONS) else ()
    return {**{k: v for k, v in classes[name].get(tag, {}).items() if k not in drop}, **own}


def _find(tree, tag, name):
    return [e for wb in tree.findall("worldbody") for e in wb.iter(tag) if e.get("name") == name]


def _couplings(tree) -> dict:
    out = {}
    for tendon in tree.findall("tendon"):
        for fixed in tendon.findall("fixed"):
            for j in fixed.findall("joint"):
                out.setdefault(j.get("joint"), f"fixed tendon {fixed.get('name')!r}")
    for eq in tree.findall("equality"):
        for j in eq.findall("joint"):
            for key in ("joint1", "joint2"):
                if j.get(key):
                    out.setdefault(j.get(key), f"joint equality {j.get('name')!r}")
    return out


def read_chain(file, root: str, tip: str, joints=None, hold=None, sha256=None) -> dict:
    """urdf.read_chain's dict for body `root` (`world`) to body or site `tip`; joints: hinges
    (default: all on the chain), hold: {joint: qpos} (default: their `ref`)."""
    path = resolve(file, "mjcf")
    tree, sha = read_model(file)
    if sha256 is not None and sha != sha256:
        raise _bad("file", str(file), "changed since this body was planned (the SHA-256 of the "
                   "model and its includes differs); run the command again")
    if not tree.findall("worldbody"):
        raise _bad("file", str(file), f"{path.name} has no <worldbody>")
    compiler, classes = _compiler(tree, file), _classes(tree, file)
    steps, parent = _path(tree, root, tip, path.name)
    ops = _ops(tree, steps, parent, classes, compiler, root, file)
    joints, hold = chosen([op[1] for op in ops if op[0] == "hinge"], joints, hold, "hinge",
                          kind="mjcf")
    return _compile(ops, joints, hold, compiler, file)


def _path(tree, root, tip, name):
    if root == "world":
        start = None
    else:
        hits = _find(tree, "body", root)
        if len(hits) != 1:
            raise _bad("root", root, f"{len(hits)} bodies of that name in {name}")
        start = hits[0]
    bodies, sites = _find(tree, "body", tip), _find(tree, "site", tip)
    if len(bodies) + len(sites) != 1:
        raise _bad("tip", tip, f"{len(bodies)} bodies and {len(sites)} sites of that name in "
                   f"{name}; name one body or one site")
    end = (bodies or sites)[0]
    parent = {c: p for wb in tree.findall("worldbody") for p in wb.iter() for c in p}
    steps, elem = [], end
    while elem is not start and not (start is None and elem.tag == "worldbody"):
        if elem not in parent:  # a worldbody: the root was not met on the way up
            raise _bad("root", root, f"body {root!r} is not on the path from {tip!r} to the "
                       "world: root -> tip is not a chain")
        if elem.tag not in ELEMENTS:
            raise _bad("tip", tip, f"<{elem.tag}> on the chain: only bodies, frames and the "
                       "tip's site are read")
        steps.append(elem)
        elem = parent[elem]
    steps.reverse()
    if any(e.tag == "site" for e in steps[:-1]):
        raise _bad("tip", tip, "a site inside a site")
    return steps, parent


def _ops(tree, steps, parent, classes, compiler, root, file) -> list:
    def cls(elem):  # the class of an element without its own: the nearest childclass around it
        e = parent.get(elem)
        while e is not None:
            if e.get("childclass"):
                return e.get("childclass")
            e = parent.get(e)
        return "main"

    coupled = _couplings(tree)
    ops = []
    for elem in steps:
        attrs = _attrs(elem, "site", cls(elem), classes, file) if elem.tag == "site" \
            else elem.attrib  # bodies and frames take no defaults
        try:
            ops.append(("pose", _pose(attrs, compiler)))
        except ValueError as err:
            raise _bad("file", str(file), f"<{elem.tag} name={elem.get('name')!r}>: bad "
                       f"{err}") from None
        for j in elem if elem.tag == "body" else ():
            if j.tag not in ("joint", "freejoint"):
                continue
            ja = _attrs(j, "joint", cls(j), classes, file) if j.tag == "joint" else {}
            kind = ja.get("type", "hinge") if j.tag == "joint" else "free"
            if kind != "hinge":
                raise _bad("root", root, f"joint {j.get('name')!r} on the chain is {kind}: only "
                           "hinge joints are taken")
            if j.get("name") in coupled:
                raise _bad("root", root, f"joint {j.get('name')!r} on the chain is coupled to "
                           f"others by {coupled[j.get('name')]}: its angle is not free")
            ops.append(("hinge", j.get("name"), ja))
    return ops


def _compile(ops, joints, hold, compiler, file) -> dict:
    angle = np.deg2rad if compiler["angle"] == "degree" else (lambda x: x)
    T, frames, limits = np.eye(4), [], []
    for op in ops:
        if op[0] == "pose":
            T = T @ op[1]
            continue
        name, ja = op[1], op[2]
        try:
            pos = _floats(ja.get("pos", "0 0 0"), 3, "pos")
            axis = _unit(_floats(ja.get("axis", "0 0 1"), 3, "axis"), "axis")
            ref = float(angle(_floats(ja.get("ref", "0"), 1, "ref")[0]))
            lo_hi = angle(_floats(ja["range"], 2, "range")) if "range" in ja else None
        except ValueError as err:
            raise _bad("file", str(file), f"joint {name!r}: bad {err}") from None
        shift, back = np.eye(4), np.eye(4)
        shift[:3, 3], back[:3, 3] = pos, -pos
        if name not in joints:  # held: turned by (qpos - ref) about its axis through pos
            R = np.eye(4)
            R[:3, :3] = _rot_axis(axis, float(hold.get(name, ref)) - ref)
            T = T @ shift @ R @ back
            continue
        Z = np.eye(4)
        Z[:3, :3] = _z_onto(axis)
        frames.append((T @ shift @ Z)[:3].copy())
        turn = np.eye(4)  # Rz(qpos - ref) = Rz(qpos) Rz(-ref): the -ref after the joint
        turn[:3, :3] = _rot_axis(np.array([0.0, 0.0, 1.0]), -ref)
        Zt = np.eye(4)
        Zt[:3, :3] = Z[:3, :3].T
        T = turn @ Zt @ back
        limited = ja.get("limited", "auto")
        has = limited == "true" or (limited == "auto" and compiler["autolimits"] == "true")
        if has and lo_hi is not None and not lo_hi[0] < lo_hi[1]:
            raise _bad("file", str(file), f"joint {name!r}: its range {ja['range']!r} is "
                       + ("reversed (lower above upper)" if lo_hi[0] > lo_hi[1] else
                          "empty (lower equals upper)") + " on a limited joint")
        limits.append(list(lo_hi) if has and lo_hi is not None else [np.nan, np.nan])
    return dict(frames=np.array(frames), tool=T[:3, 3].copy(), rest=T[:3, :3].copy(),
                names=joints, limits=np.array(limits, float))
