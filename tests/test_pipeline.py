"""End-to-end: simulate -> aggregate -> report on tiny settings in a temporary folder.

Checks the artifact schema, that a rerun computes nothing, that an interrupted run resumes to
the same files, that 1 and 2 workers give the same bytes, failures, bad input, Hydra multirun,
and that the report regenerates every file it lists, byte for byte.
"""
import json
import shutil
from pathlib import Path

import pandas as pd
import pyarrow.parquet as pq
import pytest

import gbmodel
import pipeline.simulate as simulate_mod
from pipeline import aggregate, cache, report, simulate
from pipeline.config import REPO_ROOT, CONF_DIR
from pipeline.report import listed_files
from conftest import files_of, run_cli, tiny_overrides

EXPERIMENTS = sorted(p.stem for p in (CONF_DIR / "experiment").glob("*.yaml"))
TRIAL_COLUMNS = ["figure", "body", "growth", "growth_period", "condition", "trial", "epoch", "size",
                 "abs_error", "rel_error"]
CURVE_STATS = [f"{c}_{s}" for c in ("abs_error", "rel_error") for s in ("mean", "std", "q25", "q75")]


@pytest.fixture(scope="module")
def smoke_tree(tmp_path_factory):
    """Every experiment simulated (tiny), aggregated and reported into one temporary tree."""
    from pipeline.config import compose

    root = tmp_path_factory.mktemp("smoke")
    summaries = {}
    for name in EXPERIMENTS:
        cfg = compose(tiny_overrides(root, f"experiment={name}"))
        summaries[name] = simulate.simulate(cfg)
    cfg = compose(tiny_overrides(root))
    assert aggregate.aggregate(cfg) == []
    _choices(cfg)
    report.report(cfg)
    return root, cfg, summaries


def _choices(cfg):
    """The open-choices stage at a tiny scale, into the report folder as `make` runs it."""
    from pipeline import choices

    choices.main(["--epochs", "20", "--seeds", "1", "--workers", "1", "--out",
                  str(cfg.paths.report), "--cache", str(Path(cfg.paths.cache) / "choices")])


@pytest.mark.parametrize("name", EXPERIMENTS)
def test_every_experiment_runs(smoke_tree, name):
    _, cfg, summaries = smoke_tree
    s = summaries[name]
    assert s.failed == {} and s.ran == s.total > 0


def test_trial_files_have_the_schema_and_sidecar(smoke_tree):
    _, cfg, _ = smoke_tree
    curves = sorted(p for p in Path(cfg.paths.cache).rglob("*.parquet")
                    if p.parent.name != "choices")  # the open-choices sweep has its own table
    assert curves
    for path in curves:
        df = pq.read_table(path).to_pandas()
        assert list(df.columns) == TRIAL_COLUMNS
        assert df["epoch"].is_monotonic_increasing and (df["abs_error"] > 0).all()
        assert ((df["rel_error"] - df["abs_error"] / df["size"]).abs() < 1e-12).all()
        side = json.loads(path.with_suffix(".json").read_text())
        assert side["key"] == path.stem and side["code"]
        assert set(side) >= {"labels", "spec", "seed", "fast", "M", "snapshots"}
        body = gbmodel.make_body(side["spec"]["body"])
        assert len(side["M"]) == body.m


def test_aggregate_schema(smoke_tree):
    _, cfg, _ = smoke_tree
    for name in EXPERIMENTS:
        df = pd.read_parquet(f"{cfg.paths.aggregate}/{name}/curves.parquet")
        assert [c for c in TRIAL_COLUMNS if c in df.columns] == [
            c for c in TRIAL_COLUMNS if c not in ("trial", "abs_error", "rel_error")]
        assert set(CURVE_STATS) <= set(df.columns)
        summ = pd.read_parquet(f"{cfg.paths.aggregate}/{name}/summary.parquet")
        assert {"final_abs_error_mean", "final_rel_error_std", "peak_abs_error_growth",
                "n_bootstrap_failures", "paper_final_abs_error"} <= set(summ.columns)
    summ = pd.read_parquet(f"{cfg.paths.aggregate}/fig7/summary.parquet")
    assert (summ["paper_final_abs_error"] == 0.006).all()


def test_report_lists_and_regenerates_its_files_byte_for_byte(smoke_tree):
    _, cfg, _ = smoke_tree
    out = Path(cfg.paths.report)
    listed = listed_files(out / "report.md")
    assert {"fig4_curves.png", "fig4_curves.pdf", "fig2_stages.png", "fig3_postures.pdf",
            "fig6_postures.png", "summary.csv", "summary.md", "report.md"} <= set(listed)
    before = files_of(out)
    assert sorted(before) == sorted(listed)
    shutil.rmtree(out)
    _choices(cfg)  # cached: writes its two files again without computing
    report.report(cfg)
    assert files_of(out) == before


def test_report_stage_regenerates_every_file_of_the_committed_report(smoke_tree):
    """outputs/report/ (committed, full scale) holds exactly the files its report.md lists, and
    the report stage, run at smoke scale, writes every one of them."""
    committed = REPO_ROOT / "outputs" / "report"
    listed = listed_files(committed / "report.md")
    assert sorted(listed) == sorted(p.name for p in committed.iterdir() if p.is_file())
    _, cfg, _ = smoke_tree
    regenerated = listed_files(Path(cfg.paths.report) / "report.md")
    assert set(listed) <= set(regenerated), set(listed) - set(regenerated)


def test_rerun_computes_nothing(smoke_tree, monkeypatch):
    from pipeline.config import compose

    root, _, _ = smoke_tree
    monkeypatch.setattr(simulate_mod, "run_one", lambda t: pytest.fail("a cached trial ran"))
    for workers in (1, 2):
        s = simulate.simulate(compose(tiny_overrides(root, "experiment=fig4", f"workers={workers}")))
        assert s.ran == 0 and s.cached == s.total


def test_interrupted_run_resumes_to_the_same_files(tmp_path, compose_tiny, monkeypatch):
    overrides = ("experiment=fig4", "trials.count=2")
    simulate.simulate(compose_tiny(tmp_path / "whole", *overrides))

    real_write, written = cache.write_trial, []

    def write_then_stop(*args):
        real_write(*args)
        written.append(1)
        if len(written) == 3:
            raise KeyboardInterrupt

    monkeypatch.setattr(cache, "write_trial", write_then_stop)
    with pytest.raises(KeyboardInterrupt):
        simulate.simulate(compose_tiny(tmp_path / "cut", *overrides))
    monkeypatch.setattr(cache, "write_trial", real_write)
    s = simulate.simulate(compose_tiny(tmp_path / "cut", *overrides))
    assert s.cached == 3 and s.ran == s.total - 3
    assert files_of(tmp_path / "cut/outputs/smoke/cache") == files_of(
        tmp_path / "whole/outputs/smoke/cache")


def test_one_and_two_workers_give_identical_files(tmp_path, compose_tiny):
    overrides = ("experiment=fig5", "conditions.periods=[10]", "conditions.references=[1.0]",
                 "trials.count=2")
    s1 = simulate.simulate(compose_tiny(tmp_path / "w1", *overrides, "workers=1"))
    s2 = simulate.simulate(compose_tiny(tmp_path / "w2", *overrides, "workers=2"))
    assert s1.ran == s2.ran == 4
    assert files_of(tmp_path / "w1/outputs/smoke/cache") == files_of(
        tmp_path / "w2/outputs/smoke/cache")


def test_a_failing_trial_is_recorded_and_the_others_finish(tmp_path, compose_tiny, monkeypatch):
    real = gbmodel.run_trial

    def flaky(spec, rng, fast=True):
        if spec.period == 100:
            raise FloatingPointError("diverged")
        return real(spec, rng, fast)

    monkeypatch.setattr(gbmodel, "run_trial", flaky)
    cfg = compose_tiny(tmp_path, "conditions.periods=[10,100]", "trials.count=2")
    s = simulate.simulate(cfg)
    assert len(s.failed) == 2 and s.ran == 4
    assert all("FloatingPointError: diverged" in e for e in s.failed.values())
    man = json.loads(cache.manifest_path(cfg.paths.cache, "custom").read_text())
    assert man["conditions"]["TG100"]["trials"]["0"]["status"] == "failed"
    assert len(list((tmp_path / "outputs/smoke/cache/custom").glob("*.parquet"))) == 2
    assert simulate_mod.run(cfg) == 1  # the failed trials run again, fail again: non-zero exit
    monkeypatch.setattr(gbmodel, "run_trial", real)
    assert simulate_mod.run(cfg) == 0


@pytest.mark.parametrize("override, shown", [
    ("body=leg", "body=leg: unknown option"), ("growth=sideways", "growth=sideways"),
    ("growth.period=-1", "growth.period=-1"), ("growth.period=1.5", "growth.period"),
    ("learner.epochs=0", "learner.epochs=0"), ("trials.count=0", "trials.count=0"),
    ("learner.radius=-0.1", "learner.radius=-0.1"), ("experiment=fig9", "experiment=fig9"),
    ("learner.rate=1", "learner.rate"), ("growth.period=10,100", "needs -m"),
])
def test_bad_input_is_one_clear_error_and_writes_nothing(tmp_path, override, shown):
    r = run_cli("pipeline.simulate", *tiny_overrides(tmp_path, override))
    assert r.returncode == 2
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: ") and shown in lines[0], r.stderr
    assert not list(tmp_path.rglob("*")), "nothing may be written, not even a log"


def test_bad_value_in_a_sweep_is_caught_before_any_job_runs(tmp_path):
    r = run_cli("pipeline.simulate", "-m", *tiny_overrides(tmp_path, "growth.period=10,-5"))
    assert r.returncode == 2 and "growth.period=-5" in r.stderr, r.stderr
    assert not (tmp_path / "outputs/smoke/cache").exists()


def test_hydra_multirun_fills_one_cache_that_aggregate_and_report_read(tmp_path):
    sweep = ["-m", "body=arm5", "growth=proportional", "growth.period=10,100", "trials.count=2",
             "learner.epochs=20", "workers=1", f"paths.root={tmp_path}"]
    r = run_cli("pipeline.simulate", *sweep)
    assert r.returncode == 0, r.stderr
    man = json.loads((tmp_path / "outputs/cache/custom/manifest.json").read_text())
    assert sorted(man["conditions"]) == ["TG10", "TG100"]
    # again, through the joblib launcher: everything is cached already
    r = run_cli("pipeline.simulate", *sweep, "hydra/launcher=joblib", "hydra.launcher.n_jobs=2")
    assert r.returncode == 0, r.stderr
    assert r.stderr.count("0 run, 0 failed") == 2
    for stage in ("pipeline.aggregate", "pipeline.report"):
        r = run_cli(stage, f"paths.root={tmp_path}")
        assert r.returncode == 0, r.stderr
    curves = pd.read_parquet(tmp_path / "outputs/aggregate/custom/curves.parquet")
    assert sorted(curves["condition"].unique()) == ["TG10", "TG100"]
    assert (tmp_path / "outputs/report/custom_curves.png").exists()
    assert not list(tmp_path.glob("*.log")) and not (tmp_path / "multirun").exists()


@pytest.mark.slow
def test_ctrl_c_on_two_workers_stops_at_once_and_resumes(tmp_path):
    """A real Ctrl-C (SIGINT to the process group) during a pool run, then a rerun."""
    import os
    import signal
    import subprocess
    import sys
    import time

    from pipeline.config import REPO_ROOT

    args = tiny_overrides(tmp_path / "cut", "experiment=fig7", "learner.epochs=3000",
                          "trials.count=2", "workers=2")
    env = dict(os.environ, PYTHONPATH=str(REPO_ROOT))
    proc = subprocess.Popen([sys.executable, "-m", "pipeline.simulate", *args], env=env,
                            stderr=subprocess.PIPE, text=True, start_new_session=True,
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    folder = tmp_path / "cut/outputs/smoke/cache/fig7"
    while not list(folder.glob("*.parquet")) and proc.poll() is None:
        time.sleep(0.2)
    os.killpg(proc.pid, signal.SIGINT)
    _, err = proc.communicate(timeout=30)
    assert proc.returncode == 130, err
    assert "interrupted" in err and "Traceback" not in err
    r = run_cli("pipeline.simulate", *args)
    assert r.returncode == 0 and "cached" in r.stderr
    whole = run_cli("pipeline.simulate", *tiny_overrides(
        tmp_path / "whole", "experiment=fig7", "learner.epochs=3000", "trials.count=2"))
    assert whole.returncode == 0
    assert files_of(tmp_path / "cut/outputs/smoke/cache") == files_of(
        tmp_path / "whole/outputs/smoke/cache")
