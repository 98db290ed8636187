"""A stage's config is composed once (issue 43 item 4): cli.check composes a one-job command line
as Hydra's run of the stage composes it (config.hydra_run.compose_as_run), and the run is given
that config (composed_once) instead of a second compose, only when its loader is asked for the very same
thing (arguments, search path, job name, working directory, environment)."""
import os
import subprocess
import sys

from conftest import tiny_overrides

from pipeline import cli, simulate
from pipeline.config import REPO_ROOT
from pipeline.config import hydra_run as hr

# Hydra's real run composes (the shortcut left out); what check() kept must be that config
SAME = """
import sys
from hydra._internal.config_loader_impl import ConfigLoaderImpl
from omegaconf import OmegaConf
from pipeline import cli, simulate
from pipeline.config import hydra_run as hr
sys.argv = ["pipeline.simulate", *sys.argv[1:]]
assert cli.check(sys.argv[1:], simulate.main) is None
key, given = hr.COMPOSED[0]
real = ConfigLoaderImpl.load_configuration
def capture(self, **k):
    cfg = real(self, **k)
    print("KEY", hr._load_key(self, k["config_name"], k["overrides"], k["run_mode"],
                              k["from_shell"], k["validate_sweep_overrides"]) == key)
    print("YAML", OmegaConf.to_yaml(cfg) == OmegaConf.to_yaml(given))
    print("TYPES", OmegaConf.get_type(cfg.learner) is OmegaConf.get_type(given.learner),
          OmegaConf.is_struct(cfg) == OmegaConf.is_struct(given))
    raise SystemExit(0)
ConfigLoaderImpl.load_configuration = capture
with hr.known_mode(hr.MODE):
    simulate.main()
"""


def test_the_run_is_given_the_config_hydra_would_compose(tmp_path):
    """What check() keeps for the run is, key and config, what Hydra's own run composes for the
    same command line (with Hydra's own overrides too); a mismatch of either would run a config
    other than Hydra's."""
    env = dict(os.environ, PYTHONPATH=str(REPO_ROOT))
    for extra in ([], ["hydra.job.chdir=false"]):
        out = subprocess.run([sys.executable, "-c", SAME, *tiny_overrides(tmp_path, *extra)],
                             capture_output=True, text=True, cwd="/", env=env, timeout=300)
        assert out.returncode == 0, out.stderr
        assert out.stdout.split() == ["KEY", "True", "YAML", "True", "TYPES", "True", "True"], (
            out.stdout + out.stderr)


def test_a_load_of_anything_else_composes(tmp_path, monkeypatch):
    """The kept config answers only the load it was composed for: other overrides, or the
    same ones under another environment, are composed (never the kept, stale config)."""
    argv = tiny_overrides(tmp_path, "workers=1")
    assert cli.check(argv, simulate.main) is None
    kept = list(hr.COMPOSED)
    hr.COMPOSED.clear()
    assert len(kept) == 1 and kept[0][1].workers == 1
    obj = kept[0][1]
    with hr.composed_once(kept):
        other = hr.compose_as_run(simulate.main, tiny_overrides(tmp_path, "workers=2",
                                                                 "hydra.mode=RUN"))
        assert other.workers == 2 and len(kept) == 1
        monkeypatch.setenv("GBGROWTH_TEST_COMPOSED_ONCE", "1")
        again = hr.compose_as_run(simulate.main, [*argv, "hydra.mode=RUN"])
        assert again is not obj and len(kept) == 1  # another environment
        monkeypatch.delenv("GBGROWTH_TEST_COMPOSED_ONCE")
        same = hr.compose_as_run(simulate.main, [*argv, "hydra.mode=RUN"])
        assert same is obj and kept == []  # the very load: given the kept config, once
    hr.COMPOSED.clear()
