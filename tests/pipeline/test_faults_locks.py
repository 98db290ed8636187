"""Claims are bounded: one open file per run however many trials it claims; a planted link as
the claims file is refused, never followed."""
import os
import subprocess
import sys

import pytest

from pipeline import cache, io
from pipeline.config import REPO_ROOT, compose
from pipeline.plan import plan


def test_a_thousand_uncached_trials_under_256_open_files(tmp_path):
    cmd = ("ulimit -n 256 && exec " + sys.executable + " -m pipeline.simulate trials.count=1000 "
           f"learner.epochs=2 workers=1 growth=none paths.root={tmp_path}")
    r = subprocess.run(["bash", "-c", cmd], cwd=REPO_ROOT, capture_output=True, text=True,
                       timeout=600)
    assert r.returncode == 0, r.stderr[-2000:]
    assert "1000 trials: 0 cached, 1000 run, 0 failed" in r.stderr
    assert not list((tmp_path / "outputs/cache").rglob("*.lock"))


def test_claims_exclude_each_other_across_processes_and_within_one(tmp_path):
    a, b = plan(compose(["trials.count=2", "learner.epochs=10", f"paths.root={tmp_path}"]))
    mine = cache.Claim(tmp_path, a)
    assert mine.acquire()
    assert not cache.Claim(tmp_path, a).acquire()  # a second claim of this process
    other = subprocess.run(
        [sys.executable, "-c", "import sys, json; from pipeline import cache; "
         "print(cache.Claim(sys.argv[1], json.loads(sys.argv[2])).acquire(), "
         "cache.Claim(sys.argv[1], json.loads(sys.argv[3])).acquire())",
         str(tmp_path), __import__("json").dumps(dict(key=a["key"])),
         __import__("json").dumps(dict(key=b["key"]))],
        cwd=REPO_ROOT, capture_output=True, text=True, timeout=120)
    assert other.stdout.split() == ["False", "True"], other.stderr
    mine.release()
    assert cache.Claim(tmp_path, a).acquire()


def test_a_planted_claims_link_is_refused(tmp_path):
    target = tmp_path / "elsewhere"
    (tmp_path / "cache").mkdir()
    os.symlink(target, tmp_path / "cache" / cache.CLAIMS)
    (t,) = plan(compose(["trials.count=1", "learner.epochs=10", f"paths.root={tmp_path}"]))
    with pytest.raises(io.UnsafeName, match="a link"):
        cache.Claim(tmp_path / "cache", t).acquire()
    assert not target.exists()
