"""SLURM as labs run it: account, qos, gres, constraint and free-form sbatch options reach the
job script submitit writes; the stages that do not submit do not need submitit."""
import importlib.util
import shutil

import pytest

from conftest import tiny_overrides
import dataclasses

from pipeline import engines, simulate
from pipeline.engines import submitit_jobs
from pipeline.config import ConfigError, compose
from pipeline.plan import plan

LAB = ["engine=slurm", "engine.account=lab42", "engine.qos=short", "engine.gres=tmpdisk:10",
       "engine.constraint=avx2", "+engine.extra.reservation=course", "engine.partition=cpu"]


def _params(cfg):
    from omegaconf import OmegaConf

    _, settings = engines.settings_of(OmegaConf.to_container(cfg.engine))
    return submitit_jobs.job_parameters(dataclasses.asdict(settings), 4, "slurm", "fig4")


def test_lab_options_compose_and_become_submitit_parameters():
    params = _params(compose(LAB))
    assert params["slurm_account"] == "lab42" and params["slurm_qos"] == "short"
    assert params["slurm_gres"] == "tmpdisk:10" and params["slurm_constraint"] == "avx2"
    assert params["slurm_additional_parameters"] == {"reservation": "course"}
    plain = _params(compose(["engine=slurm"]))  # unset: nothing is passed, SLURM's defaults
    assert not {"slurm_account", "slurm_qos", "slurm_gres", "slurm_constraint",
                "slurm_additional_parameters"} & set(plain)


def test_lab_options_reach_the_sbatch_script(monkeypatch, tmp_path):
    submitit = pytest.importorskip("submitit")
    real = shutil.which
    monkeypatch.setattr(shutil, "which", lambda n, *a: f"/usr/bin/{n}" if n == "srun"
                        else real(n, *a))  # build the script without a cluster
    ex = submitit.AutoExecutor(folder=str(tmp_path), cluster="slurm")
    ex.update_parameters(**_params(compose(LAB)))
    script = ex._executor._make_submission_file_text("echo", "u1")
    for line in ("#SBATCH --account=lab42", "#SBATCH --qos=short", "#SBATCH --gres=tmpdisk:10",
                 "#SBATCH --constraint=avx2", "#SBATCH --reservation=course",
                 "#SBATCH --partition=cpu"):
        assert line in script, script


def test_only_the_stage_that_submits_needs_submitit(monkeypatch, tmp_path):
    real = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec",
                        lambda name, *a: None if name == "submitit" else real(name, *a))
    cfg = compose(tiny_overrides(tmp_path, "engine=slurm"))
    assert plan(cfg)  # aggregate and report plan the figure: no package needed
    with pytest.raises(ConfigError, match=r"needs the package submitit"):
        simulate.jobs_of(cfg)
