"""No silent NaN, a cache that checks itself, a committed report nobody overwrites: each fault
injected, with its expected message and exit status, and nothing lost."""
import json
import os
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from pipeline import aggregate, cache, cli, report, simulate
from pipeline.studies import claims, paper, scorecard
from pipeline.config import REPO_ROOT, ConfigError, VariantConf, compose
from pipeline.fingerprint import code_fingerprint
from pipeline.plan import plan
from conftest import TINY, files_of, run_cli, tiny_overrides

COMMITTED = REPO_ROOT / "outputs" / "report"


@pytest.fixture(scope="module", autouse=True)
def committed_report_untouched():
    """Whatever these tests do, the committed report keeps its bytes."""
    before = files_of(COMMITTED)
    yield
    assert files_of(COMMITTED) == before


# ---- 1. divergence -----------------------------------------------------------------------------
WILD = "learner.learning_rate=1000"  # the largest rate allowed (gbmodel.spec); diverges in a few epochs


def test_a_diverging_trial_is_a_result_named_with_its_epoch(tmp_path, compose_tiny):
    cfg = compose_tiny(tmp_path, WILD, "growth=none", "trials.count=2")
    s = simulate.simulate(cfg)
    assert s.ran == 2 and len(s.failed) == 2
    for error in s.failed.values():
        assert re.fullmatch(r"diverged: the error became (nan|inf|-inf) at epoch \d+", error), error
    assert any("diverged" in line and "epoch" in line for line in s.lines())
    folder = Path(cfg.paths.cache)
    sides = [json.loads(p.read_text()) for p in (folder / "trials").rglob("*.json")]
    assert len(sides) == 2 and all(x["status"] == "diverged" for x in sides)
    assert all(isinstance(x["epoch"], int) and 1 <= x["epoch"] <= 30 for x in sides)
    assert not list(folder.rglob("*.parquet")) and not (folder / "failed").exists()
    # a result: cached, not run again
    again = simulate.simulate(cfg)
    assert again.ran == 0 and again.cached == 2


def test_the_cli_exits_1_naming_the_diverged_trials(tmp_path):
    r = run_cli("pipeline.simulate", *tiny_overrides(tmp_path, WILD, "growth=none"))
    assert r.returncode == 1, r.stderr
    assert "diverged" in r.stderr and re.search(r"at epoch \d+", r.stderr), r.stderr
    assert "Traceback" not in r.stderr


def test_aggregate_counts_diverged_trials_and_never_averages_them(tmp_path, compose_tiny):
    cfg = compose_tiny(tmp_path, "growth=none", "trials.count=2", "report.explain=false")
    cfg.conditions.variants = [VariantConf(label="tame"), VariantConf(label="wild", set=[WILD])]
    s = simulate.simulate(cfg)
    assert s.ran == 4 and len(s.failed) == 2
    assert aggregate.aggregate(cfg) == []
    folder = Path(cfg.paths.aggregate) / "custom"
    summ = pd.read_parquet(folder / "summary.parquet").set_index("condition")
    assert summ.loc["wild", "n_diverged"] == 2 and summ.loc["wild", "n_trials"] == 0
    assert summ.loc["wild", "diverged_epochs"]
    assert np.isnan(summ.loc["wild", "final_abs_error_mean"])
    assert summ.loc["tame", "n_diverged"] == 0 and summ.loc["tame", "n_trials"] == 2
    trials = pd.read_parquet(folder / "trials.parquet")
    assert set(trials["condition"]) == {"tame"}
    final = trials[trials["epoch"] == trials["epoch"].max()]
    assert summ.loc["tame", "final_abs_error_mean"] == pytest.approx(final["abs_error"].mean())
    assert np.isfinite(pd.read_parquet(folder / "curves.parquet")["abs_error_mean"]).all()
    report.report(cfg)  # and the report stage takes it
    out = pd.read_csv(Path(cfg.paths.report) / "summary.csv").set_index("condition")
    assert out.loc["wild", "n_diverged"] == 2


def _diverged_summary():
    """A condition of 5 trials: 3 finished well, 2 diverged."""
    summary = pd.DataFrame([dict(figure="figX", condition="TG10", body="arm5",
                                 growth="proportional", growth_period=10, n_trials=3,
                                 n_diverged=2, n_run_failures=0, n_bootstrap_failures=0,
                                 final_abs_error_mean=0.02, final_abs_error_std=0.001,
                                 final_rel_error_mean=0.02, final_rel_error_std=0.001,
                                 peak_abs_error_growth=np.nan, rise_abs_error_growth=np.nan,
                                 peak_epoch_growth=-1, paper_final_abs_error=np.nan,
                                 end_size=1.0)])
    trials = pd.DataFrame(dict(condition=["TG10"] * 6, trial=[0, 0, 1, 1, 2, 2],
                               epoch=[1, 20] * 3, abs_error=[0.1, 0.02] * 3,
                               rel_error=[0.1, 0.02] * 3))
    return trials, summary


def test_diverged_trials_fail_the_bootstrapping_claim():
    tests = claims.judge(claims.measures("figX", *_diverged_summary()))
    boot = next(t for t in tests if t.claim == "bootstrap")
    assert scorecard.run_test(boot)["verdict"] == "not reproduced"


def test_diverged_trials_show_in_the_summary_table():
    _, summary = _diverged_summary()
    assert "diverged" in paper.summary_markdown(summary)


def test_a_rerun_still_names_the_diverged_trials(tmp_path, compose_tiny):
    cfg = compose_tiny(tmp_path, WILD, "growth=none")
    simulate.simulate(cfg)
    again = simulate.simulate(cfg)
    assert "diverged" in " ".join(again.lines()).replace("failed or diverged", "")


# ---- 2. a damaged cache ------------------------------------------------------------------------
def test_damaged_cache_files_are_named_and_recomputed_to_the_same_bytes(tmp_path, compose_tiny,
                                                                        capsys):
    clean = compose_tiny(tmp_path / "clean", "experiment=fig4")
    simulate.simulate(clean)
    cfg = compose_tiny(tmp_path / "hurt", "experiment=fig4")
    simulate.simulate(cfg)
    folder = Path(cfg.paths.cache) / "trials"
    curves = sorted(folder.rglob("*.parquet"))
    assert len(curves) == 6
    sides = [c.with_suffix(".json") for c in curves]
    damage = {  # file -> new content
        curves[0]: curves[0].read_bytes()[: curves[0].stat().st_size // 2],  # truncated
        sides[1]: b"\x00\xffgarbage{",  # not JSON, not even text
        sides[2]: sides[2].read_bytes()[: sides[2].stat().st_size // 2],  # truncated JSON
        sides[3]: b"[1, 2]\n",  # JSON, but no object
        sides[4]: json.dumps(dict(json.loads(sides[4].read_text()), key="other")).encode(),
    }
    for path, data in damage.items():
        path.write_bytes(data)
    curves[5].unlink()  # lost
    names = sorted(p.name for p in [*damage, curves[5]])

    problems = aggregate.aggregate(cfg)  # never a JSONDecodeError: each one named
    assert len(problems) == 6
    for name in names:
        assert sum(name in p for p in problems) == 1, (name, problems)

    capsys.readouterr()
    s = simulate.simulate(cfg)
    err = capsys.readouterr().err
    lines = [ln for ln in err.splitlines() if "recomputing" in ln]
    assert len(lines) == 6, err
    for name in names:
        assert sum(name in ln for ln in lines) == 1, (name, lines)
    assert s.ran == 6 and s.cached == 0 and s.failed == {}
    assert files_of(Path(cfg.paths.cache)) == files_of(Path(clean.paths.cache))
    assert aggregate.aggregate(cfg) == []


def test_a_damaged_plan_record_is_named_and_never_replaces_a_good_aggregate(tmp_path,
                                                                           compose_tiny):
    cfg = compose_tiny(tmp_path, "experiment=fig4")
    simulate.simulate(cfg)
    assert aggregate.aggregate(cfg) == []
    summary = Path(cfg.paths.aggregate) / "fig4" / "summary.parquet"
    before = summary.read_bytes()
    group = json.loads((Path(cfg.paths.cache) / "plans/fig4/current.json").read_text())["group"]
    for garbage in (b'{"figure": "fig4", "whole": tr', b'{"figure": "fig4", "conditions": [1]}'):
        bad = Path(cfg.paths.cache) / "plans/fig4" / group / "0000000000000000.json"
        bad.write_bytes(garbage)
        problems = aggregate.aggregate(cfg)
        assert len(problems) == 1 and bad.name in problems[0] and "left as it was" in problems[0]
        assert summary.read_bytes() == before
    bad.unlink()
    assert aggregate.aggregate(cfg) == []


# ---- 3. who writes the committed report --------------------------------------------------------
def test_a_small_run_reports_into_latest_and_cannot_publish(tmp_path, compose_tiny):
    cfg = compose_tiny(tmp_path, "experiment=fig4", "report.explain=false")
    simulate.simulate(cfg)
    aggregate.aggregate(cfg)
    published = Path(cfg.paths.published)
    assert published == tmp_path / "outputs" / "report"
    published.mkdir(parents=True)
    (published / "report.md").write_text("the committed report\n")
    written = report.report(cfg)
    latest = Path(cfg.paths.report)
    assert latest == tmp_path / "outputs" / "smoke" / "latest"
    assert written and all(p.is_relative_to(latest) for p in written)  # models/ lies below it
    assert files_of(published) == {"report.md": b"the committed report\n"}

    before = files_of(tmp_path)
    r = run_cli("pipeline.report", *tiny_overrides(tmp_path, "report.publish=true",
                                                    "report.explain=false"))
    assert r.returncode == 2, r.stderr
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: report.publish=true: "), r.stderr
    assert "full scale" in lines[0]
    assert files_of(tmp_path) == before  # nothing written, neither published nor latest
    with pytest.raises(ConfigError):
        report.report(compose_tiny(tmp_path, "report.publish=true"))


# ---- 4. bad input on the command line ----------------------------------------------------------
@pytest.mark.parametrize("args, shown", [
    (["learner.epochs=1000000000000"], "at most 1e+09 epochs"),
    (["body=icub", "growth=nonproportional"], "growth.pattern='nonproportional'"),
    (["body=arm2", "experiment=fig5"], "growth.pattern='nonproportional'"),
])
def test_bad_input_exits_2_with_one_line(tmp_path, args, shown):
    r = run_cli("pipeline.simulate", *tiny_overrides(tmp_path, *args))
    assert r.returncode == 2, r.stderr
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: ") and shown in lines[0], r.stderr
    assert not list(tmp_path.rglob("*"))


def test_a_file_as_the_output_root_exits_2_with_one_line():
    r = run_cli("pipeline.simulate", *TINY, "paths.root=/etc/passwd")
    assert r.returncode == 2, r.stderr
    lines = r.stderr.strip().splitlines()
    assert lines == ["error: paths.root='/etc/passwd': /etc/passwd is a file, not a folder"]


@pytest.mark.parametrize("key", ["published", "bench"])
def test_every_output_path_that_is_a_file_is_refused(key):
    with pytest.raises(ConfigError, match=rf"^paths\.{key}="):
        plan(compose([f"paths.{key}=/etc/passwd"]))


def test_an_experiment_with_another_body_must_name_its_own_figure(tmp_path):
    """`experiment=fig4 body=icub` would replace the arm5 Fig. 4 with iCub trials (and judge
    them by the 2 cm claim): refused in one line naming both, nothing written; with a figure
    name of its own it runs that body, with the iCub's learner settings."""
    r = run_cli("pipeline.simulate", "experiment=fig4", "body=icub", f"paths.root={tmp_path}")
    lines = r.stderr.strip().splitlines()
    assert r.returncode == 2 and len(lines) == 1, r.stderr
    assert "experiment=fig4 with body=icub would replace figure fig4" in lines[0]
    assert "figure=" in lines[0] and not list(tmp_path.rglob("*"))
    overrides = ["experiment=fig4", "body=icub", "figure=fig4_icub"]
    assert cli.check(overrides) is None
    cfg = compose(overrides)
    assert cfg.body.name == "icub" and cfg.figure == "fig4_icub"
    assert cfg.learner.radius == 0.1 and cfg.learner.targets_per_epoch == 30
    trials = plan(cfg)
    assert {t["spec"]["body"]["name"] for t in trials} == {"icub"}
    assert not {t["key"] for t in trials} & {t["key"] for t in plan(compose(["experiment=fig4"]))}
    # what leaves the experiment's conditions as they are is no replacement
    assert cli.check(["experiment=fig7", "trials.count=2", "profile=smoke", "workers=1"]) is None


# ---- 5. two runs on one cache ------------------------------------------------------------------
def test_two_simulate_runs_at_once_compute_each_trial_once(tmp_path):
    args = tiny_overrides(tmp_path, "experiment=fig7", "learner.epochs=4000", "trials.count=2",
                          "conditions.periods=[100]", "conditions.references=[1.0]",
                          "figure=fig7_short")
    env = dict(os.environ, PYTHONPATH=str(REPO_ROOT))
    procs = [subprocess.Popen([sys.executable, "-m", "pipeline.simulate", *args], cwd="/",
                              env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
             for _ in range(2)]
    outs = [p.communicate(timeout=300) for p in procs]
    for p, (out, err) in zip(procs, outs):
        assert p.returncode == 0, err
    done = [ln for _, err in outs for ln in err.splitlines() if re.search(r"\bok in [\d.]+ s", ln)]
    assert len(done) == 4, "\n".join(err for _, err in outs)
    code_fingerprint.cache_clear()  # the keys the two processes computed, not this one's older ones
    cfg = compose(args)
    trials = plan(cfg)
    assert len(trials) == 4
    assert all(cache.check(cfg.paths.cache, t)[0] is not None for t in trials)
    assert not list(Path(cfg.paths.cache).rglob("*.lock"))


def test_a_trial_finished_by_another_run_after_the_check_is_not_recomputed(tmp_path, compose_tiny,
                                                                          monkeypatch):
    cfg = compose_tiny(tmp_path, "experiment=fig4")
    simulate.simulate(cfg)  # the other run, which finishes every trial ...
    real, seen = cache.check, set()

    def just_before(cache_dir, trial):  # ... just after this run's first look at each
        if trial["key"] not in seen:
            seen.add(trial["key"])
            return None, None
        return real(cache_dir, trial)

    monkeypatch.setattr(cache, "check", just_before)
    s = simulate.simulate(cfg)
    assert s.ran == 0 and s.cached == s.total


# ---- 6. the kernels compile once ---------------------------------------------------------------
def test_warm_runs_and_says_so():
    """It loads the kernels and byte-compiles the packages (read where none are written)."""
    stale = Path(simulate.__file__).parent / "__pycache__" / \
        f"simulate.{sys.implementation.cache_tag}.pyc"
    stale.unlink(missing_ok=True)
    r = run_cli("pipeline.warm")
    assert r.returncode == 0, r.stderr
    assert re.fullmatch(r"kernels compiled or loaded from numba's cache in [\d.]+ s\n", r.stdout)
    assert stale.is_file()


def test_make_refuses_a_python_older_than_311_and_says_which(tmp_path):
    """The Makefile takes python3.11, else python3, and checks the version before creating
    anything (a fake interpreter that reports 3.9 is refused, with its path named)."""
    fake = tmp_path / "python3"
    fake.write_text("#!/bin/sh\ncase \"$2\" in *version_info*) exit 1;; "
                    "*python_version*) echo 3.9.0;; esac\n")
    fake.chmod(0o755)
    r = subprocess.run(["make", "-B", "-s", ".venv/.installed", f"PYTHON={fake}"],
                       cwd=REPO_ROOT, capture_output=True, text=True, timeout=60)
    assert r.returncode != 0
    assert f"{fake} is Python 3.9.0; need >= 3.11" in r.stdout + r.stderr


def test_make_stops_when_no_experiment_is_listed():
    """The Makefile's lists come from the experiments tool; when it fails (here: a Python that
    fails), make stops with one line instead of running the default config under experiments=[]."""
    r = subprocess.run(["make", "-n", "-s", "simulate", "PY=/bin/false"], cwd=REPO_ROOT,
                       capture_output=True, text=True, timeout=60)
    assert r.returncode != 0
    assert "no experiments listed: '/bin/false -m pipeline.tools.experiments --make' failed" \
        in r.stderr, r.stderr
    assert "pipeline.simulate" not in r.stdout


def test_an_edited_model_in_a_sidecar_is_caught_by_its_seal_and_recomputed(tmp_path,
                                                                           compose_tiny):
    cfg = compose_tiny(tmp_path, "growth=none")
    simulate.simulate(cfg)
    side = next((Path(cfg.paths.cache) / "trials").rglob("*.json"))
    record = json.loads(side.read_text())
    record["M"][0][0] += 1e-3  # a plausible model, silently changed
    side.write_text(json.dumps(record))
    trial = plan(cfg)[0]
    done, why = cache.check(cfg.paths.cache, trial)
    assert done is None and "seal" in why
    again = simulate.simulate(cfg)
    assert again.ran == 1 and cache.check(cfg.paths.cache, trial)[0] is not None


def test_a_damaged_aggregate_file_is_one_line_and_exit_2(tmp_path, compose_tiny):
    cfg = compose_tiny(tmp_path, "growth=none")
    simulate.simulate(cfg)
    aggregate.aggregate(cfg)
    models = Path(cfg.paths.aggregate) / "custom" / "models.json"
    models.resolve().write_text('{"figure": "custom", "condi')
    r = run_cli("pipeline.report", *tiny_overrides(tmp_path))
    lines = r.stderr.strip().splitlines()
    assert r.returncode == 2 and len(lines) == 1 and "models.json" in lines[0], r.stderr
