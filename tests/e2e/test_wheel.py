"""Installed, not only cloned (docs/install.md): the wheel built from the checkout, installed into
a fresh virtual environment in a temporary folder, runs a small sweep, aggregate, report and
models with its own `gbgrowth` command from a folder outside the checkout, finds a conf/ of that
folder, and writes every output under it: nothing into the checkout, nothing into the installed
package (issue: "Install it, run it anywhere").

The default suite builds the wheel offline (`pip wheel --no-build-isolation` with this
environment's setuptools, which `make setup` installs: the test extra) and installs it without
its dependencies, which the fresh environment borrows from this one by a .pth line: about a
minute. The slow test installs as a user does, `pip install .` with every dependency from the
package index, and runs the compiled kernels."""
import json
import os
import shutil
import subprocess
import sys
import sysconfig
import time
import tomllib
from pathlib import Path

import pytest

from pipeline import __version__
from pipeline.config import REPO_ROOT

# what the wheel is built from (pyproject.toml names the packages and the package data)
SOURCES = ("pyproject.toml", "README.md", "LICENSE", "conf", "gbmodel", "pipeline")
IGNORE = shutil.ignore_patterns("__pycache__", "*.pyc", "*.nbi", "*.nbc")
SKIP = {".git", ".venv", "__pycache__", ".pytest_cache"}  # caches, not the project's files
# the user's own experiment, in a conf/ of the working folder: found by convention
OWN_EXPERIMENT = """# @package _global_
figure: mine
trials:
  count: 1
"""


def files_state(folder: Path) -> dict[str, tuple[int, int]]:
    """Relative path -> (size, mtime in ns) of every file under folder but caches (__pycache__:
    Python's bytecode and numba's compiled kernels, which numba keeps beside the sources)."""
    out = {}
    for dirpath, dirnames, filenames in os.walk(folder):
        dirnames[:] = [d for d in dirnames if d not in SKIP]
        for f in filenames:
            p = Path(dirpath) / f
            st = p.lstat()
            out[p.relative_to(folder).as_posix()] = (st.st_size, st.st_mtime_ns)
    return out


def copy_sources(tmp: Path) -> Path:
    """A copy of the checkout's sources: a build writes build/ and *.egg-info beside what it
    builds, into the copy, not the checkout."""
    src = tmp / "src"
    src.mkdir()
    for name in SOURCES:
        p = REPO_ROOT / name
        (shutil.copytree(p, src / name, ignore=IGNORE) if p.is_dir()
         else shutil.copy2(p, src / name))
    return src


def build_wheel(tmp: Path) -> Path:
    """The wheel, built offline with this environment's setuptools."""
    r = subprocess.run([sys.executable, "-m", "pip", "wheel", "--no-deps", "-q",
                        "--no-build-isolation", "--no-index", "-w", str(tmp / "dist"),
                        str(copy_sources(tmp))], capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr[-3000:]
    (wheel,) = (tmp / "dist").glob("gbgrowth-*.whl")
    return wheel


def clean_env(**extra) -> dict:
    """The environment of a user's shell: no PYTHONPATH leading back to the checkout."""
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "PYTHONHOME")}
    return dict(env, MPLBACKEND="Agg", **extra)


def run_installed(venv: Path, work: Path, fast: bool, env: dict) -> dict[str, float]:
    """In `work`: a sweep, aggregate, report and models with the installed commands; every
    output checked to lie under `work`. Returns the seconds of each command."""
    gb = str(venv / "bin" / "gbgrowth")
    (work / "conf" / "experiment").mkdir(parents=True)
    (work / "conf" / "experiment" / "mine.yaml").write_text(OWN_EXPERIMENT)
    tiny = ["experiment=mine", "figure=mine", "learner.epochs=30", "workers=1"]
    if fast:
        tiny.append("learner.fast=false")  # the numpy path: no kernel to compile here
    times = {}

    def run(name, *args, python=False):
        start = time.perf_counter()
        cmd = [str(venv / "bin" / "python"), *args] if python else [gb, *args]
        r = subprocess.run(cmd, cwd=work, env=env, capture_output=True, text=True, timeout=900)
        times[name] = round(time.perf_counter() - start, 1)
        assert r.returncode == 0, f"{name}: {r.stderr[-3000:]}"
        return r.stdout

    assert run("--version", "--version").strip() == f"gbgrowth {__version__}"
    run("simulate", "simulate", "-m", *tiny, "growth.period=10,20")
    run("aggregate", "aggregate", *tiny)
    run("report", "report", *tiny, "report.explain=false")
    listing = run("models", "models", "outputs/aggregate/mine")
    assert "mine: 2 condition(s)" in listing and "TG10: arm5, 1 trial(s)" in listing
    check = f"""
import json, gbmodel, pipeline
from pipeline import models
fig = models.load("mine")                                   # by name: outputs/ of this folder
committed = models.load({str(REPO_ROOT / "outputs/report/models/fig4.json")!r})  # by path
x = committed["TG1000"].body.target_set(1.0)[:3]
print(json.dumps(dict(files=[gbmodel.__file__, pipeline.__file__], labels=fig.labels,
                      reach=committed["TG1000"].reach(x).tolist(),
                      bodies=list(gbmodel.BODIES), arm5=gbmodel.make_body("arm5").m,
                      learners=list(gbmodel.learners.available()))))
"""
    got = json.loads(run("models.load", "-c", check, python=True))
    site = Path(sysconfig.get_paths(vars={"base": str(venv), "platbase": str(venv)})["purelib"])
    assert all(Path(f).is_relative_to(site) for f in got["files"]), got["files"]
    assert got["labels"] == ["TG10", "TG20"] and len(got["reach"]) == 3
    assert "arm5" in got["bodies"] and got["arm5"] == 5 and "goal_babbling" in got["learners"]

    out = work / "outputs"
    assert (out / "aggregate" / "mine" / "models.json").is_file()
    report = (out / "latest" / "mine" / "report.md").read_text()
    assert "## Provenance" in report
    snapshots = sorted(out.glob("logs/*/*/.hydra/config.yaml")) + sorted(
        out.glob("logs/*/*/*/.hydra/config.yaml"))
    stages = {p.relative_to(out / "logs").parts[0] for p in snapshots}
    assert {"simulate-multirun", "aggregate", "report"} <= stages, stages
    overrides = next(p for p in snapshots if "aggregate" in p.parts).parent / "overrides.yaml"
    assert "experiment=mine" in overrides.read_text()
    assert sorted(p.name for p in work.iterdir()) == ["conf", "outputs"]
    return times


def fresh_venv(tmp: Path, with_pip: bool) -> Path:
    venv = tmp / "venv"
    args = [] if with_pip else ["--without-pip"]
    subprocess.run([sys.executable, "-m", "venv", *args, str(venv)], check=True, timeout=300)
    return venv


def site_packages(venv: Path) -> Path:
    return Path(subprocess.run(
        [str(venv / "bin" / "python"), "-c", "import sysconfig; print(sysconfig.get_paths()"
         "['purelib'])"], capture_output=True, text=True, check=True).stdout.strip())


def test_the_wheel_installs_and_runs_outside_the_checkout(tmp_path):
    import setuptools

    major, minor = (int(x) for x in setuptools.__version__.split(".")[:2])
    assert (major, minor) >= (70, 1), (
        f"setuptools {setuptools.__version__}: building a wheel offline needs >= 70.1 (its own "
        "bdist_wheel); make setup installs it (pyproject.toml: the test extra)")
    before = files_state(REPO_ROOT)
    start = time.perf_counter()
    wheel = build_wheel(tmp_path)
    venv = fresh_venv(tmp_path, with_pip=False)
    site = site_packages(venv)
    # the dependencies: this environment's, borrowed by one .pth line (its own .pth files,
    # this checkout's editable install among them, are not read)
    ours = [p for p in sys.path if Path(p).name == "site-packages" and Path(p).is_dir()]
    (site / "_gbgrowth_test_dependencies.pth").write_text("".join(f"{p}\n" for p in ours))
    r = subprocess.run([sys.executable, "-m", "pip", "--python", str(venv / "bin" / "python"),
                        "install", "--no-deps", "--no-index", "-q", str(wheel)],
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr[-3000:]
    installed = time.perf_counter() - start
    package = files_state(site)
    work = tmp_path / "work"
    work.mkdir()
    times = run_installed(venv, work, fast=True, env=clean_env())
    print(f"build + install {installed:.1f} s; " + ", ".join(f"{k} {v} s" for k, v in times.items()))
    assert files_state(site) == package  # nothing written into the installed package
    assert files_state(REPO_ROOT) == before  # nor into the checkout


def test_the_wheel_lists_every_package_and_the_configs():
    """pyproject.toml lists the packages by name (conf/ is mapped to gbgrowth_conf): a new
    package folder must be listed, else the wheel lacks it."""
    tool = tomllib.loads((REPO_ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]
    on_disk = {p.parent.relative_to(REPO_ROOT).as_posix().replace("/", ".")
               for top in ("gbmodel", "pipeline")
               for p in (REPO_ROOT / top).rglob("__init__.py") if "__pycache__" not in p.parts}
    assert set(tool["packages"]) == on_disk | {"gbgrowth_conf"}
    assert tool["package-dir"] == {"gbgrowth_conf": "conf"}
    assert (REPO_ROOT / "conf" / "__init__.py").is_file()  # Hydra's pkg:// needs it
    assert not list((REPO_ROOT / "conf").glob("*/*/*.yaml"))  # package-data: two levels
    data = tool["package-data"]
    for top in ("gbmodel", "pipeline"):  # every data file a module reads is package data
        for p in (REPO_ROOT / top).rglob("*"):
            if p.is_file() and p.suffix != ".py" and "__pycache__" not in p.parts:
                assert any(p.match(pattern) for pattern in data["*"]), p


@pytest.mark.slow
def test_pip_install_from_the_index_runs_the_compiled_kernels(tmp_path):
    """As a user installs: `pip install <checkout>` into a fresh environment, every dependency
    from the package index (a few minutes), then the same commands on the compiled kernels."""
    before = files_state(REPO_ROOT)
    src = copy_sources(tmp_path)
    venv = fresh_venv(tmp_path, with_pip=True)
    start = time.perf_counter()
    r = subprocess.run([str(venv / "bin" / "python"), "-m", "pip", "install", "-q",
                        "-c", str(REPO_ROOT / "requirements.lock"), str(src)],
                       capture_output=True, text=True, timeout=1800, env=clean_env())
    assert r.returncode == 0, r.stderr[-3000:]
    installed = time.perf_counter() - start
    site = site_packages(venv)
    package = {k: v for k, v in files_state(site).items() if k.startswith(("gbmodel/",
                                                                           "pipeline/",
                                                                           "gbgrowth_conf/"))}
    work = tmp_path / "work"
    work.mkdir()
    times = run_installed(venv, work, fast=False, env=clean_env())
    print(f"pip install {installed:.1f} s; " + ", ".join(f"{k} {v} s" for k, v in times.items()))
    after = {k: v for k, v in files_state(site).items() if k in package or k.startswith((
        "gbmodel/", "pipeline/", "gbgrowth_conf/"))}
    assert after == package
    assert files_state(REPO_ROOT) == before


def test_the_citation_names_this_version_and_the_paper():
    """CITATION.cff (GitHub's "Cite this repository"): this version, a release date, the paper
    as a reference and as the preferred citation."""
    import datetime

    import yaml

    cff = yaml.safe_load((REPO_ROOT / "CITATION.cff").read_text())
    assert cff["cff-version"] == "1.2.0" and cff["version"] == __version__
    datetime.date.fromisoformat(cff["date-released"])
    paper = cff["preferred-citation"]
    assert paper in cff["references"] and paper["year"] == 2010
    assert paper["title"] == "Mastering Growth while Bootstrapping Sensorimotor Coordination"
    assert [a["family-names"] for a in paper["authors"]] == ["Rolf", "Steil", "Gienger"]
