"""Start-up: the heavy packages are imported only where they are used (issue 43, item 4).

`import pipeline` (which every stage, tool and `gbgrowth` command runs first) and the
`gbgrowth --version` / `--help` paths load none of the numerical or drawing stack; the engines'
names are known without importing what each engine runs on. Each check runs in a fresh
interpreter, so what this test process imported does not count.
"""
import json
import os
import subprocess
import sys

import pytest
from conftest import tiny_overrides

from pipeline.config import REPO_ROOT

HEAVY = ("pandas", "pyarrow", "matplotlib", "numba", "scipy")
LOADED = "import json, sys; print(json.dumps(sorted({m.split('.')[0] for m in sys.modules})))"


def loaded(code: str) -> set[str]:
    """The top-level packages a fresh interpreter holds after running `code` (then LOADED)."""
    env = dict(os.environ, PYTHONPATH=str(REPO_ROOT))
    proc = subprocess.run([sys.executable, "-c", f"{code}\n{LOADED}"], capture_output=True,
                          text=True, cwd="/", env=env, timeout=120)
    assert proc.returncode == 0, proc.stderr
    return set(json.loads(proc.stdout.strip().splitlines()[-1]))


def command(argv: list[str]) -> str:
    """`python -m pipeline ARGV` run in-process, its exit swallowed (then LOADED)."""
    return (f"import runpy, sys\nsys.argv = ['gbgrowth', *{argv!r}]\n"
            "try:\n    runpy.run_module('pipeline', run_name='__main__', alter_sys=True)\n"
            "except SystemExit:\n    pass")


@pytest.mark.parametrize("code", [
    "import pipeline",
    command(["--version"]),
    command(["--help"]),
], ids=["import pipeline", "gbgrowth --version", "gbgrowth --help"])
def test_the_package_and_version_load_no_heavy_package(code):
    """Before: importing the package registered the config (gbmodel's learners: numba, scipy)
    and the engines (the local pool: numpy, gbmodel) in every process, 1.8 s CPU for
    `gbgrowth --version`."""
    heavy = loaded(code) & {*HEAVY, "numpy", "hydra", "omegaconf", "gbmodel"}
    assert not heavy, f"{code!r} imported {sorted(heavy)}"


def test_naming_the_engines_imports_none_of_what_they_run_on():
    """The engine registry discovers every engine module (the config group `engine` is made
    from them) without the pool, the numerical core or a cluster package."""
    code = "from pipeline import engines\nassert 'local' in engines.available()"
    heavy = loaded(code) & {*HEAVY, "numpy", "gbmodel", "ray", "submitit"}
    assert not heavy, f"naming the engines imported {sorted(heavy)}"


def test_a_stage_config_loads_no_table_or_drawing_package():
    """The config every stage composes (pipeline.config) needs no table or drawing package."""
    heavy = loaded("import pipeline.config") & {"pandas", "pyarrow", "matplotlib"}
    assert not heavy, f"pipeline.config imported {sorted(heavy)}"


LEARNERS_IMPORTED = ("import sys\nimport pipeline.config as c\n"
                     "print([m for m in sys.modules if m.startswith('gbmodel.learners.')])\n")


def test_the_learner_schemas_need_no_learner_import_and_equal_their_params():
    """The config's learner schemas are read from each shipped learner's source (its Params),
    not from importing the learners (numba, scipy: 0.7 s CPU in every stage), and kept nowhere;
    what the source says is what the imported Params say."""
    import gbmodel
    from pipeline import config

    for name in set(gbmodel.learners.available()) - set(gbmodel.learners._REGISTERED):
        fields = config.learner_params(name)
        assert fields == config.defaults_of(gbmodel.learners.get(name).Params), name
    env = dict(os.environ, PYTHONPATH=str(REPO_ROOT))
    out = subprocess.run([sys.executable, "-c", LEARNERS_IMPORTED], capture_output=True,
                         text=True, cwd="/", env=env, timeout=120)
    assert out.returncode == 0 and out.stdout.strip() == "[]", out.stderr + out.stdout


def test_a_changed_learner_default_is_in_the_schema_at_once(tmp_path):
    """A learner's default edited in its file is in the schema at once (read from the file: no
    record to go stale, none written into the package)."""
    import shutil

    shutil.copytree(REPO_ROOT / "gbmodel", tmp_path / "gbmodel",
                    ignore=shutil.ignore_patterns("__pycache__"))
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(tmp_path), str(REPO_ROOT)]))
    show = ("import gbmodel, pipeline.config as c\nassert gbmodel.__file__.startswith(%r)\n"
            "print(c.compose([]).learner.get('spread', None),"
            " c.compose(['learner=motor_babbling']).learner.spread)\n" % str(tmp_path))

    def spread() -> str:
        out = subprocess.run([sys.executable, "-c", show], capture_output=True, text=True,
                             cwd="/", env=env, timeout=120)
        assert out.returncode == 0, out.stderr
        return out.stdout.strip()

    assert spread() == "None 0.4"
    learner = tmp_path / "gbmodel/learners/motor_babbling.py"
    text = learner.read_text()
    assert "    spread: float = 0.4\n" in text
    learner.write_text(text.replace("    spread: float = 0.4\n", "    spread: float = 0.25\n"))
    assert spread() == "None 0.25"
    assert not list((tmp_path / "gbmodel").rglob("params.*"))


COMPOSES = """
import atexit, sys
from hydra._internal.config_loader_impl import ConfigLoaderImpl
calls = []
real = ConfigLoaderImpl.load_configuration
def counted(self, *args, **kwargs):
    calls.append(kwargs.get("run_mode"))
    return real(self, *args, **kwargs)
ConfigLoaderImpl.load_configuration = counted
atexit.register(lambda: print("COMPOSES", len(calls), file=sys.stderr))
from pipeline import cli, simulate
sys.argv = ["pipeline.simulate", *sys.argv[1:]]
cli.main(simulate.main)
"""


def test_a_stage_composes_its_config_once_not_five_times(tmp_path):
    """A one-job stage composes the command line once: the check (config and Hydra's section
    at once, as Hydra's run composes it), and Hydra's run is given that config
    (config.hydra_run.composed_once); Hydra's section is checked by its values (an allow-list),
    with no compose of the project's own section to compare with. Before: five (the check's config and its Hydra
    section apart, the project's own section, Hydra's start once more only to read
    hydra.mode, and Hydra's run). The run is the same: the trial is computed and cached."""
    env = dict(os.environ, PYTHONPATH=str(REPO_ROOT))
    counts, errs = [], []
    for _ in range(2):
        out = subprocess.run([sys.executable, "-c", COMPOSES, *tiny_overrides(tmp_path)],
                             capture_output=True, text=True, cwd="/", env=env, timeout=300)
        assert out.returncode == 0, out.stderr
        counts.append(out.stderr.strip().splitlines()[-1])
        errs.append(out.stderr)
    assert "1 trials: 0 cached, 1 run, 0 failed" in errs[0], errs[0]
    assert "1 trials: 1 cached, 0 run, 0 failed" in errs[1], errs[1]
    assert counts == ["COMPOSES 1", "COMPOSES 1"], counts


def test_the_aggregate_stage_loads_no_statistics_pool_or_drawing_package():
    """`python -m pipeline.aggregate` imports pandas only where it computes a figure's
    statistics (a cached figure: none), and none of simulate's process pools (pipeline.execute:
    multiprocessing, concurrent.futures' process pool; the command line's check imported it for
    the one call that stops pools on Ctrl-C), nor gbmodel's learners or the drawing stack."""
    heavy = loaded("import pipeline.aggregate") & {"pandas", "multiprocessing", "matplotlib",
                                                     "numba", "scipy"}
    assert not heavy, f"pipeline.aggregate imported {sorted(heavy)}"
