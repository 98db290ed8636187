"""Keys from content: an edited URDF, a constant or default of gbmodel edited after the import,
a sidecar whose content does not hash to its key."""
import os
import shutil
import subprocess
import sys

import pytest

from pipeline import cache, io
from pipeline.config import REPO_ROOT, compose
from pipeline.plan import plan, trial_key

SCRIPT = """
import sys
from pathlib import Path
import gbmodel
import gbmodel.learners.goal_babbling
from pipeline import fingerprint
folder = Path(gbmodel.__file__).parent
path, old, new = folder / sys.argv[1], sys.argv[2], sys.argv[3]
text = path.read_text()
assert old in text, old
path.write_text(text.replace(old, new))
try:
    print(fingerprint.code_fingerprint("goal_babbling"))
except fingerprint.CodeChanged as err:
    print("refused:", err)
"""


def _edit(tmp_path, file, old, new):
    copy = tmp_path / "copy"
    shutil.copytree(REPO_ROOT / "gbmodel", copy / "gbmodel",
                    ignore=shutil.ignore_patterns("__pycache__"))
    env = dict(os.environ, PYTHONPATH=f"{copy}{os.pathsep}{REPO_ROOT}", NUMBA_DISABLE_JIT="1")
    r = subprocess.run([sys.executable, "-c", SCRIPT, file, old, new], capture_output=True,
                       text=True, env=env, cwd=copy, timeout=120)
    assert r.returncode == 0, r.stderr
    return r.stdout.strip()


@pytest.mark.parametrize("file, old, new, name", [
    ("evaluation.py", "HELDOUT_SEED = 20100907", "HELDOUT_SEED = 20100908", "HELDOUT_SEED"),
    ("learners/goal_babbling/__init__.py", "    radius: float = 0.2", "    radius: float = 0.3",
     "Params.radius"),
    ("evaluation.py", "def eval_epochs(epochs: int, per_decade: int = 20)",
     "def eval_epochs(epochs: int, per_decade: int = 21)", "eval_epochs (a default)"),
])
def test_a_constant_or_default_edited_after_the_import_is_refused(tmp_path, file, old, new, name):
    out = _edit(tmp_path, file, old, new)
    assert out.startswith("refused: ") and f"({name} differs)" in out, out


def test_an_unchanged_constant_gives_the_usual_fingerprint(tmp_path):
    from pipeline.fingerprint import code_fingerprint
    out = _edit(tmp_path, "evaluation.py", "HELDOUT_SEED = 20100907",
                "HELDOUT_SEED = 20100907  # the same value")
    assert out == code_fingerprint("goal_babbling")
