"""The code fingerprint of a trial: a hash of the gbmodel code that computes it (the shared core
plus its learner's files), as part of its cache key, so a trial is recomputed when its code
changes and only then. Files are read, not imported, and each text is parsed once per process
(_facts). Each file of a module this process has imported is checked against that module, when
the fingerprint is taken and again once the process has imported more: its functions' compiled
code and the plain values it holds (constants, defaults, class attributes such as a dataclass's
defaults). A file edited in between raises CodeChanged, a one-line error: run the command again.
"""
from __future__ import annotations

import ast
import hashlib
import inspect
import sys
from functools import lru_cache
from pathlib import Path

import numpy as np

import gbmodel
import gbmodel.learners


class CodeChanged(RuntimeError):
    """A gbmodel file differs from the code this process imported from it."""


def _dump(tree) -> str:
    """ast.dump of `tree` with its docstrings taken out (in place)."""
    for node in ast.walk(tree):
        body = getattr(node, "body", None)
        if (isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef))
                and body and isinstance(body[0], ast.Expr)
                and isinstance(body[0].value, ast.Constant) and isinstance(body[0].value.value, str)):
            node.body = body[1:] or [ast.Pass()]
    return ast.dump(tree, annotate_fields=False, include_attributes=False)


def source_fingerprint(sources) -> str:
    """Hash of (name, source text) pairs by their names and syntax trees: comments, docstrings
    and layout do not change it. Whole files, not what the kernels reach: a function no code
    names can still change results (a numba extension, a registry)."""
    h = hashlib.sha256()
    for name, text in sorted(sources):
        h.update(name.encode() + b"\0")
        h.update(_facts(text)["tree"].encode() + b"\0")
    return h.hexdigest()[:16]


def _compiled(node):
    try:
        return compile(ast.Expression(node), "<fingerprint>", "eval")
    except Exception:
        return None


def _checks(body: list) -> list:
    """The plain assignments, function defaults and classes of a module's or class's `body`,
    their expressions compiled: ("=", name, code), ("def", name, [code of each default],
    [(keyword-only arg, code or None)]), ("class", name, checks of its body)."""
    out = []
    for node in body:
        targets = ([node.target] if isinstance(node, ast.AnnAssign) and node.value is not None
                   else node.targets if isinstance(node, ast.Assign) else [])
        out += [("=", t.id, _compiled(node.value)) for t in targets if isinstance(t, ast.Name)]
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
            out.append(("def", node.name, [_compiled(e) for e in node.args.defaults],
                        [(a.arg, None if e is None else _compiled(e))
                         for a, e in zip(node.args.kwonlyargs, node.args.kw_defaults)]))
        if isinstance(node, ast.ClassDef):
            out.append(("class", node.name, _checks(node.body)))
    return out


def _learn(text: str) -> dict:
    """From one parse and one compile: tree (without docstrings), code (the module compiled),
    checks (_checks) and imports: ("from", level, module or None, [names]) or ("import", None,
    None, [names])."""
    tree = ast.parse(text)
    checks = _checks(tree.body)
    imports = [("from", n.level, n.module, [a.name for a in n.names])
               if isinstance(n, ast.ImportFrom) else ("import", None, None,
                                                      [a.name for a in n.names])
               for n in ast.walk(tree) if isinstance(n, (ast.ImportFrom, ast.Import))]
    return dict(tree=_dump(tree), code=compile(text, "<fingerprint>", "exec"), checks=checks,
                imports=imports)


_facts = lru_cache(maxsize=512)(lambda text: _learn(text))  # once per text and process


def _codes(code, out=None) -> dict:
    """Every code object in a compiled module, by qualified name (lambdas of a scope share one)."""
    out = {} if out is None else out
    for const in code.co_consts:
        if inspect.iscode(const):
            out.setdefault(const.co_qualname, []).append(const)
            _codes(const, out)
    return out


def _live_codes(module):
    """The code objects of the functions (plain, jitted, methods) of `module`'s own file (the
    import sets their co_filename to module.__file__)."""
    seen, todo = set(), list(vars(module).values())
    while todo:
        obj = todo.pop()
        if id(obj) in seen:
            continue
        seen.add(id(obj))
        if inspect.isclass(obj) and obj.__module__ == module.__name__:
            todo += list(vars(obj).values())
            continue
        if isinstance(obj, (staticmethod, classmethod)):
            obj = obj.__func__
        elif isinstance(obj, property):
            todo += [f for f in (obj.fget, obj.fset, obj.fdel) if f is not None]
            continue
        obj = getattr(obj, "py_func", obj)  # a numba dispatcher: the Python function it compiles
        try:
            obj = inspect.unwrap(obj)
        except ValueError:
            continue
        code = getattr(obj, "__code__", None)
        if inspect.iscode(code) and code.co_filename == module.__file__:
            yield code


def _plain(value) -> bool:
    """A value that compares by content (a number, a string, containers and arrays of them)."""
    if isinstance(value, (int, float, complex, str, bytes, bool, type(None), np.generic)):
        return True
    if isinstance(value, np.ndarray):
        return value.dtype.kind in "biufcSUb"
    if isinstance(value, (tuple, list, frozenset, set)):
        return all(_plain(v) for v in value)
    if isinstance(value, dict):
        return all(_plain(k) and _plain(v) for k, v in value.items())
    return False


def _same(a, b) -> bool:
    try:
        if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
            return (type(a) is type(b) and a.shape == b.shape and a.dtype == b.dtype
                    and bool(np.array_equal(a, b, equal_nan=a.dtype.kind in "fc")))
        if type(a) is not type(b):
            return False
        if isinstance(a, float) and a != a:
            return b != b
        if isinstance(a, (tuple, list)):
            return len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b))
        if isinstance(a, dict):
            return a.keys() == b.keys() and all(_same(a[k], b[k]) for k in a)
        return bool(a == b)
    except Exception:
        return False


_SKIP = object()


def _value(code, scope: dict):
    """The plain value of compiled expression `code` in a copy of `scope`, else _SKIP."""
    try:
        value = eval(code, dict(scope))
    except Exception:  # (code None: a TypeError) cannot be evaluated on its own
        return _SKIP
    return value if _plain(value) else _SKIP


def _values(checks: list, scope: dict, live, where: str):
    """(name, value now in the file, value the import made) of the plain assignments and
    defaults of `checks`, `live` their namespace; a private mutable container (`_CACHE = {}`)
    is state the code fills, not a constant: skipped."""
    for kind, name, *rest in checks:
        if kind == "=" and name in live and _plain(live[name]) and not (
                name.startswith("_") and isinstance(live[name], (list, dict, set))):
            yield f"{where}{name}", _value(rest[0], scope), live[name]
        elif kind == "def" and name in live:
            func = getattr(live[name], "__func__", live[name])
            func = getattr(func, "py_func", func)
            defaults, (codes, kwonly) = getattr(func, "__defaults__", None) or (), rest
            kw = getattr(func, "__kwdefaults__", None) or {}
            pairs = list(zip(codes, defaults)) if len(codes) == len(defaults) else []
            pairs += [(code, kw[arg]) for arg, code in kwonly if code is not None and arg in kw]
            for code, was in pairs:
                if _plain(was):
                    yield f"{where}{name} (a default)", _value(code, scope), was
        elif kind == "class" and inspect.isclass(live.get(name)):
            cls = live[name]
            yield from _values(rest[0], {**scope, **vars(cls)}, dict(vars(cls)),
                               f"{where}{name}.")


def _gbmodel_modules() -> dict:
    """Resolved file -> module, for the imported modules of gbmodel."""
    return {Path(m.__file__).resolve(): m for name, m in list(sys.modules.items())
            if (name == "gbmodel" or name.startswith("gbmodel."))
            and getattr(m, "__file__", None)}


def as_imported(path: Path, text: str, modules: dict | None = None) -> str:
    """`text` (the file `path` as read now) if it is the code this process imported from it (or
    the file is not an imported module of gbmodel), else CodeChanged naming the file. A code's
    flags are not compared: under a profiler numba's dispatcher gives its function a copy of its
    code flagged CO_NEWLOCALS alone, the bytecode, constants and names the file's."""
    path = Path(path).resolve()
    module = (_gbmodel_modules() if modules is None else modules).get(path)
    if module is None:
        return text
    compiled, scope = _codes(_facts(text)["code"]), dict(vars(module))
    changed = next((c.co_qualname for c in _live_codes(module)
                    if not any(c == m or c.replace(co_flags=m.co_flags) == m
                               for m in compiled.get(c.co_qualname, ()))), None)
    if changed is None:
        changed = next((name for name, now, was in _values(_facts(text)["checks"], scope, scope, "")
                        if now is not _SKIP and not _same(now, was)), None)
    if changed is not None:
        raise CodeChanged(f"{path}: changed since this process imported it ({changed} "
                          "differs); run the command again")
    return text


def imported_learners(sources, name: str) -> set[str]:
    """The other learners whose code the files `sources` ((label, text) pairs, labels as
    gbmodel/learners/...py) import (relative imports resolved): online Goal Babbling and motor
    babbling run goal_babbling's code. A name imported from the learners package counts when it
    is a learner (`from gbmodel.learners import goal_babbling`), not the registry's."""
    found, known = set(), set(gbmodel.learners.available())
    for label, text in sources:
        parts = label[:-3].split("/") if label.endswith(".py") else []
        if parts[:2] != ["gbmodel", "learners"]:
            continue  # a learner registered from elsewhere: its source is hashed as it is
        package = parts[:-1]  # of a module, and of a package's __init__ alike
        for kind, level, module, names in _facts(text)["imports"]:
            if kind == "from":
                base = package[:len(package) - level + 1] if level else []
                stem = base + (module.split(".") if module else [])
                targets = [stem + n.split(".") for n in names] \
                    if not module or stem == ["gbmodel", "learners"] else [stem]
            else:
                targets = [n.split(".") for n in names]
            found |= {t[2] for t in targets
                      if t[:2] == ["gbmodel", "learners"] and len(t) > 2 and t[2] != name
                      and t[2] in known}
    return found


def _files_of(name: str) -> list[tuple[str, str]] | None:
    """gbmodel.learners.sources(name) of a learner of gbmodel/learners/, read without importing
    it (a cached simulate loads no numba); None for a learner registered at run time."""
    root = Path(gbmodel.__file__).resolve().parent
    if name in gbmodel.learners._REGISTERED or name not in gbmodel.learners.available():
        return None
    package, single = root / "learners" / name / "__init__.py", root / "learners" / f"{name}.py"
    files = (sorted(package.parent.rglob("*.py")) if package.is_file()
             else [single] if single.is_file() else None)
    if files is None:
        return None
    return [(f.resolve().relative_to(root.parent).as_posix(), f.read_text()) for f in files]


def learner_sources(learner: str) -> list[tuple[str, str]]:
    """(label, text) of the learner's own files and of every learner's whose code it imports,
    transitively."""
    done, todo, out = set(), [learner], {}
    while todo:
        name = todo.pop()
        if name in done:
            continue
        done.add(name)
        theirs = _files_of(name)
        theirs = gbmodel.learners.sources(name) if theirs is None else theirs
        out.update(theirs)
        todo += sorted(imported_learners(theirs, name) - done)
    return sorted(out.items())


@lru_cache(maxsize=None)
def _fingerprint(learner: str) -> tuple[str, dict, set, list]:
    """(fingerprint, resolved path -> the text hashed, the paths checked against their module,
    [len(sys.modules) at the last check]) of `learner`, computed once per process."""
    root = Path(gbmodel.__file__).resolve().parent
    shared = [p for p in root.rglob("*.py")
              if "learners" not in p.relative_to(root).parts[:-1]]
    shared.append(root / "learners" / "__init__.py")
    theirs = learner_sources(learner)  # from the files: a learner not imported stays so
    texts = {p.resolve(): p.read_text() for p in shared}
    own = [(p.relative_to(root.parent).as_posix(), texts[p.resolve()]) for p in shared]
    for label, text in theirs:
        texts[(root.parent / label).resolve()] = text
    return source_fingerprint(own + theirs), texts, set(), [None]


def code_fingerprint(learner: str) -> str:
    """The fingerprint of the code a trial of `learner` runs: gbmodel's shared core (every file
    outside gbmodel/learners/, and the registry) plus the files of that learner and of the
    learners it imports code from. Every file whose module the process has imported is checked
    against the text hashed (as_imported) on the first call and on any later one after the
    process imported more (pipeline.worker.run_one asks again after each trial)."""
    fp, texts, checked, seen = _fingerprint(learner)
    if seen[0] != len(sys.modules):
        modules, n = _gbmodel_modules(), len(sys.modules)
        for path in texts.keys() & modules.keys() - checked:
            as_imported(path, texts[path], modules)
            checked.add(path)
        seen[0] = n
    return fp


code_fingerprint.cache_clear = _fingerprint.cache_clear  # the tests' way to read files again
