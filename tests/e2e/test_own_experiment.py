"""Your own experiment, end to end: sweeps keep every value, labels say what varied, a trial is
its content, launchers work on uncached trials, the step is the learner's, trained models load,
and the stages work in proportion to what changed (issue: "Your own experiment")."""
import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

import gbmodel
from gbmodel.learners.goal_babbling import Params
from pipeline import aggregate, models, simulate
from pipeline.config import ConfigError, compose
from pipeline.labels import condition_labels
from pipeline.plan import plan, plan_conditions
from conftest import figure_trials, run_cli, tiny_overrides


def _summary(root, figure="custom", profile="smoke"):
    return pd.read_parquet(Path(root) / f"outputs/{profile}/aggregate/{figure}/summary.parquet")


# ---- 1. a condition is its settings; labels from what differs ----------------------------------
def test_a_multirun_over_a_learner_key_keeps_every_value(tmp_path):
    r = run_cli("pipeline.simulate", "-m", *tiny_overrides(tmp_path, "learner.variations=10,20,40",
                                                           "growth=none"))
    assert r.returncode == 0, r.stderr
    assert run_cli("pipeline.aggregate", *tiny_overrides(tmp_path)).returncode == 0
    summ = _summary(tmp_path)
    assert summ["condition"].tolist() == ["V=10", "V=20", "V=40"]
    assert (summ["n_trials"] == 1).all()
    trials, problems = figure_trials(tmp_path / "outputs/smoke/cache", "custom")
    assert len({t["key"] for t in trials}) == 3 and problems == []


def test_a_grid_over_two_learner_keys_gives_four_conditions(tmp_path):
    r = run_cli("pipeline.simulate", "-m", *tiny_overrides(
        tmp_path, "learner.radius=0.1,0.2", "learner.steps=5,7", "growth=none"))
    assert r.returncode == 0, r.stderr
    assert run_cli("pipeline.aggregate", *tiny_overrides(tmp_path)).returncode == 0
    assert sorted(_summary(tmp_path)["condition"]) == [
        "R=0.1, L=5", "R=0.1, L=7", "R=0.2, L=5", "R=0.2, L=7"]


def test_labels_name_only_what_differs_and_a_shared_label_is_an_error():
    def conds(*override_sets):
        return plan_conditions([t for o in override_sets for t in plan(compose(list(o)))])

    assert condition_labels(conds(["growth.period=10"], ["growth.period=100"])) == ["TG10", "TG100"]
    assert condition_labels(conds(["body=arm2"], ["body=arm5"])) == [
        "body=arm2, eta=0.000518", "body=arm5, eta=0.000876"]
    assert condition_labels(conds(["learner=motor_babbling"], ["learner=goal_babbling"])) == [
        "learner=motor_babbling", "learner=goal_babbling"]
    a, b = conds(["learner.radius=0.1"], ["learner.radius=0.2"])
    b["variant"] = a["variant"] = dict(label="same", choice="", chosen=False)
    with pytest.raises(ConfigError, match="two different conditions share the label 'same'.*"
                                          "learner.radius=0.1 vs 0.2"):
        condition_labels([a, b])


def test_a_new_run_of_the_same_figure_says_what_it_replaces(tmp_path, compose_tiny, capsys):
    simulate.simulate(compose_tiny(tmp_path, "growth=none"))
    capsys.readouterr()
    simulate.simulate(compose_tiny(tmp_path, "growth=none"))  # the same run: nothing replaced
    assert "replaces" not in capsys.readouterr().err
    simulate.simulate(compose_tiny(tmp_path, "growth=none", "learner.radius=0.3"))
    err = capsys.readouterr().err
    assert "[custom] now the 1 condition(s) of this run; it replaces an earlier run's 1" in err
    assert "figure=NAME" in err


# ---- 2. the trial key is the trial's content ---------------------------------------------------
def test_the_same_trial_under_two_figures_is_computed_once(tmp_path, compose_tiny):
    first = simulate.simulate(compose_tiny(tmp_path, "growth=none", "figure=mine"))
    again = simulate.simulate(compose_tiny(tmp_path, "growth=none", "figure=yours"))
    assert first.ran == 1 and again.ran == 0 and again.cached == 1
    cfg = compose_tiny(tmp_path)
    aggregate.aggregate(cfg)
    for fig in ("mine", "yours"):
        assert _summary(tmp_path, fig)["n_trials"].tolist() == [1]


# ---- 3. launchers on uncached trials ----------------------------------------------------------
@pytest.mark.parametrize("launcher", ["basic", "joblib"])
def test_every_documented_launcher_runs_uncached_trials(tmp_path, launcher):
    r = run_cli("pipeline.simulate", "-m", *tiny_overrides(
        tmp_path, "growth.period=10,20", "trials.count=2", "workers=2",
        f"hydra/launcher={launcher}"))
    assert r.returncode == 0, r.stderr
    assert r.stderr.count("2 run, 0 failed") == 2, r.stderr


# ---- 4. the step is a property of the learner --------------------------------------------------
def test_the_plain_steps_rate_is_per_sample_and_exact_at_the_papers_settings():
    p = Params()
    assert p.rate() == p.learning_rate  # exactly: the paper's figures keep their rate
    assert Params(variations=40).rate() == pytest.approx(p.learning_rate * 2120 / 4240)
    assert Params(steps=14).rate() == pytest.approx(p.learning_rate * 2120 / 4220)
    assert Params(variations=40, step="normalised").rate() == p.learning_rate
    assert Params(rate_samples=None, variations=40).rate() == p.learning_rate
    icub = compose(["body=icub"]).learner
    assert Params(**{k: v for k, v in icub.items() if k not in ("name", "epochs",
                                                               "evals_per_decade")}).rate() == 0.000558


def test_the_rate_rule_is_a_command_for_any_body(tmp_path):
    from pipeline.tools import rate

    got = rate.rate(compose(["body=arm2"]), epochs=200, seeds=(0,))
    assert got["rate_samples"] == 2120 and got["W"] > 0
    assert got["learning_rate"] == pytest.approx(1 / got["W"])


def test_a_body_borrowing_arm5s_rate_is_told_so(tmp_path):
    trials = plan(compose(["body=arm2", "learner.learning_rate=0.000876"]))
    notes = simulate.learner_notes(trials + trials)
    assert len(notes) == 1 and "body arm2 learns at the 5-DOF arm's plain-step rate" in notes[0]
    assert "pipeline.tools.rate body=arm2" in notes[0]
    assert simulate.learner_notes(plan(compose(["body=arm2"]))) == []


# ---- 7. trained models from Python -------------------------------------------------------------
def test_trained_models_load_and_reach(tmp_path, compose_tiny):
    cfg = compose_tiny(tmp_path, "growth.period=10", "conditions.snapshots=[5]")
    simulate.simulate(cfg)
    aggregate.aggregate(cfg)
    fig = models.load("custom", cfg.paths.aggregate)
    assert fig.labels == ["TG10"]
    m = fig["TG10"]
    x = m.body.target_set(m.size)[:3]
    q = m.posture(x)
    assert q.shape == (3, 5) and np.allclose(
        m.reach(x), m.body.forward(q, gbmodel.growth.factors(m.body, m.size)))
    assert not np.allclose(m.posture(x, epoch=5), q)  # the snapshot is another model
    side = json.loads((Path(cfg.paths.aggregate) / "custom/models.json").read_text())
    assert np.allclose(m.M[0], side["conditions"]["TG10"]["trials"]["0"]["M"])
    with pytest.raises(KeyError, match="has no condition 'TG99'"):
        fig["TG99"]


# ---- 8. work in proportion to what changed -----------------------------------------------------
def test_aggregate_names_an_unknown_figure_in_one_line(tmp_path, compose_tiny):
    simulate.simulate(compose_tiny(tmp_path, "growth=none"))
    r = run_cli("pipeline.aggregate", *tiny_overrides(tmp_path, "figure=nonexistent"))
    lines = r.stderr.strip().splitlines()
    assert r.returncode == 2 and len(lines) == 1, r.stderr
    assert "figure=nonexistent: not simulated" in lines[0] and "custom" in lines[0]


def test_aggregate_rebuilds_only_the_figures_whose_inputs_changed(tmp_path, compose_tiny):
    simulate.simulate(compose_tiny(tmp_path, "growth=none", "figure=a"))
    simulate.simulate(compose_tiny(tmp_path, "growth=none", "figure=b"))
    cfg = compose_tiny(tmp_path)
    aggregate.aggregate(cfg)
    folder = Path(cfg.paths.aggregate)
    stamp = {f: (folder / f / "summary.parquet").stat().st_mtime_ns for f in ("a", "b")}
    aggregate.aggregate(cfg)  # nothing changed: nothing rewritten
    assert {f: (folder / f / "summary.parquet").stat().st_mtime_ns for f in "ab"} == stamp
    simulate.simulate(compose_tiny(tmp_path, "growth=none", "figure=b", "trials.count=2"))
    aggregate.aggregate(cfg)
    assert (folder / "a/summary.parquet").stat().st_mtime_ns == stamp["a"]
    assert _summary(tmp_path, "b")["n_trials"].tolist() == [2]
    assert not list(folder.glob(".*.dir"))  # no half-written set left behind


def test_legends_name_what_varied_not_the_growth_they_share():
    from pipeline.studies import figures

    sweep = pd.DataFrame(dict(condition=["V=10", "V=20", "V=40"], growth=["proportional"] * 3,
                              growth_period=[1000] * 3, end_size=[1.0] * 3))
    assert [figures.condition_label(r) for _, r in sweep.iterrows()] == ["V=10", "V=20", "V=40"]
    styles = figures.condition_styles(sweep)
    assert len({str(s["color"]) for s in styles.values()}) == 3
    paper = pd.DataFrame(dict(condition=["TG100", "const0.5"], growth=["proportional", "none"],
                              growth_period=[100, 0], end_size=[1.0, 0.5]))
    assert [figures.condition_label(r) for _, r in paper.iterrows()] == [
        "T_G = 100", "constant size 0.5"]
