"""Ready to publish: `python -m build` gives an sdist and a wheel that `twine check --strict`
accepts, and CITATION.cff validates against the Citation File Format's schema (cffconvert).
Needs the extra [publish] (make publish installs it, and cffconvert in a throwaway environment:
it pins an older jsonschema); without them the tests skip and say so. Built offline, from a copy
of the sources, as tests/e2e/test_wheel.py builds its wheel."""
import os
import shutil
import subprocess
import sys
import tarfile
import zipfile

import pytest

from pipeline import __version__
from pipeline.config import REPO_ROOT
from test_wheel import copy_sources


def test_build_gives_an_sdist_and_a_wheel_that_twine_accepts(tmp_path):
    pytest.importorskip("build", reason="the extra [publish]: make publish")
    pytest.importorskip("twine", reason="the extra [publish]: make publish")
    src, dist = copy_sources(tmp_path), tmp_path / "dist"
    for name in ("CITATION.cff", "MANIFEST.in"):
        shutil.copy2(REPO_ROOT / name, src / name)
    r = subprocess.run([sys.executable, "-m", "build", "--no-isolation", "--sdist", "--wheel",
                        "--outdir", str(dist), str(src)], capture_output=True, text=True,
                       timeout=600)
    assert r.returncode == 0, r.stderr[-3000:]
    sdist = dist / f"gbgrowth-{__version__}.tar.gz"
    wheel = dist / f"gbgrowth-{__version__}-py3-none-any.whl"
    r = subprocess.run([sys.executable, "-m", "twine", "check", "--strict", str(sdist), str(wheel)],
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 0 and r.stdout.count("PASSED") == 2, r.stdout + r.stderr
    with zipfile.ZipFile(wheel) as z:
        names = set(z.namelist())
        entry = z.read(f"gbgrowth-{__version__}.dist-info/entry_points.txt").decode()
    assert {"pipeline/envs/growing_reach.py", "pipeline/html_report.py"} <= names
    assert "[gymnasium.envs]\ngbgrowth = pipeline.envs:register_envs" in entry
    with tarfile.open(sdist) as t:
        assert f"gbgrowth-{__version__}/CITATION.cff" in t.getnames()


def test_the_citation_file_validates_against_its_schema():
    cff = shutil.which("cffconvert") or str(REPO_ROOT / "build" / "cff" / "bin" / "cffconvert")
    if not os.access(cff, os.X_OK):
        pytest.skip("no cffconvert: make publish installs it (in build/cff/)")
    r = subprocess.run([cff, "--validate", "-i", str(REPO_ROOT / "CITATION.cff")],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 0 and "valid" in r.stdout, r.stdout + r.stderr
