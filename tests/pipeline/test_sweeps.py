"""Issue 55's first hour, second pass: a sweep over growth=none and a growing body with a period
runs both (the period ignored, in one line, where it means nothing); a sweep says what it costs
in all before its first job, by a cost model calibrated on the committed measured times; each
command's --help is its own, and every tool's documents its every flag."""
import re
import signal
import subprocess
import sys
from pathlib import Path

import pandas as pd
import pytest

from pipeline import check as check_module
from pipeline import cli, simulate
from pipeline.config import REPO_ROOT, compose
from pipeline.plan import cost, cpu_seconds, plan
from pipeline.simulate import Job, unique_trials, with_views
from conftest import run_cli, tiny_overrides

NONE_NOTE = "is ignored in the jobs of growth=none"


# ---- 1. a key that applies to some conditions only ---------------------------------------------
def test_a_sweep_over_growth_none_and_proportional_with_a_period_gets_both_conditions(tmp_path):
    sweep = tiny_overrides(tmp_path, "growth=none,proportional", "growth.period=20", "figure=gn")
    r = run_cli("pipeline.simulate", "-m", *sweep)
    assert r.returncode == 0, r.stderr
    notes = [ln for ln in r.stderr.splitlines() if NONE_NOTE in ln]
    assert notes == ["note: growth.period=20 is ignored in the jobs of growth=none (a body of one "
                     "size has no period); the sweep's growing jobs use it"]
    r = run_cli("pipeline.aggregate", *tiny_overrides(tmp_path, "figure=gn"))
    assert r.returncode == 0, r.stderr
    summary = pd.read_parquet(tmp_path / "outputs" / "smoke" / "aggregate" / "gn"
                              / "summary.parquet")
    assert sorted(summary["condition"]) == ["TG20", "const1.0"]


def test_the_ignored_period_leaves_growth_none_the_constant_bodys_trials(tmp_path):
    keys = lambda *o: [t["key"] for t in plan(compose(tiny_overrides(tmp_path, *o)))]
    assert keys("growth=none", "growth.period=20") == keys("growth=none")


@pytest.mark.parametrize("argv", [
    ["growth=none", "growth.period=300"],  # a single run
    ["-m", "growth=none", "growth.period=300"],  # a sweep of one job
    ["-m", "growth=none", "growth.period=100,300"],  # no job of the sweep grows
    ["-m", "growth=none", "learner.radius=0.1,0.2", "growth.period=300"],
])
def test_a_period_no_job_uses_keeps_its_one_line_refusal(tmp_path, argv):
    line = cli.check([*argv, *tiny_overrides(tmp_path)[:1], f"paths.root={tmp_path}"])
    assert line is not None and "\n" not in line
    assert "growth=none keeps the body at one size, so it has no period" in line, line


# ---- 2. a sweep's estimate, and the cost model against measured CPU ----------------------------
ALL = "all, each shared trial once"  # the provenance's last row
_ROW = re.compile(rf"^\| (\w+|{ALL}) \| (\d+) \| ([\d.]+) (s|min)"
                  r"(?: \((\d+) of \d+ trials\))? \| [\d.]+ (?:s|min) \|$", re.M)


def measured_per_experiment() -> dict[str, tuple[int, float]]:
    """experiment (and ALL) -> (trials, measured CPU seconds) from the committed report's
    provenance; a row measured on k of its n trials (the others cached before times were kept)
    scaled by n / k."""
    text = (REPO_ROOT / "outputs" / "report" / "report.md").read_text()
    return {name: (int(n), float(v) * (60 if unit == "min" else 1) * int(n) / int(k or n))
            for name, n, v, unit, k in _ROW.findall(text)}


def test_the_cost_model_is_within_1_5x_of_the_committed_measured_cpu():
    """Each experiment of the committed report (measured CPU of its trials, whichever run computed
    them; a view at 0 s), each shared trial counted once, and one job of the README's sweep
    measured on the report's AMD EPYC, the two jobs side by side (`python -m pipeline.simulate
    learner.radius=0.1 growth.period=100 figure=grid workers=1`: 25.3 s of CPU in its 20
    trials; with `learner.variations=10 growth=none figure=vsweep`: 16.7 s)."""
    measured = measured_per_experiment()
    every, every_seconds = measured.pop(ALL)
    assert len(measured) >= 16, sorted(measured)
    planned = {name: plan(compose([f"experiment={name}"])) for name in measured}
    distinct = {t["key"]: t for trials in planned.values() for t in trials}
    assert every == len(distinct)
    # a view (scored by a longer run of its learning, as make studies ran them all) measures 0 s
    _, views = with_views(unique_trials([Job(n, {}, t, n) for n, t in planned.items()]))
    ratios = {}
    for name, trials in planned.items():
        assert len(trials) == measured[name][0], name
        own = [t for t in trials if t["key"] not in views]
        if own:  # fig2's three trials are all views
            ratios[name] = measured[name][1] / cpu_seconds(sum(map(cost, own)), len(own))
    own = [t for k, t in distinct.items() if k not in views]
    ratios["all"] = every_seconds / cpu_seconds(sum(map(cost, own)), len(own))
    job = plan(compose(["learner.radius=0.1", "growth.period=100", "figure=grid"]))
    ratios["README sweep job"] = 25.3 / cpu_seconds(sum(map(cost, job)), len(job))
    job = plan(compose(["learner.variations=10", "growth=none", "figure=vsweep"]))
    ratios["README V sweep job"] = 16.7 / cpu_seconds(sum(map(cost, job)), len(job))
    outside = {k: round(r, 2) for k, r in ratios.items() if not 1 / 1.5 <= r <= 1.5}
    assert not outside, outside


def test_a_sweep_says_its_estimate_in_all_before_its_first_job(tmp_path, capsys):
    """The README's four-job sweep (20 trials of 100,000 epochs a job, 1.9 CPU-min by the cost
    model, pipeline.plan.SECONDS_PER_COST) at the paper's scale: what cli.main does
    before Hydra launches the first job, the check and simulate.before_sweep, without a trial."""
    argv = ["-m", "learner.radius=0.1,0.2", "growth.period=100,1000", "figure=grid",
            f"paths.root={tmp_path}"]
    assert cli.check(argv) is None
    (n_jobs, jobs, cache_dir, workers), = check_module.SWEEP
    assert n_jobs == 4 and len(jobs) == 3  # one job left to the mean of the three planned
    simulate.before_sweep(n_jobs, jobs, cache_dir, workers)
    line = capsys.readouterr().err.strip().splitlines()[-1]
    assert line.startswith("estimate: the sweep's 4 jobs (1 counted at the mean of the 3 "
                           "planned), 80 trials of 100,000 epochs, about 1m5"), line
    assert "on 2 worker(s)" in line and not any(tmp_path.iterdir())


def test_the_estimate_prints_before_hydra_launches_the_first_job(tmp_path):
    """The same sweep as a command: the estimate line comes before Hydra's first line; the run is
    then stopped (SIGTERM: exit 143, the same command resumes)."""
    cmd = [sys.executable, "-m", "pipeline.simulate", "-m", "learner.radius=0.1,0.2",
           "growth.period=100,1000", "figure=grid", "workers=1", f"paths.root={tmp_path}"]
    p = subprocess.Popen(cmd, cwd=REPO_ROOT, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                         text=True)
    before = []
    try:
        for line in p.stdout:
            if line.startswith("estimate:") or "trials done" in line:
                break
            before.append(line)
    finally:
        p.send_signal(signal.SIGTERM)
        p.communicate(timeout=120)
    assert line.startswith("estimate: the sweep's 4 jobs"), (line, before)
    assert not any("Launching" in b or "#0" in b for b in before), before


# ---- 3. help ------------------------------------------------------------------------------------
STAGES = ("pipeline.simulate", "pipeline.aggregate", "pipeline.report")


def test_each_stages_help_is_its_own_and_short():
    texts = {}
    for stage in STAGES:
        r = run_cli(stage, "--help")
        assert r.returncode == 0, r.stderr
        text = texts[stage] = r.stdout
        assert len(text.splitlines()) < 80, stage
        for part in ("Main options:", "Example:", f"python -m {stage} ", "--help-all",
                     "--cfg job"):
            assert part in text, (stage, part)
    assert len(set(texts.values())) == len(STAGES)
    assert "report.error_unit=mm" in texts["pipeline.report"]
    assert "-m KEY=A,B" in texts["pipeline.simulate"]
    full = run_cli("pipeline.simulate", "--help-all")
    assert full.returncode == 0 and "== Config (override any key" in full.stdout
    assert "log_epoch_axis: true" in full.stdout


@pytest.mark.parametrize("command", ["simulate", "aggregate", "report", "rate", "body", "bench",
                                     "models"])
def test_every_gbgrowth_command_takes_help(command):
    from pipeline.__main__ import STAGES as COMMANDS

    assert set(COMMANDS) | {"models"} == {"simulate", "aggregate", "report", "rate", "body",
                                          "bench", "models"}
    r = run_cli("pipeline", command, "--help")
    assert r.returncode == 0, r.stderr
    assert r.stdout.startswith(f"usage: gbgrowth {command}"), r.stdout[:200]
    assert "Example:" in r.stdout and len(r.stdout.splitlines()) < 80


TOOLS = sorted(p.stem for p in (REPO_ROOT / "pipeline" / "tools").glob("*.py")
               if '__name__ == "__main__"' in p.read_text())


@pytest.mark.parametrize("tool", TOOLS)
def test_every_tool_documents_every_flag_in_its_help(tool):
    source = (REPO_ROOT / "pipeline" / "tools" / f"{tool}.py").read_text()
    # its own flags: argparse's, a constant's (WRITE = "--write"), one compared with an argument
    flags = set(re.findall(r"""(?:add_argument\(\s*|^[A-Z_]+ = |[=!]= \[?)["'](--[a-z][a-z-]*)""",
                           source, re.M)) - {"--help"}
    r = run_cli(f"pipeline.tools.{tool}", "--help")
    assert r.returncode == 0, (tool, r.stderr)
    missing = [f for f in flags if not re.search(re.escape(f) + r"\b", r.stdout)]
    assert not missing, (tool, missing)


def test_the_report_options_compose_on_the_command_line():
    cfg = compose(["report.title=Radius x period", "report.error_unit=mm",
                   "report.log_epoch_axis=false"])
    assert (cfg.report.title, cfg.report.error_unit, cfg.report.log_epoch_axis) == (
        "Radius x period", "mm", False)
    d = compose([]).report
    assert (d.title, d.error_unit, d.log_epoch_axis) == ("", "m", True)
