"""Keys from content: an edited URDF, a constant or default of gbmodel edited after the import,
a sidecar whose content does not hash to its key."""
import os
import shutil
import subprocess
import sys

import pytest

from pipeline import cache, io
from pipeline.config import REPO_ROOT, compose
from pipeline.keys import trial_key
from pipeline.plan import plan

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


ARM = """<?xml version="1.0"?>
<robot name="two">
  <link name="world"/><link name="l1"/><link name="l2"/><link name="tool"/>
  <joint name="j1" type="revolute"><parent link="world"/><child link="l1"/>
    <origin xyz="0 0 0.1"/><axis xyz="0 0 1"/><limit lower="-2" upper="2"/></joint>
  <joint name="j2" type="revolute"><parent link="l1"/><child link="l2"/>
    <origin xyz="0.3 0 0"/><axis xyz="0 0 1"/><limit lower="-2" upper="2"/></joint>
  <joint name="tip" type="fixed"><parent link="l2"/><child link="tool"/>
    <origin xyz="0.3 0 0"/></joint>
</robot>
"""


def _urdf_cfg(path, root):
    cfg = compose(["body=arm2", "trials.count=2", "learner.epochs=50", f"paths.root={root}",
                   "body.name=two", "body.outputs=[0,1]", "body.home=[0.3,0.6]", "body.grid.lo=[0.2,0.2]",
                   "body.grid.hi=[0.3,0.3]", "body.grid.num=[2,2]"])
    cfg.body.dh = None
    cfg.body.urdf = {"file": str(path), "root": "world", "tip": "tool"}
    return cfg


def test_an_edited_urdf_gives_other_keys(tmp_path):
    path = tmp_path / "two.urdf"
    path.write_text(ARM)
    keys = [t["key"] for t in plan(_urdf_cfg(path, tmp_path / "out"))]
    path.write_text(ARM.replace('<origin xyz="0.3 0 0"/><axis', '<origin xyz="0.45 0 0"/><axis'))
    again = [t["key"] for t in plan(_urdf_cfg(path, tmp_path / "out"))]
    assert len(keys) == 2 and not set(keys) & set(again)


def test_a_urdf_edited_after_planning_is_refused(tmp_path):
    import gbmodel
    path = tmp_path / "two.urdf"
    path.write_text(ARM)
    spec = plan(_urdf_cfg(path, tmp_path / "out"))[0]["spec"]
    gbmodel.make_body(spec["body"])  # as planned: fine
    path.write_text(ARM.replace("0 0 0.1", "0 0 0.2"))
    with pytest.raises(ValueError, match=r"^body.urdf.file=.*changed since this body was planned"):
        gbmodel.make_body(spec["body"])


def test_a_sidecar_whose_content_does_not_hash_to_its_key_is_refused(tmp_path):
    cfg = compose(["trials.count=2", "learner.epochs=20", f"paths.root={tmp_path}"])
    a, b = plan(cfg)
    result = dict(status="diverged", error="x", epoch=3)
    cache.write_trial(tmp_path, a, result)
    assert cache.check(tmp_path, a)[0] is not None
    # b's sidecar: a's content under b's key, sealed again (a copy that the seal cannot catch)
    record = {k: v for k, v in io.read_json(cache.trial_paths(tmp_path, a)[1]).items()
              if k != "seal"}
    record["key"] = b["key"]
    io.write_json(cache.trial_paths(tmp_path, b)[1], io.seal(record))
    done, why = cache.check(tmp_path, b)
    assert done is None and "do not hash to its key" in why
    assert trial_key(a["spec"], a["seed"], a["code"]) == a["key"]
