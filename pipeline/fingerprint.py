"""The code fingerprint of a trial: a hash of the gbmodel code that computes it, taken from the
code this process runs.

The cache key holds it, so a trial is recomputed when its code changes and only then. The files
are read once per learner and process (code_fingerprint is cached; a learner is read from its
files, not imported), and each file of a module this process has imported is checked against
that module's code, when the fingerprint is taken and again once the process has imported more:
a file edited between the import and the read (the driver imports gbmodel, someone saves a
file, the fingerprint reads it), or between the read and a later import, would otherwise key
one code's results with the other code's fingerprint. Both the compiled
functions and the values the module holds (its constants, function defaults, class attributes
such as a dataclass's defaults: evaluated from the file as read now and compared with what the
import made) are checked. Such a file raises CodeChanged, a one-line error: run the command again.

What is learnt from a file's text (its syntax tree without docstrings, its compiled code, the
expressions of its constants and defaults, its imports: _facts) is learnt once per process and
kept nowhere else. The checks against the imported module run on every fingerprint, from
those facts.
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


def _code_of(source: str) -> str:
    """The syntax tree of a module without its docstrings (comments are not in it anyway)."""
    return _dump(ast.parse(source))


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
    """Hash of the code of `sources`, (name, source text) pairs (names + syntax trees): a change
    of what the code computes changes it; comments, docstrings and layout do not. Whole files,
    not what the kernels reach: a function no code names can still change results (a numba
    extension's decorator, a registry), so an added unused function recomputes, on purpose."""
    h = hashlib.sha256()
    for name, text in sorted(sources):
        h.update(name.encode() + b"\0")
        h.update(_facts(text)["tree"].encode() + b"\0")
    return h.hexdigest()[:16]


def _compiled(node):
    """Expression `node` compiled on its own, or None when it cannot be."""
    try:
        return compile(ast.Expression(node), "<fingerprint>", "eval")
    except Exception:
        return None


def _checks(body: list) -> list:
    """The plain assignments, function defaults and classes of `body` (a module's or class's
    statements), in order, with their expressions compiled: ("=", name, code),
    ("def", name, [code of each default], [(keyword-only arg, code or None)]),
    ("class", name, checks of its body). _values evaluates them against the live module."""
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


def _imports(tree) -> list:
    """Every import statement of `tree`: ("from", level, module or None, [names]) and
    ("import", None, None, [names])."""
    out = []
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom):
            out.append(("from", node.level, node.module, [a.name for a in node.names]))
        elif isinstance(node, ast.Import):
            out.append(("import", None, None, [a.name for a in node.names]))
    return out


def _learn(text: str) -> dict:
    """What the fingerprint needs of a source text, from one parse and one compile: tree (the
    syntax tree without docstrings, _code_of), code (the module compiled), checks (_checks) and
    imports (_imports)."""
    tree = ast.parse(text)
    checks, imports = _checks(tree.body), _imports(tree)
    return dict(tree=_dump(tree), code=compile(text, "<fingerprint>", "exec"), checks=checks,
                imports=imports)


@lru_cache(maxsize=512)
def _facts(text: str) -> dict:
    """_learn(text), once per text and process."""
    return _learn(text)


def _codes(code, out=None) -> dict:
    """Every code object in `code` (a compiled module), by qualified name (several lambdas of
    one scope share theirs)."""
    out = {} if out is None else out
    for const in code.co_consts:
        if inspect.iscode(const):
            out.setdefault(const.co_qualname, []).append(const)
            _codes(const, out)
    return out


def _live_codes(module, path: Path):
    """The code objects of the functions (plain, jitted, methods) that `module` got from `path`."""
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
        if inspect.iscode(code) and _resolved(code.co_filename) == path:
            yield code


@lru_cache(maxsize=4096)
def _resolved(filename: str) -> Path:
    return Path(filename).resolve()


_PLAIN = (int, float, complex, str, bytes, bool, type(None))


def _plain(value) -> bool:
    """A value that compares by content (a number, a string, containers and arrays of them)."""
    if isinstance(value, _PLAIN) or isinstance(value, np.generic):
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


def _value(code, scope: dict):
    """The value of compiled expression `code` in `scope` (a copy of the live namespace), or a
    marker when it cannot be evaluated on its own or is not a plain value (an object, a
    function)."""
    if code is None:
        return _SKIP
    try:
        value = eval(code, dict(scope))
    except Exception:
        return _SKIP
    return value if _plain(value) else _SKIP


_SKIP = object()


def _values(checks: list, scope: dict, live, where: str):
    """(name, value now in the file, value the import made) of the plain assignments and
    function defaults of `checks` (_checks of a module's or class's statements); `live` is its
    namespace. A private mutable container (`_CACHE = {}`) is state the code fills, not a
    constant: skipped."""
    for kind, name, *rest in checks:
        if kind == "=":
            if name in live and not (name.startswith("_")
                                     and isinstance(live[name], (list, dict, set))):
                now = _value(rest[0], scope)
                if now is not _SKIP and _plain(live[name]):
                    yield f"{where}{name}", now, live[name]
        elif kind == "def" and name in live:
            func = live[name]
            func = getattr(func, "__func__", func)
            func = getattr(func, "py_func", func)
            defaults = getattr(func, "__defaults__", None) or ()
            codes, kwonly = rest
            if len(codes) == len(defaults):
                for code, was in zip(codes, defaults):
                    now = _value(code, scope)
                    if now is not _SKIP and _plain(was):
                        yield f"{where}{name} (a default)", now, was
            kw = getattr(func, "__kwdefaults__", None) or {}
            for arg, code in kwonly:
                if code is not None and arg in kw and _plain(kw[arg]):
                    now = _value(code, scope)
                    if now is not _SKIP:
                        yield f"{where}{name} (a default)", now, kw[arg]
        elif kind == "class" and inspect.isclass(live.get(name)):
            cls = live[name]
            yield from _values(rest[0], {**scope, **vars(cls)}, dict(vars(cls)),
                               f"{where}{name}.")


def _changed_value(module, text: str) -> str | None:
    """The first constant, default or class attribute whose value in `text` differs from the
    one the imported `module` holds, else None."""
    scope = dict(vars(module))
    for name, now, was in _values(_facts(text)["checks"], scope, scope, ""):
        if not _same(now, was):
            return name
    return None


def _gbmodel_modules() -> dict:
    """Resolved file -> module, for the imported modules of gbmodel."""
    return {Path(m.__file__).resolve(): m for name, m in list(sys.modules.items())
            if (name == "gbmodel" or name.startswith("gbmodel."))
            and getattr(m, "__file__", None)}


def _compiled_from(code, compiled) -> bool:
    """Whether live `code` is one of `compiled` (the file's as read now). Its flags are not
    compared: under a profiler (`python -m cProfile`) numba's dispatcher gives its function a
    copy of its code flagged CO_NEWLOCALS alone, the bytecode, constants and names the file's."""
    return code in compiled or any(code.replace(co_flags=c.co_flags) == c for c in compiled)


def as_imported(path: Path, text: str, modules: dict | None = None) -> str:
    """`text` (the file `path` as read now) if it is the code this process imported from it (or
    the file is not an imported module of gbmodel), else CodeChanged naming the file."""
    path = Path(path).resolve()
    module = (_gbmodel_modules() if modules is None else modules).get(path)
    if module is None:
        return text
    compiled = _codes(_facts(text)["code"])
    for code in _live_codes(module, path):
        if not _compiled_from(code, compiled.get(code.co_qualname, ())):
            raise CodeChanged(f"{path}: changed since this process imported it ({code.co_qualname} "
                              "differs); run the command again")
    name = _changed_value(module, text)
    if name is not None:
        raise CodeChanged(f"{path}: changed since this process imported it ({name} differs); "
                          "run the command again")
    return text


def imported_learners(sources, name: str) -> set[str]:
    """The other learners whose code the files `sources` ((label, text) pairs, labels as
    gbmodel/learners/...py) import, found in their import statements (relative ones resolved):
    online Goal Babbling and motor babbling run goal_babbling's reference code. A name imported
    from the learners package itself counts when it is a learner (`from gbmodel.learners import
    goal_babbling`), not when it is the registry's (`from . import register`)."""
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
    """gbmodel.learners.sources(name) of a learner of gbmodel/learners/ (its package's files, or
    its module's), read without importing it (sources imports the module to find its file: a
    cached simulate then loaded numba and scipy for nothing); None for any other learner (one
    registered at run time), which sources describes."""
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
    transitively (gbmodel.learners.sources of each, read from the files where it can: _files_of)."""
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
def _fingerprint(learner: str) -> tuple[str, dict, set]:
    """(fingerprint, resolved path -> the text hashed, the paths checked against their module)
    of `learner` (code_fingerprint), computed once per process."""
    root = Path(gbmodel.__file__).resolve().parent
    shared = [p for p in root.rglob("*.py")
              if "learners" not in p.relative_to(root).parts[:-1]]
    shared.append(root / "learners" / "__init__.py")
    theirs = learner_sources(learner)  # from the files: a learner not imported stays so
    texts = {p.resolve(): p.read_text() for p in shared}
    own = [(p.relative_to(root.parent).as_posix(), texts[p.resolve()]) for p in shared]
    for label, text in theirs:
        texts[(root.parent / label).resolve()] = text
    checked = set()
    _check_imported(texts, checked)
    return source_fingerprint(own + theirs), texts, checked


def _check_imported(texts: dict, checked: set) -> None:
    """as_imported for each file of `texts` whose module is imported now and was not checked
    yet: the text hashed must be the code the process imported (CodeChanged otherwise)."""
    modules = _gbmodel_modules()
    for path in texts.keys() & modules.keys() - checked:
        as_imported(path, texts[path], modules)
        checked.add(path)


_SEEN_MODULES: dict = {}  # learner -> len(sys.modules) when its imported files were last checked


def code_fingerprint(learner: str) -> str:
    """The fingerprint of the code a trial of `learner` runs: gbmodel's shared core (every file
    outside gbmodel/learners/, and the registry) plus that learner's own files and those of the
    learners it imports code from (learner_sources). Changing one learner recomputes its trials
    and those of the learners using its code only; an edited comment recomputes none.

    The files are read and hashed once per process (no module is imported for it: a cached
    simulate never loads a learner's kernels). Every file whose module the process has imported
    is checked against the text that was hashed (as_imported): on the first call, and again on
    any later call after the process imported more modules (a learner's, when its first trial
    runs; pipeline.worker.run_one asks again after each trial). A file edited between the read
    and the import therefore raises CodeChanged instead of keying new code's results with the
    old code's fingerprint."""
    fp, texts, checked = _fingerprint(learner)
    n = len(sys.modules)
    if _SEEN_MODULES.get(learner) != n:
        _check_imported(texts, checked)
        _SEEN_MODULES[learner] = n
    return fp


def _clear() -> None:
    _fingerprint.cache_clear()
    _SEEN_MODULES.clear()


code_fingerprint.cache_clear = _clear  # the tests' way to read the files again
