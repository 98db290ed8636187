"""The code fingerprint of a trial: a hash of the gbmodel code that computes it (the shared core
plus its learner's files), as part of its cache key, so a trial is recomputed when its code
changes and only then. Files are read, not imported, and each text is parsed once per process
(_facts); a pool's workers are handed the driver's fingerprints (trust) and take one where
their files are the driver's byte for byte, dumping only their learner's syntax trees (whose
imports name the files). The text of every gbmodel file is kept as this module's import found
it (_AT_IMPORT); a file of an imported module whose syntax (comments and docstrings aside)
differs between that text, the text hashed and the file now was edited while the process ran:
CodeChanged, a one-line error naming the definition that differs: run the command again. (A file
saved before this module's import, after its module's, is not seen: the stages import it within
a second.)
"""
from __future__ import annotations

import ast
import hashlib
import itertools
import sys
from functools import lru_cache
from pathlib import Path

import gbmodel
import gbmodel.learners


class CodeChanged(RuntimeError):
    """A gbmodel file differs from the code this process imported from it."""


def _dump(tree, imports: list | None = None) -> str:
    """ast.dump of `tree` with its docstrings taken out (in place); its imports appended to
    `imports` in the same walk."""
    for node in ast.walk(tree):
        if imports is not None and isinstance(node, (ast.ImportFrom, ast.Import)):
            imports.append(("from", node.level, node.module, [a.name for a in node.names])
                           if isinstance(node, ast.ImportFrom)
                           else ("import", None, None, [a.name for a in node.names]))
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


def _learn(text: str) -> dict:
    """From one parse: tree (without docstrings) and imports: ("from", level, module or None,
    [names]) or ("import", None, None, [names])."""
    imports = []
    tree = _dump(ast.parse(text), imports)
    return dict(tree=tree, imports=imports)


_facts = lru_cache(maxsize=512)(lambda text: _learn(text))  # once per text and process


def _bytes_key(sources) -> str:
    """sha256 of (name, text) pairs as they are, byte for byte (each with its length)."""
    h = hashlib.sha256()
    for name, text in sorted(sources):
        name, text = name.encode(), text.encode()
        h.update(b"%d %d\0" % (len(name), len(text)) + name + text)
    return h.hexdigest()


_TRUSTED: dict = {}  # _bytes_key -> fingerprint: computed here, or handed over (trust)


def known() -> dict:
    """The fingerprints this process has, by the bytes they were computed from: what a pool's
    workers are handed (trust)."""
    return dict(_TRUSTED)


def trust(fingerprints: dict) -> None:
    """Take these fingerprints (known() of the process that starts this one) for files whose
    bytes are those they were computed from: the same texts give the same fingerprint."""
    _TRUSTED.update(fingerprints)


_AT_IMPORT = {p.resolve(): p.read_text()
              for p in Path(gbmodel.__file__).resolve().parent.rglob("*.py")}


def _changed(a: list, b: list, where: str = "") -> str:
    """The first definition or assignment of statements `a` whose syntax differs from `b`'s."""
    for x, y in itertools.zip_longest(a, b):
        if x is None or y is None or ast.dump(x) != ast.dump(y):
            if isinstance(x, ast.ClassDef) and isinstance(y, ast.ClassDef):
                return _changed(x.body, y.body, f"{where}{x.name}.")
            if isinstance(x, ast.FunctionDef) and isinstance(y, ast.FunctionDef):
                default = ast.dump(x.args) != ast.dump(y.args)
                return f"{where}{x.name}{' (a default)' if default else ''}"
            names = [t.id for t in getattr(x, "targets", [getattr(x, "target", None)])
                     if isinstance(t, ast.Name)]
            return where + (getattr(x, "name", None) or ", ".join(names) or "a statement")
    return where.rstrip(".")


def _gbmodel_modules() -> dict:
    """Resolved file -> module, for the imported modules of gbmodel."""
    return {Path(m.__file__).resolve(): m for name, m in list(sys.modules.items())
            if (name == "gbmodel" or name.startswith("gbmodel."))
            and getattr(m, "__file__", None)}


def as_imported(path: Path, text: str, modules: dict | None = None) -> str:
    """`text` (the file `path` as hashed) if its module ran the same code (the file as this
    module's import found it and as it is now, comments and docstrings aside), or the file is not
    an imported module of gbmodel, else CodeChanged naming the file and the definition."""
    path = Path(path).resolve()
    if path not in (_gbmodel_modules() if modules is None else modules):
        return text
    for other in (_AT_IMPORT.get(path, text), path.read_text()):
        if other != text and _facts(other)["tree"] != _facts(text)["tree"]:
            changed = _changed(ast.parse(other).body, ast.parse(text).body)
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


def learner_sources(learner: str) -> list[tuple[str, str]]:
    """(label, text) of the learner's own files and of every learner's whose code it imports,
    transitively."""
    done, todo, out = set(), [learner], {}
    while todo:
        name = todo.pop()
        if name in done:
            continue
        done.add(name)
        theirs = gbmodel.learners.sources(name)
        out.update(theirs)
        todo += sorted(imported_learners(theirs, name) - done)
    return sorted(out.items())


@lru_cache(maxsize=None)
def _fingerprint(learner: str) -> tuple[str, dict, set, list]:
    """(fingerprint, resolved path -> the text hashed, the paths checked against their module,
    [len(sys.modules) at the last check]) of `learner`, computed once per process (or taken from
    _TRUSTED for the same bytes)."""
    root = Path(gbmodel.__file__).resolve().parent
    shared = [p for p in root.rglob("*.py")
              if "learners" not in p.relative_to(root).parts[:-1]]
    shared.append(root / "learners" / "__init__.py")
    theirs = learner_sources(learner)  # from the files: a learner not imported stays so
    texts = {p.resolve(): p.read_text() for p in shared}
    own = [(p.relative_to(root.parent).as_posix(), texts[p.resolve()]) for p in shared]
    for label, text in theirs:
        texts[(root.parent / label).resolve()] = text
    key = _bytes_key(own + theirs)
    fp = _TRUSTED[key] = _TRUSTED.get(key) or source_fingerprint(own + theirs)
    return fp, texts, set(), [None]


def code_fingerprint(learner: str) -> str:
    """The fingerprint of gbmodel's shared core (every file outside gbmodel/learners/, and the
    registry) and `learner`'s files (learner_sources), its imported files checked (as_imported)
    again after the process imported more (pipeline.worker.run_one asks after each trial)."""
    fp, texts, checked, seen = _fingerprint(learner)
    if seen[0] != len(sys.modules):
        modules, n = _gbmodel_modules(), len(sys.modules)
        for path in texts.keys() & modules.keys() - checked:
            as_imported(path, texts[path], modules)
            checked.add(path)
        seen[0] = n
    return fp


def _cache_clear() -> None:
    _fingerprint.cache_clear()
    _TRUSTED.clear()


code_fingerprint.cache_clear = _cache_clear  # the tests' way to read files again
