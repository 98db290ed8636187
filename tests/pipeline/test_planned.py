"""A command planned before takes its plan from paths.out/planned/: no compose, no planning,
the same trials; anything that changes the plan's inputs plans again."""
import json
from pathlib import Path

import pytest

from pipeline import config, io, plan, simulate
from pipeline.config import ConfigError


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
    return sorted((Path(cfg.paths.out) / plan.PLANNED).glob("*.json"))


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
    before = plan.plan_digest(cfg, [])
    monkeypatch.setattr(plan, "planning_sources", lambda: "other code")
    assert plan.plan_digest(cfg, []) != before


def test_a_conditions_spec_is_stored_once(tmp_path, compose_tiny):
    cfg = compose_tiny(tmp_path, "trials.count=5", "conditions.references=[0.5]")
    jobs = simulate.jobs_of(cfg)
    (path,) = saved(cfg)
    stored = json.loads(path.read_text())
    assert len(stored["specs"]) == 2 and len(jobs[0].trials) == 10
    assert [vars(j) for j in simulate.unpack_jobs(stored)] == json.loads(io.dump_json(
        [vars(j) for j in jobs]))
