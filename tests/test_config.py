"""Configs: every experiment composes to the paper's settings, schemas catch typos, seeds and
cache keys are stable and distinct."""
from pathlib import Path

import pytest
from hydra.errors import ConfigCompositionException
from omegaconf import OmegaConf

import gbmodel
from pipeline.config import CONF_DIR, ConfigError, compose
from pipeline.plan import code_fingerprint, conditions, plan

EXPERIMENTS = sorted(p.stem for p in (CONF_DIR / "experiment").glob("*.yaml"))

# The paper's settings per figure (sec. 3.1-3.3).
PAPER = {
    "fig4": dict(body="arm5", pattern="proportional", trials=20, radius=0.2, variations=20,
                 targets_per_epoch=15, steps=7, epochs=100_000),
    "fig5": dict(body="arm5", pattern="nonproportional", trials=20, radius=0.2, variations=20,
                 targets_per_epoch=15, steps=7, epochs=100_000),
    "fig7": dict(body="icub", pattern="proportional", trials=5, radius=0.1, variations=20,
                 targets_per_epoch=30, steps=10, epochs=100_000),
}
CONDITIONS = ["TG10", "TG100", "TG1000", "TG10000", "const0.5", "const1.0"]


def test_every_paper_figure_has_an_experiment():
    assert set(EXPERIMENTS) >= {"fig2", "fig4", "fig5", "fig7"}


@pytest.mark.parametrize("name", sorted(PAPER))
def test_experiment_holds_the_papers_conditions(name):
    cfg = compose([f"experiment={name}"])
    want = PAPER[name]
    trials = plan(cfg)
    assert [c["condition"] for c in conditions(cfg)] == CONDITIONS
    assert len(trials) == len(CONDITIONS) * want["trials"]
    spec = trials[0]["spec"]
    for k in ("body", "pattern", "radius", "variations", "targets_per_epoch", "steps", "epochs"):
        assert spec[k] == want[k], k
    growing = [t["spec"] for t in trials if t["labels"]["growth"] != "none"]
    assert {(s["start_size"], s["end_size"]) for s in growing} == {(0.5, 1.0)}
    refs = {t["labels"]["condition"]: t["spec"] for t in trials if t["labels"]["growth"] == "none"}
    assert refs["const0.5"]["start_size"] == refs["const0.5"]["end_size"] == 0.5
    assert refs["const1.0"]["period"] == 0
    assert cfg.paper.final_abs_error in (0.02, 0.006)


def test_fig2_is_the_2dof_arm_with_snapshots():
    cfg = compose(["experiment=fig2"])
    (trial,) = plan(cfg)
    assert trial["spec"]["body"] == "arm2" and trial["labels"]["growth"] == "none"
    assert len(trial["spec"]["snapshot_epochs"]) >= 3


def test_smoke_profile_shrinks_and_moves_outputs():
    cfg = compose(["experiment=fig7", "profile=smoke"])
    assert cfg.learner.epochs <= 2000 and cfg.trials.count <= 2
    assert Path(cfg.paths.out).name == "smoke"
    assert cfg.learner.radius == 0.1  # the experiment's values otherwise stay


def test_body_brings_its_learner_settings_unless_overridden():
    assert compose(["body=icub"]).learner.targets_per_epoch == 30
    assert compose(["body=icub", "learner=arm"]).learner.targets_per_epoch == 15


def test_default_learning_rate_is_the_cores():
    for learner in ("arm", "icub"):
        cfg = compose([f"learner={learner}"])
        assert cfg.learner.learning_rate == gbmodel.trial.DEFAULT_LEARNING_RATE


def test_paths_are_rooted_at_the_repository_not_the_cwd(monkeypatch, tmp_path):
    monkeypatch.chdir(tmp_path)
    cfg = compose([])
    assert Path(cfg.paths.cache) == CONF_DIR.parent / "outputs" / "cache"
    assert Path(compose([f"paths.root={tmp_path}"]).paths.report) == tmp_path / "outputs/report"


@pytest.mark.parametrize("override", ["learner.rate=0.1", "growth.period=1.5", "trials.count=two",
                                      "body=foo", "experiment=fig9"])
def test_wrong_key_or_type_fails_at_compose_time(override):
    with pytest.raises(ConfigCompositionException):
        compose([override])


@pytest.mark.parametrize("override, key", [
    ("growth.period=-1", "growth.period"), ("learner.epochs=0", "learner.epochs"),
    ("trials.count=0", "trials.count"), ("learner.radius=-0.1", "learner.radius"),
    ("body.name=leg", "body.name"), ("growth.pattern=sideways", "growth.pattern"),
    ("conditions.periods=[10,-5]", "conditions.periods"), ("workers=0", "workers"),
])
def test_bad_values_raise_one_line_naming_the_key(override, key):
    with pytest.raises(ConfigError) as err:
        plan(compose([override]))
    assert str(err.value).startswith(f"{key}=") and "\n" not in str(err.value)


def test_seeds_and_keys_are_distinct_and_stable():
    cfg = compose(["experiment=fig4"])
    a, b = plan(cfg), plan(compose(["experiment=fig4"]))
    assert [t["key"] for t in a] == [t["key"] for t in b]
    assert len({t["key"] for t in a}) == len(a)
    assert len({tuple(t["seed"]["spawn_key"]) for t in a}) == len(a)
    # the random stream depends on the condition's content, not on the figure's name
    c = plan(compose(["experiment=fig4", "figure=other"]))
    assert [t["seed"] for t in c] == [t["seed"] for t in a]
    assert not {t["key"] for t in c} & {t["key"] for t in a}
    # a change in what a trial uses changes its key
    d = plan(compose(["experiment=fig4", "learner.radius=0.3"]))
    assert not {t["key"] for t in d} & {t["key"] for t in a}


def test_code_fingerprint_follows_the_code_not_its_comments(tmp_path):
    from pipeline.plan import source_fingerprint

    module = tmp_path / "m.py"
    module.write_text('"""Doc."""\ndef f(x):\n    """Twice x."""\n    return 2 * x  # double\n')
    base = source_fingerprint(tmp_path)
    assert len(base) == 16 and len(code_fingerprint()) == 16
    module.write_text('"""Other doc."""\n\ndef f(x):\n    # comment\n    return 2 * x\n')
    assert source_fingerprint(tmp_path) == base
    module.write_text('"""Doc."""\ndef f(x):\n    """Twice x."""\n    return 3 * x\n')
    assert source_fingerprint(tmp_path) != base
    (tmp_path / "n.py").write_text("y = 1\n")
    assert source_fingerprint(tmp_path) != base


def test_config_round_trips_to_yaml():
    cfg = compose(["experiment=fig5"])
    assert "nonproportional" in OmegaConf.to_yaml(cfg)
