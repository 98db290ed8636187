"""End-to-end: simulate -> aggregate -> report on tiny settings in a temporary folder.

Checks the artifact schema, that a rerun computes nothing, that an interrupted run resumes to
the same files, that 1 and 2 workers give the same bytes, failures, bad input, Hydra multirun,
and that the report regenerates every file it lists, byte for byte.
"""
import hashlib
import json
from pathlib import Path

import pandas as pd
import pyarrow.parquet as pq
import pytest

import gbmodel
import pipeline.simulate as simulate_mod
from pipeline import aggregate, cache, engines, execute, io, report, simulate
from pipeline.config import CONF_DIR, REPO_ROOT, compose
from pipeline.fingerprint import code_fingerprint
from pipeline.report import listed_files
from conftest import figure_trials, files_of, run_cli, tiny_overrides

EXPERIMENTS = sorted(p.stem for p in (CONF_DIR / "experiment").glob("*.yaml"))
# The readings studies run here on the reference path (every reading, short, one growing
# condition; the path evaluation is slow), the kernel's agreement is tests/studies/test_readings.py's.
READINGS = ("learner.fast=false", "learner.epochs=12", "learner.evals_per_decade=3",
            "conditions.periods=[10]")
CURVE_STATS = [f"{c}_{s}" for c in ("abs_error", "rel_error") for s in ("mean", "std", "q25", "q75")]
SIDECAR = {"key", "labels", "spec", "seed", "code", "status", "curve_sha256", "M", "snapshots",
           "seal"}


def experiment_overrides(root, name):
    return tiny_overrides(root, f"experiment={name}",
                          *(READINGS if name.startswith("readings") else ()))


@pytest.fixture(scope="module")
def smoke_tree(tmp_path_factory):
    """Every experiment simulated (tiny), aggregated and reported into one temporary tree."""
    root = tmp_path_factory.mktemp("smoke")
    summaries = {}
    for name in EXPERIMENTS:
        summaries[name] = simulate.simulate(compose(experiment_overrides(root, name)))
    cfg = compose(tiny_overrides(root))
    summaries["aggregate problems"] = aggregate.aggregate(cfg)
    report.report(cfg)
    return root, cfg, summaries


@pytest.mark.parametrize("name", EXPERIMENTS)
def test_every_experiment_runs(smoke_tree, name):
    _, cfg, summaries = smoke_tree
    s = summaries[name]
    assert s.failed == {} and s.ran + s.cached == s.total > 0  # cached: shared with a figure before
    trials, problems = figure_trials(cfg.paths.cache, compose([f"experiment={name}"]).figure)
    assert len({t["key"] for t in trials}) == s.total and problems == []


def test_aggregate_finds_every_trial(smoke_tree):
    assert smoke_tree[2]["aggregate problems"] == []


def test_trial_files_have_the_schema_and_sidecar(smoke_tree):
    _, cfg, _ = smoke_tree
    curves = sorted(Path(cfg.paths.cache).rglob("*.parquet"))
    assert curves
    for path in curves:
        assert pq.read_schema(path).equals(io.TRIAL_CURVE, check_metadata=False), path
        df = pq.read_table(path).to_pandas()
        assert df["epoch"].is_monotonic_increasing and (df["abs_error"] > 0).all()
        assert ((df["rel_error"] - df["abs_error"] / df["size"]).abs() < 1e-12).all()
        side = json.loads(path.with_suffix(".json").read_text())
        assert set(side) >= SIDECAR and side["status"] == "ok"
        assert side["key"] == path.stem and side["code"]
        assert side["curve_sha256"] == hashlib.sha256(path.read_bytes()).hexdigest()
        assert "seconds" not in side  # timing varies from run to run; the sidecar's bytes do not
        assert "figure" not in side and "condition" not in side["labels"]  # content only
        assert io.check_seal(side) == side
        if side["spec"]["learner"]["name"] == "goal_babbling":  # M: (m, features)
            assert len(side["M"]) == gbmodel.make_body(**side["spec"]["body"]).m


def test_aggregate_schema(smoke_tree):
    _, cfg, _ = smoke_tree
    group = [c for c in io.LABEL_COLUMNS if c != "trial"]
    for name in EXPERIMENTS:
        fig = compose([f"experiment={name}"]).figure
        folder = Path(cfg.paths.aggregate) / fig
        assert pq.read_schema(folder / "trials.parquet").names == io.CURVE_COLUMNS
        df = pd.read_parquet(folder / "curves.parquet")
        assert list(df.columns[:len(group)]) == group
        assert set(CURVE_STATS) | {"epoch", "samples", "size", "n_trials"} <= set(df.columns)
        summ = pd.read_parquet(folder / "summary.parquet")
        assert {"final_abs_error_mean", "final_rel_error_std", "peak_abs_error_growth",
                "rise_abs_error_growth", "n_bootstrap_failures", "n_diverged", "n_run_failures",
                "paper_final_abs_error", "variant", "choice", "chosen"} <= set(summ.columns)
        assert (summ["n_diverged"] == 0).all() and (summ["n_run_failures"] == 0).all()
        models = json.loads((folder / "models.json").read_text())
        assert set(models["conditions"]) == set(summ["condition"])
    summ = pd.read_parquet(f"{cfg.paths.aggregate}/fig7/summary.parquet")
    assert (summ["paper_final_abs_error"] == 0.006).all()


def test_aggregated_trials_have_the_curve_schema(smoke_tree):
    _, cfg, _ = smoke_tree
    schema = pq.read_schema(Path(cfg.paths.aggregate) / "fig4" / "trials.parquet")
    assert schema.equals(io.CURVE, check_metadata=False), schema


def test_report_lists_its_files(smoke_tree):
    _, cfg, _ = smoke_tree
    out = Path(cfg.paths.report)
    assert out == Path(cfg.paths.out) / "latest"
    listed = listed_files(out / "report.md")
    assert {"fig4_curves.png", "fig4_curves.pdf", "fig2_stages.png", "fig3_postures.pdf",
            "fig6_postures.png", "summary.csv", "summary.md", "claims.csv", "curves.parquet",
            "choices.csv", "choices.md", "readings.csv", "explanations.csv",
            "report.md"} <= set(listed)
    assert sorted(set(files_of(out)) - {"report.html"}) == sorted(listed)  # report.md rendered
    assert (out / "report.html").read_text().count("<img ") >= 1
    assert (Path(cfg.paths.out) / "index.html").is_file()
    choices = pd.read_csv(out / "choices.csv")
    assert {"choices_arm2", "choices_arm5", "choices_icub"} == set(choices["figure"])
    # the discussion belongs to the committed full-scale run, not to these numbers
    assert "left out" in (out / "report.md").read_text()


def test_report_regenerates_byte_for_byte_and_publishes_the_committed_reports_files(
        smoke_tree, monkeypatch):
    """report.publish=true writes, into a fresh paths.published, the very bytes the report stage
    wrote into paths.report; and outputs/report/ (committed, full scale) holds exactly the files
    its report.md lists, every one of which the stage writes. (The scale check is bypassed here:
    a full-scale run takes hours; that it refuses a smoke-scale tree is tested in
    pipeline/test_stage_faults.py.)"""
    committed = REPO_ROOT / "outputs" / "report"
    listed = listed_files(committed / "report.md")
    assert sorted(listed + ["report.html"]) == sorted(  # report.html: report.md rendered
        p.relative_to(committed).as_posix() for p in committed.rglob("*") if p.is_file())
    root, cfg, _ = smoke_tree
    monkeypatch.setattr(report, "check_published_scale", lambda cfg, aggs: None)
    pub_cfg = compose(tiny_overrides(root, "report.publish=true"))
    published = Path(pub_cfg.paths.published)
    assert published == root / "outputs" / "report" and published != committed
    assert not published.exists()
    report.report(pub_cfg)
    assert files_of(published) == files_of(Path(cfg.paths.report))
    written = listed_files(published / "report.md")
    # calibration.csv needs a replicate set beside its figure, which the tiny tree does not run
    # (its writing: tests/studies/test_replicate.py)
    assert set(listed) - {"calibration.csv"} <= set(written), set(listed) - set(written)
    # The code writes more than the committed report holds: the studies that are not paper
    # experiments (readings, baselines: never published at full scale, as the report stands) and
    # explanations.csv, which the committed report predates.


def test_rescore_judges_the_smoke_reports_measures_again(smoke_tree):
    """python -m pipeline.tools.rescore on the smoke report's measures.parquet: the same
    verdicts (none: a smoke run decides nothing), no trial run."""
    _, cfg, _ = smoke_tree
    r = run_cli("pipeline.tools.rescore", str(cfg.paths.report))
    assert r.returncode == 0, r.stderr
    assert "no verdict" in r.stdout and "no cell changed" in r.stdout


def test_rerun_computes_nothing(smoke_tree, monkeypatch):
    root, _, _ = smoke_tree

    def no_trials(conf, todo, *args, **kwargs):
        assert not todo, "a cached trial ran"
        return iter(())

    monkeypatch.setattr(engines, "run", no_trials)  # the engine that would run them
    monkeypatch.setattr(execute, "run_one", lambda t: pytest.fail("a cached trial ran"))
    monkeypatch.setattr(execute, "warm_up", lambda t: pytest.fail("nothing to warm up for"))
    for workers in (1, 2):
        s = simulate.simulate(compose(tiny_overrides(root, "experiment=fig4",
                                                     f"workers={workers}")))
        assert s.ran == 0 and s.cached == s.total == 6


def test_aggregate_reads_only_the_trials_of_the_newest_plan(tmp_path, compose_tiny):
    simulate.simulate(compose_tiny(tmp_path, "experiment=fig4", "trials.count=2"))
    cfg = compose_tiny(tmp_path, "experiment=fig4")  # 1 trial: the other stays in the cache
    simulate.simulate(cfg)
    assert aggregate.aggregate(cfg) == []
    summ = pd.read_parquet(Path(cfg.paths.aggregate) / "fig4/summary.parquet")
    assert (summ["n_trials"] == 1).all() and len(summ) == 6
    assert len(list((Path(cfg.paths.cache) / "trials").rglob("*.parquet"))) == 12


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
    cut = tmp_path / "cut/outputs/smoke/cache"
    assert not list(cut.rglob("*.lock")) and not list(cut.rglob(".*.tmp"))
    s = simulate.simulate(compose_tiny(tmp_path / "cut", *overrides))
    assert s.cached == 3 and s.ran == s.total - 3
    assert files_of(cut) == files_of(tmp_path / "whole/outputs/smoke/cache")


def test_one_and_two_workers_give_identical_files(tmp_path, compose_tiny):
    # spawned workers fingerprint the code afresh (execute.run_one checks it against the plan's):
    # so does this process, in case the code was edited since it first did
    code_fingerprint.cache_clear()
    overrides = ("experiment=fig5", "conditions.periods=[10]", "conditions.references=[1.0]",
                 "trials.count=2")
    s1 = simulate.simulate(compose_tiny(tmp_path / "w1", *overrides, "workers=1"))
    s2 = simulate.simulate(compose_tiny(tmp_path / "w2", *overrides, "workers=2"))
    assert s1.ran == s2.ran == 4
    assert files_of(tmp_path / "w1/outputs/smoke/cache") == files_of(
        tmp_path / "w2/outputs/smoke/cache")


def test_a_failing_trial_is_recorded_and_the_others_finish(tmp_path, compose_tiny, monkeypatch):
    real = gbmodel.run_trial

    def flaky(spec, rng):
        if spec.growth.get("period") == 100:
            raise FloatingPointError("boom")
        return real(spec, rng)

    monkeypatch.setattr(gbmodel, "run_trial", flaky)
    cfg = compose_tiny(tmp_path, "conditions.periods=[10,100]", "trials.count=2")
    s = simulate.simulate(cfg)
    assert len(s.failed) == 2 and s.ran == 4
    assert all("FloatingPointError: boom" in e for e in s.failed.values())
    folder = tmp_path / "outputs/smoke/cache"
    failed = [json.loads(p.read_text()) for p in sorted((folder / "failed").glob("*.json"))]
    assert sorted(f["key"] for f in failed) == sorted(s.failed)
    assert {f["labels"]["growth_period"] for f in failed} == {100}
    assert len(list(folder.rglob("*.parquet"))) == 2
    problems = aggregate.aggregate(cfg)
    assert sorted(problems) == [f"[custom] TG100 trial {i}: not computed (run pipeline.simulate)"
                                for i in (0, 1)]
    summ = pd.read_parquet(tmp_path / "outputs/smoke/aggregate/custom/summary.parquet")
    assert summ.set_index("condition")["n_run_failures"].to_dict() == {"TG10": 0, "TG100": 2}
    assert simulate_mod.run(cfg) == 1  # the failed trials run again, fail again: non-zero exit
    monkeypatch.setattr(gbmodel, "run_trial", real)
    assert simulate_mod.run(cfg) == 0
    assert not list((folder / "failed").glob("*.json"))
    assert aggregate.aggregate(cfg) == []


@pytest.mark.parametrize("override, shown", [
    ("body=leg", "body=leg: unknown option"), ("growth=sideways", "growth=sideways"),
    ("growth.period=-1", "growth.period=-1"), ("growth.period=1.5", "growth.period"),
    ("learner.epochs=0", "learner.epochs=0"), ("trials.count=0", "trials.count=0"),
    ("learner.radius=-0.1", "learner.radius=-0.1"), ("experiment=fig9", "experiment=fig9"),
    ("learner.rate=1", "learner.rate"), ("growth.period=10,100", "needs -m"),
    ("learner=nope", "learner=nope: unknown option"), ("learner.fast=maybe", "learner.fast"),
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
    sweep = ["-m", "body=arm5", "growth=proportional", "growth.period=10,20", "trials.count=2",
             "learner.epochs=20", "workers=1", "report.explain=false", f"paths.root={tmp_path}"]
    r = run_cli("pipeline.simulate", *sweep)
    assert r.returncode == 0, r.stderr
    trials, problems = figure_trials(tmp_path / "outputs/cache", "custom")
    assert sorted({t["condition"] for t in trials}) == ["TG10", "TG20"]
    assert len(trials) == 4 and problems == []
    # again, through the joblib launcher: everything is cached already
    r = run_cli("pipeline.simulate", *sweep, "hydra/launcher=joblib", "hydra.launcher.n_jobs=2")
    assert r.returncode == 0, r.stderr
    assert r.stderr.count("0 run, 0 failed") == 2, r.stderr
    for stage in ("pipeline.aggregate", "pipeline.report"):
        r = run_cli(stage, f"paths.root={tmp_path}", "report.explain=false")
        assert r.returncode == 0, r.stderr
    curves = pd.read_parquet(tmp_path / "outputs/aggregate/custom/curves.parquet")
    assert sorted(curves["condition"].unique()) == ["TG10", "TG20"]
    assert (tmp_path / "outputs/latest/custom_curves.png").exists()
    assert not (tmp_path / "outputs/report").exists()  # the published report: make reproduce only
    assert not list(tmp_path.glob("*.log")) and not (tmp_path / "multirun").exists()


@pytest.mark.slow
def test_ctrl_c_on_two_workers_stops_at_once_and_resumes(tmp_path):
    """A real Ctrl-C (SIGINT to the process group) during a pool run, then a rerun."""
    import os
    import signal
    import subprocess
    import sys
    import time

    args = tiny_overrides(tmp_path / "cut", "experiment=fig7", "figure=fig7_cut",
                          "learner.epochs=3000", "trials.count=2", "workers=2")
    env = dict(os.environ, PYTHONPATH=str(REPO_ROOT))
    proc = subprocess.Popen([sys.executable, "-m", "pipeline.simulate", *args], env=env,
                            stderr=subprocess.PIPE, text=True, start_new_session=True,
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    folder = tmp_path / "cut/outputs/smoke/cache/trials"  # a trial finished: Ctrl-C mid-run
    while not list(folder.glob("*/*.parquet")) and proc.poll() is None:
        time.sleep(0.2)
    os.killpg(proc.pid, signal.SIGINT)
    _, err = proc.communicate(timeout=30)
    assert proc.returncode == 130, err
    assert "stopped by SIGINT" in err and "Traceback" not in err
    r = run_cli("pipeline.simulate", *args)
    assert r.returncode == 0 and "cached" in r.stderr, r.stderr
    whole = run_cli("pipeline.simulate", *tiny_overrides(
        tmp_path / "whole", "experiment=fig7", "figure=fig7_cut", "learner.epochs=3000",
        "trials.count=2"))
    assert whole.returncode == 0, whole.stderr
    assert files_of(tmp_path / "cut/outputs/smoke/cache") == files_of(
        tmp_path / "whole/outputs/smoke/cache")
