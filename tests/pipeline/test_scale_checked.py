"""The command-line check (pipeline.cli.check) plans a one-job command once: the same command
line again, with the same config files and code, takes the note it left under
paths.out/planned/checked/ and plans nothing; the run's own settings are checked every time."""
import json
from pathlib import Path

import pytest

from pipeline import cli, plan
from pipeline.config import compose
from tests.conftest import tiny_overrides


@pytest.fixture
def plans(monkeypatch):
    """How often cli.check plans a config."""
    n, real = [], plan.plan

    def counting(cfg, remember=False):
        n.append(cfg.figure)
        return real(cfg, remember)

    monkeypatch.setattr(cli, "plan", counting)
    return n


def check(argv: list[str]) -> str | None:
    """cli.check, then what cli.finish does after a stage that ran: the note is kept."""
    problem = cli.check(argv)
    if problem is None:
        cli.finish(lambda cfg: 0, None)
    return problem


def notes(root: Path) -> list[Path]:
    return sorted(root.rglob(f"{plan.PLANNED}/checked/*.json"))


def test_a_checked_command_line_is_not_planned_again(tmp_path, plans):
    argv = tiny_overrides(tmp_path, "figure=tiny")
    assert check(argv) is None and plans == ["tiny"]
    assert len(notes(tmp_path)) == 1
    assert json.loads(notes(tmp_path)[0].read_text())["trials"] > 0
    assert check(argv) is None and plans == ["tiny"]  # the note: no planning
    assert check([*argv, "trials.count=2"]) is None and plans == ["tiny", "tiny"]
    assert len(notes(tmp_path)) == 2


def test_a_damaged_note_plans_again(tmp_path, plans):
    argv = tiny_overrides(tmp_path, "figure=tiny")
    check(argv)
    notes(tmp_path)[0].write_text("{")
    assert check(argv) is None and len(plans) == 2


def test_the_runs_own_settings_are_checked_on_a_checked_command_line(tmp_path, plans):
    argv = tiny_overrides(tmp_path, "figure=tiny")
    assert check(argv) is None
    aggregate = Path(compose(argv).paths.aggregate)
    aggregate.parent.mkdir(parents=True, exist_ok=True)
    aggregate.write_text("a file where a folder belongs")
    problem = check(argv)
    assert problem is not None and "paths.aggregate" in problem and len(plans) == 1


def test_a_changed_body_file_plans_again(tmp_path):
    body = tmp_path / "arm.urdf"
    body.write_text("<robot/>")
    note = tmp_path / "note.json"
    trials = [{"spec": {"body": {"urdf": {"file": str(body), "sha256": "0" * 64}}}}]
    plan.mark_checked(note, trials)
    assert json.loads(note.read_text())["body_files"] == [[str(body), "0" * 64]]
    assert not plan.was_checked(note)  # the file's bytes are not those it was planned with
    import gbmodel.urdf

    trials[0]["spec"]["body"]["urdf"]["sha256"] = gbmodel.urdf.digest(str(body))
    plan.mark_checked(note, trials)
    assert plan.was_checked(note)
    body.write_text("<robot name='other'/>")
    assert not plan.was_checked(note)
    assert not plan.was_checked(None) and not plan.was_checked(tmp_path / "missing.json")


def test_a_sweep_is_planned_every_time(tmp_path, plans):
    argv = ["-m", *tiny_overrides(tmp_path, "figure=tiny", "trials.count=1,2")]
    assert check(argv) is None and check(argv) is None
    assert len(plans) == 4 and notes(tmp_path) == []


def test_a_refused_stage_leaves_no_note(tmp_path, plans):
    argv = tiny_overrides(tmp_path, "figure=tiny")
    assert cli.check(argv) is None
    with pytest.raises(SystemExit):
        cli.finish(lambda cfg: 2, None)
    assert notes(tmp_path) == [] and cli._PASSED == []
