"""What a new user's first commands used to accept in silence is one line now (pipeline.cli.check:
the stage prints it as `error: ...` and exits 2 before anything is written), and `--help` lists
only what a user can choose."""
import pytest

from pipeline import cli
from conftest import run_cli


def _body(folder, file_name, name):
    (folder / "body").mkdir(parents=True, exist_ok=True)
    (folder / "body" / f"{file_name}.yaml").write_text(
        f"name: {name}\ndescription: arm5 again\ndh: [[0.5, 0, 0, 0], [0.5, 0, 0, 0]]\n"
        "outputs: [0, 1]\nhome: [0.5, 0.5]\ngrid: {lo: [-0.3, 0.3], hi: [0.3, 0.6], num: [3, 3]}\n")


def test_a_body_file_named_otherwise_than_its_name_is_refused(tmp_path):
    _body(tmp_path, "my_arm", "arm_two")
    line = cli.check([f"hydra.searchpath=[file://{tmp_path}]", "body=my_arm", "growth=none"])
    assert line and line.startswith("body=my_arm: its file my_arm.yaml says name: arm_two"), line
    _body(tmp_path, "same", "same")
    assert cli.check([f"hydra.searchpath=[file://{tmp_path}]", "body=same", "growth=none",
                      "profile=smoke"]) is None


def test_a_growth_period_without_growth_is_refused():
    line = cli.check(["growth=none", "growth.period=100"])
    assert line and line.startswith("growth.period=100: growth=none keeps the body"), line


def test_a_growth_period_longer_than_the_run_is_refused():
    line = cli.check(["growth=proportional", "growth.period=5000", "learner.epochs=1000"])
    assert line and line.startswith("growth.period=5000: longer than the run"), line
    assert cli.check(["growth=proportional", "growth.period=1000", "learner.epochs=1000",
                      "profile=smoke"]) is None


def test_a_missing_searchpath_folder_is_named(tmp_path):
    line = cli.check([f"hydra.searchpath=[file://{tmp_path}/nope]", "body=my_arm"])
    assert line and line.startswith(f"hydra.searchpath: {tmp_path}/nope is not a folder"), line


@pytest.mark.parametrize("stage", ["pipeline.simulate", "pipeline.tools.rate"])
def test_help_lists_only_what_a_user_chooses(stage):
    r = run_cli(stage, "--help")
    assert r.returncode == 0, r.stderr
    groups = r.stdout.split("== Configuration groups", 1)[1].split("\n==", 1)[0]
    assert "learner: example_memory, goal_babbling, motor_babbling, online_goal_babbling" in groups
    assert "_schema" not in groups and "body_learner:" not in groups
    assert "body: arm2, arm5" in groups and "experiment: " in groups


def test_a_run_longer_than_a_minute_says_what_it_costs_first():
    from pipeline.config import compose
    from pipeline.plan import plan
    from pipeline.progress import estimate

    long = plan(compose(["experiment=fig4", "trials.count=10"]))  # 100,000 epochs each: ~2 min
    line = estimate(long, 2)
    assert line and line.startswith(f"estimate: {len(long)} trials of 100,000 epochs, about "), line
    assert "CPU time" in line and "on 2 worker(s)" in line
    assert estimate(plan(compose(["profile=smoke", "trials.count=1"])), 2) is None  # seconds


def test_the_report_stage_prints_a_line_per_section():
    import io

    from pipeline.progress import Steps

    out = io.StringIO()
    step = Steps("report", 2, stream=out)
    step("figures: fig4")
    step("readings: readings_fig4")
    lines = out.getvalue().splitlines()
    assert lines[0].startswith("[report] 1/2 figures: fig4 | elapsed 0m0")
    assert lines[1].startswith("[report] 2/2 readings: readings_fig4 | elapsed")
