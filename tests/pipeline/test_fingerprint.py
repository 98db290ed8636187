"""The code fingerprint is taken from the code the process runs: a gbmodel file edited after the
process imported it is refused (CodeChanged, one line), not hashed as if it had run."""
import os
import shutil
import subprocess
import sys

from pipeline.config import REPO_ROOT

SCRIPT = """
import sys
from pathlib import Path
import gbmodel
from pipeline import fingerprint
growth = Path(gbmodel.__file__).parent / "growth.py"
assert str(growth).startswith(sys.argv[1]), growth
text = growth.read_text()
edit = sys.argv[2]
if edit == "code":  # what progress() computes changes after the import
    text = text.replace("    if schedule == \\"linear\\":\\n        return u", "    if schedule == \\"linear\\":\\n        return u * 1.0")
elif edit == "comment":  # a comment at the end: no code moves
    text += "# a comment\\n"
assert edit == "none" or text != growth.read_text()
growth.write_text(text)
try:
    print(fingerprint.code_fingerprint("goal_babbling"))
except fingerprint.CodeChanged as err:
    print("refused:", err)
"""


def _run(tmp_path, edit):
    copy = tmp_path / edit
    shutil.copytree(REPO_ROOT / "gbmodel", copy / "gbmodel",
                    ignore=shutil.ignore_patterns("__pycache__"))
    env = dict(os.environ, PYTHONPATH=f"{copy}{os.pathsep}{REPO_ROOT}", NUMBA_DISABLE_JIT="1")
    r = subprocess.run([sys.executable, "-c", SCRIPT, str(copy), edit], capture_output=True,
                       text=True, env=env, cwd=copy, timeout=120)
    assert r.returncode == 0, r.stderr
    return r.stdout.strip()


def test_a_file_edited_after_the_import_is_refused(tmp_path):
    out = _run(tmp_path, "code")
    assert out.startswith("refused: ") and "growth.py: changed since this process imported it" \
        in out and "progress differs" in out, out
    assert "\n" not in out


def test_unchanged_or_comment_edited_files_give_the_usual_fingerprint(tmp_path):
    from pipeline.fingerprint import code_fingerprint
    assert _run(tmp_path, "none") == _run(tmp_path, "comment") == code_fingerprint("goal_babbling")


LEARNT = """
import sys
from pathlib import Path
import gbmodel
from pipeline import fingerprint
assert str(Path(gbmodel.__file__)).startswith(sys.argv[1]), gbmodel.__file__
learnt = []
learn = fingerprint._learn
fingerprint._learn = lambda text: learnt.append(text) or learn(text)
print(fingerprint.code_fingerprint("goal_babbling"), len(learnt),
      sum("# edited" in t for t in learnt))
"""


def test_files_are_parsed_once_per_process_and_nothing_is_kept(tmp_path):
    """Each file is parsed once per process and kept nowhere (no record in gbmodel/__pycache__/);
    an edited file (its modification time put back) is read as it is now; a comment leaves the
    fingerprint as it was."""
    from pipeline.fingerprint import code_fingerprint
    copy = tmp_path / "code"
    shutil.copytree(REPO_ROOT / "gbmodel", copy / "gbmodel",
                    ignore=shutil.ignore_patterns("__pycache__"))
    env = dict(os.environ, PYTHONPATH=f"{copy}{os.pathsep}{REPO_ROOT}", NUMBA_DISABLE_JIT="1")

    def run():
        r = subprocess.run([sys.executable, "-c", LEARNT, str(copy)], capture_output=True,
                           text=True, env=env, cwd=copy, timeout=120)
        assert r.returncode == 0, r.stderr
        fp, learnt, edited = r.stdout.split()
        return fp, int(learnt), int(edited)

    usual = code_fingerprint("goal_babbling")
    fp, learnt, _ = run()
    assert fp == usual and learnt > 10  # every file of the learner and of the shared core
    assert run() == (usual, learnt, 0)  # each once, again in a new process: nothing kept
    growth = copy / "gbmodel" / "growth.py"
    stat = growth.stat()
    growth.write_text(growth.read_text() + "# edited\n")
    os.utime(growth, ns=(stat.st_atime_ns, stat.st_mtime_ns))  # the same modification time
    assert run() == (usual, learnt, 1)  # a comment: the same fingerprint, the file as it is
    assert not list((copy / "gbmodel").rglob("*.marshal"))  # (the records it kept before)


SHOW = """
import sys
from pathlib import Path
import gbmodel
from pipeline import fingerprint
assert str(Path(gbmodel.__file__)).startswith(sys.argv[1]), gbmodel.__file__
print(fingerprint.code_fingerprint("motor_babbling"))
"""


def test_a_changed_byte_changes_the_fingerprint_under_the_same_size_and_time(tmp_path):
    """The records are found by the SHA-256 of a file's text, never by its modification time or
    size: one digit of a learner's default changed in place (same length, its modification time
    put back) is a new fingerprint; put back, the old one (read from its record)."""
    copy = tmp_path / "code"
    shutil.copytree(REPO_ROOT / "gbmodel", copy / "gbmodel",
                    ignore=shutil.ignore_patterns("__pycache__"))
    env = dict(os.environ, PYTHONPATH=f"{copy}{os.pathsep}{REPO_ROOT}", NUMBA_DISABLE_JIT="1")

    def run() -> str:
        r = subprocess.run([sys.executable, "-c", SHOW, str(copy)], capture_output=True,
                           text=True, env=env, cwd=copy, timeout=120)
        assert r.returncode == 0, r.stderr
        return r.stdout.strip()

    learner = copy / "gbmodel" / "learners" / "motor_babbling.py"
    text, before = learner.read_text(), learner.stat()
    usual = run()
    assert "    spread: float = 0.4\n" in text
    learner.write_text(text.replace("    spread: float = 0.4\n", "    spread: float = 0.5\n"))
    os.utime(learner, ns=(before.st_atime_ns, before.st_mtime_ns))
    after = learner.stat()
    assert (after.st_size, after.st_mtime_ns) == (before.st_size, before.st_mtime_ns)
    edited = run()
    assert len(edited) == len(usual) == 16 and edited != usual
    learner.write_text(text)
    os.utime(learner, ns=(before.st_atime_ns, before.st_mtime_ns))
    assert run() == usual


LATE_IMPORT = """
import importlib, sys
from pathlib import Path
import gbmodel
from pipeline import fingerprint
assert str(Path(gbmodel.__file__)).startswith(sys.argv[1]), gbmodel.__file__
fp = fingerprint.code_fingerprint("motor_babbling")
name = "gbmodel.learners.motor_babbling"
assert name not in sys.modules and "numba" not in sys.modules  # read, not imported
learner = Path(gbmodel.__file__).parent / "learners" / "motor_babbling.py"
if sys.argv[2] == "edit":  # saved after the read, before the import: other code than hashed
    learner.write_text(learner.read_text().replace("spread: float = 0.4", "spread: float = 0.25"))
importlib.import_module(name)
try:
    print(fingerprint.code_fingerprint("motor_babbling") == fp)
except fingerprint.CodeChanged as err:
    print("refused:", err)
"""


def test_a_learner_is_hashed_without_its_import_and_checked_when_it_is_imported(tmp_path):
    """code_fingerprint reads a learner's files without importing it (a cached simulate loads
    no kernel); a later call, after the process imported the learner, checks the module against
    the text it hashed: a file saved in between is refused, one left alone passes."""
    for edit in ("none", "edit"):
        copy = tmp_path / edit
        shutil.copytree(REPO_ROOT / "gbmodel", copy / "gbmodel",
                        ignore=shutil.ignore_patterns("__pycache__"))
        env = dict(os.environ, PYTHONPATH=f"{copy}{os.pathsep}{REPO_ROOT}",
                   NUMBA_DISABLE_JIT="1")
        r = subprocess.run([sys.executable, "-c", LATE_IMPORT, str(copy), edit],
                           capture_output=True, text=True, env=env, cwd=copy, timeout=120)
        assert r.returncode == 0, r.stderr
        out = r.stdout.strip()
        if edit == "none":
            assert out == "True", out
        else:
            assert out.startswith("refused: ") and "motor_babbling.py: changed since this " \
                "process imported it" in out and "spread" in out, out


def test_a_profiled_run_is_not_taken_for_changed_code():
    """Under a profiler numba's dispatcher swaps its function's code for a copy with other
    flags (the same bytecode): `python -m cProfile -m pipeline.simulate` failed every fast-path
    trial with CodeChanged. The code is the file's; an edit still raises (test above)."""
    import cProfile

    import numpy as np

    import gbmodel
    from gbmodel.learners.goal_babbling import fast
    from pipeline import fingerprint
    from pipeline.tools.bench import paper_spec
    from pathlib import Path

    spec = gbmodel.TrialSpec.from_dict(paper_spec("arm5", 2, True))
    profile = cProfile.Profile()
    profile.enable()
    try:
        gbmodel.run_trial(spec, np.random.default_rng(0))  # the kernels called while profiled
    finally:
        profile.disable()
    path = Path(fast.__file__)
    assert fingerprint.as_imported(path, path.read_text()) == path.read_text()


def test_a_trusted_fingerprint_is_taken_for_the_same_bytes_only(monkeypatch):
    """fingerprint.trust (a pool worker's, from its driver): the fingerprint of exactly these
    bytes is taken, only the learner's own files parsed (their imports name the files); for any
    other bytes every file is parsed as usual."""
    from pipeline import fingerprint as f
    f.code_fingerprint.cache_clear()
    usual = f.code_fingerprint("goal_babbling")
    [key] = f.known()
    own = len(f.learner_sources("goal_babbling"))
    learnt = []
    monkeypatch.setattr(f, "_learn", lambda text: learnt.append(text) or dict(
        tree="another tree", imports=[]))
    try:
        for trusted, parses_all in (({key: usual}, False), ({"other bytes": usual}, True)):
            f.code_fingerprint.cache_clear()
            f._facts.cache_clear()
            learnt.clear()
            monkeypatch.setattr(f, "_TRUSTED", dict(trusted))
            fp = f.code_fingerprint("goal_babbling")
            assert (len(learnt) > own) == parses_all and (fp == usual) != parses_all
    finally:
        monkeypatch.undo()
        f.code_fingerprint.cache_clear()
        f._facts.cache_clear()
    assert f.code_fingerprint("goal_babbling") == usual
