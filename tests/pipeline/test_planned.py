"""A command planned before takes its plan from paths.out/planned/: no compose, no planning,
the same trials; anything that changes the plan's inputs plans again. The command-line check
(pipeline.cli.check) plans a one-job command once: the same command line again, with the same
config files and code, takes the note it left under paths.out/planned/checked/ and plans
nothing; the run's own settings are checked every time."""
import json
from pathlib import Path

import pytest

from pipeline import check as check_module
from pipeline import cli, config, io, plan, planned, simulate
from pipeline.config import ConfigError, compose
from conftest import tiny_overrides


@pytest.fixture
def composes(monkeypatch):
    """How often an experiment is composed."""
    n, real = [], config.compose

    def counting(overrides=()):
        n.append(list(overrides))
        return real(overrides)

    monkeypatch.setattr(config, "compose", counting)
    return n


def saved(cfg) -> list[Path]:
    return sorted((Path(cfg.paths.out) / planned.PLANNED).glob("*.json"))


def test_a_planned_command_is_not_composed_again_and_gives_the_same_trials(
        tmp_path, compose_tiny, composes):
    cfg = compose_tiny(tmp_path, "experiments=[fig4,fig2]")
    first = simulate.jobs_of(cfg, ["experiments=[fig4,fig2]"])
    assert len(composes) >= 2 and len(saved(cfg)) == 1
    composes.clear()
    again = simulate.jobs_of(cfg, ["experiments=[fig4,fig2]"])
    assert composes == []
    assert [vars(j) for j in again] == json.loads(io.dump_json([vars(j) for j in first]))
    assert [j.figure for j in again] == ["fig4", "fig2"]


def test_other_overrides_or_a_damaged_file_plan_again(tmp_path, compose_tiny):
    cfg = compose_tiny(tmp_path)
    one = simulate.jobs_of(cfg)
    cfg.trials.count = 2
    two = simulate.jobs_of(cfg)
    assert len(two[0].trials) == 2 * len(one[0].trials) and len(saved(cfg)) == 2
    for p in saved(cfg):
        p.write_text("{")
    assert [vars(j) for j in simulate.jobs_of(cfg)] == json.loads(io.dump_json(
        [vars(j) for j in two]))


def test_the_runs_own_settings_are_checked_on_a_planned_command(tmp_path, compose_tiny):
    cfg = compose_tiny(tmp_path)
    simulate.jobs_of(cfg)
    Path(cfg.paths.aggregate).parent.mkdir(parents=True, exist_ok=True)
    Path(cfg.paths.aggregate).write_text("a file where a folder belongs")
    with pytest.raises(ConfigError, match="paths.aggregate"):
        simulate.jobs_of(cfg)


def test_the_digest_follows_the_planning_sources(tmp_path, compose_tiny, monkeypatch):
    cfg = compose_tiny(tmp_path)
    before = planned.plan_digest(cfg, [])
    monkeypatch.setattr(planned, "planning_sources", lambda: "other code")
    assert planned.plan_digest(cfg, []) != before


def test_a_conditions_spec_is_stored_once(tmp_path, compose_tiny):
    cfg = compose_tiny(tmp_path, "trials.count=5", "conditions.references=[0.5]")
    jobs = simulate.jobs_of(cfg)
    (path,) = saved(cfg)
    stored = json.loads(path.read_text())
    assert len(stored["specs"]) == 2 and len(jobs[0].trials) == 10
    assert [vars(j) for j in simulate.unpack_jobs(stored)] == json.loads(io.dump_json(
        [vars(j) for j in jobs]))


def test_an_edited_urdf_file_plans_again(tmp_path, compose_tiny):
    """A URDF lies outside the folders plan_digest hashes: saved jobs whose body file changed
    since are planned again (new keys), not reused and then refused by read_chain forever."""
    import gbmodel.urdf
    from pipeline.config import compose

    from omegaconf import OmegaConf
    src = gbmodel.urdf.resolve(OmegaConf.to_container(compose(["body=ergo_jr"]).body.urdf.file))
    urdf = tmp_path / "arm.urdf"
    urdf.write_bytes(Path(src).read_bytes())
    over = ["body=ergo_jr", f"body.urdf.file={urdf}", "growth=none"]
    cfg = compose_tiny(tmp_path, *over)
    first = simulate.jobs_of(cfg, over)
    text = urdf.read_text()
    i = text.index('xyz="') + 5
    urdf.write_text(text[:i] + "0.001 " + text[i:].split(" ", 1)[1])  # one origin moved
    again = simulate.jobs_of(cfg, over)
    keys = lambda jobs: [t["key"] for j in jobs for t in j.trials]  # noqa: E731
    assert keys(again) != keys(first)
    assert {j.trials[0]["spec"]["body"]["urdf"]["sha256"] for j in again} == {
        gbmodel.urdf.digest(str(urdf))}


def test_saved_jobs_of_other_code_plan_again(tmp_path, compose_tiny, monkeypatch):
    """Saved jobs carry their trials' code fingerprint; one that is not the running code's is
    planned again. Where plan_digest hashed the learner's files (a shipped learner of the
    gbmodel this process imported) the same digest is the same code: nothing is parsed."""
    from pipeline import planned

    cfg = compose_tiny(tmp_path)
    first = simulate.jobs_of(cfg, [])
    saved_jobs = io.read_json(saved(cfg)[0])
    assert planned.covers_code() and saved_jobs["covered"] is True

    def parsed(name):
        raise AssertionError("a fingerprint computed")
    monkeypatch.setattr(simulate, "code_fingerprint", parsed)
    assert simulate.still_planned(saved_jobs) is True
    monkeypatch.setattr(simulate, "covers_code", lambda: False)  # (registered elsewhere)
    monkeypatch.setattr(simulate, "code_fingerprint", lambda name: "0" * 16)
    assert simulate.still_planned(saved_jobs) is False
    monkeypatch.undo()
    monkeypatch.setattr(simulate, "covers_code", lambda: False)
    assert simulate.still_planned(saved_jobs) is True
    monkeypatch.undo()
    assert [t["key"] for t in simulate.jobs_of(cfg, [])[0].trials] == [
        t["key"] for t in first[0].trials]


def test_a_plan_saved_with_a_registered_learner_is_checked_without_it(tmp_path, compose_tiny):
    """A learner registered under a shipped name (its code not the folder's) while the plan was
    saved: run without it, the saved trials' fingerprint is not this code's: planned again."""
    import importlib

    import gbmodel.learners
    from pipeline.fingerprint import code_fingerprint

    cfg = compose_tiny(tmp_path)
    gbmodel.learners.register("goal_babbling",
                              importlib.import_module("gbmodel.learners.goal_babbling"))
    code_fingerprint.cache_clear()
    try:
        first = simulate.jobs_of(cfg, [])
        saved_jobs = io.read_json(saved(cfg)[0])
    finally:
        gbmodel.learners._REGISTERED.pop("goal_babbling")
        code_fingerprint.cache_clear()
    assert saved_jobs["covered"] is False
    assert simulate.still_planned(saved_jobs) is False
    again = simulate.jobs_of(cfg, [])
    assert [t["code"] for t in again[0].trials] != [t["code"] for t in first[0].trials]
    assert io.read_json(saved(cfg)[0])["covered"] is True


def test_the_planning_sources_follow_the_python_version(monkeypatch):
    """Another Python may dump the same files' syntax trees otherwise (another fingerprint):
    saved jobs, taken by their digest without a fingerprint, are not taken there."""
    import sys

    from pipeline import planned

    planned.planning_sources.cache_clear()
    here = planned.planning_sources()
    monkeypatch.setattr(sys, "version_info", (3, 99, 0, "final", 0))
    planned.planning_sources.cache_clear()
    try:
        assert planned.planning_sources() != here
    finally:
        monkeypatch.undo()
        planned.planning_sources.cache_clear()
    assert planned.planning_sources() == here


def test_a_learner_outside_the_hashed_gbmodel_is_not_covered(monkeypatch):
    """covers_code: with a learner registered from elsewhere (it may shadow a shipped one, or
    be imported by one), or a gbmodel imported from another folder than the one plan_digest
    hashes, learners are fingerprinted as before."""
    import gbmodel
    import gbmodel.learners
    from pipeline import planned

    assert planned.covers_code()
    monkeypatch.setattr(gbmodel.learners, "registered", lambda: ["stay_home"])
    assert not planned.covers_code()
    monkeypatch.undo()
    monkeypatch.setattr(gbmodel, "__file__", "/elsewhere/gbmodel/__init__.py")
    assert not planned.covers_code()


def test_the_stage_takes_the_plan_the_command_line_check_made(tmp_path, monkeypatch):
    """The config is planned once per stage: cli.check plans a one-job command before Hydra
    starts, and the stage's plan of the same config takes that plan (once); a sweep's check
    remembers nothing (each job plans its own)."""
    from conftest import tiny_overrides
    from pipeline import cli
    from pipeline.config import compose

    args = tiny_overrides(tmp_path, "experiment=fig4", "figure=once")
    calls, real = [], plan._plan
    monkeypatch.setattr(plan, "_plan", lambda cfg: calls.append(1) or real(cfg))
    assert cli.check(args) is None and len(calls) == 1
    first = plan.plan(compose(args))
    assert len(calls) == 1  # the check's plan
    again = plan.plan(compose(args))
    assert len(calls) == 2 and [t["key"] for t in again] == [t["key"] for t in first]
    assert cli.check(["-m", *args, "growth.period=10,20"]) is None
    plan.plan(compose([*args, "growth.period=10"]))
    assert len(calls) == 5  # two jobs checked, then planned again by the stage

@pytest.fixture
def plans(monkeypatch):
    """How often cli.check plans a config."""
    n, real = [], plan.plan

    def counting(cfg, remember=False):
        n.append(cfg.figure)
        return real(cfg, remember)

    monkeypatch.setattr(check_module, "plan", counting)
    return n


def check(argv: list[str]) -> str | None:
    """cli.check, then what cli.finish does after a stage that ran: the note is kept."""
    problem = cli.check(argv)
    if problem is None:
        cli.finish(lambda cfg: 0, None)
    return problem


def notes(root: Path) -> list[Path]:
    return sorted(root.rglob(f"{planned.PLANNED}/checked/*.json"))


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
    planned.mark_checked(note, trials)
    assert json.loads(note.read_text())["body_files"] == [["urdf", {"file": str(body)}, "0" * 64]]
    assert not planned.was_checked(note)  # the file's bytes are not those it was planned with
    import gbmodel.urdf

    trials[0]["spec"]["body"]["urdf"]["sha256"] = gbmodel.urdf.digest(str(body))
    planned.mark_checked(note, trials)
    assert planned.was_checked(note)
    body.write_text("<robot name='other'/>")
    assert not planned.was_checked(note)
    assert not planned.was_checked(None) and not planned.was_checked(tmp_path / "missing.json")


def test_a_sweep_is_planned_every_time(tmp_path, plans):
    argv = ["-m", *tiny_overrides(tmp_path, "figure=tiny", "trials.count=1,2")]
    assert check(argv) is None and check(argv) is None
    assert len(plans) == 4 and notes(tmp_path) == []


def test_a_refused_stage_leaves_no_note(tmp_path, plans):
    argv = tiny_overrides(tmp_path, "figure=tiny")
    assert cli.check(argv) is None
    with pytest.raises(SystemExit):
        cli.finish(lambda cfg: 2, None)
    assert notes(tmp_path) == [] and check_module.PASSED == []


def test_an_edited_experiment_of_the_working_directory_plans_again(tmp_path, compose_tiny,
                                                                  monkeypatch):
    """`experiments=[mine]` composes mine from a conf/ of the working directory (the search-path
    plugin), a folder planning_sources does not hash: an edit there plans again instead of
    running the saved plan of the file as it was."""
    own = tmp_path / "work" / "conf" / "experiment"
    own.mkdir(parents=True)
    text = ("# @package _global_\ndefaults:\n  - override /growth: proportional\n"
            "figure: mine\nconditions:\n  periods: [10]\n  references: []\n")
    (own / "mine.yaml").write_text(text)
    monkeypatch.chdir(tmp_path / "work")
    cfg = compose_tiny(tmp_path, "experiments=[mine]")
    first = simulate.jobs_of(cfg, ["experiments=[mine]"])
    assert {t["labels"]["growth_period"] for t in first[0].trials} == {10}
    (own / "mine.yaml").write_text(text.replace("[10]", "[20]"))
    again = simulate.jobs_of(cfg, ["experiments=[mine]"])
    assert {t["labels"]["growth_period"] for t in again[0].trials} == {20}
