"""Configs: every experiment composes to the paper's settings, schemas catch typos, seeds and
cache keys are stable and distinct."""
from pathlib import Path

import pytest

import pipeline.fingerprint as fingerprint_module
from hydra.errors import ConfigCompositionException
from omegaconf import OmegaConf

from gbmodel.learners import goal_babbling
from pipeline.config import CONF_DIR, ConfigError, compose
from pipeline.fingerprint import code_fingerprint
from pipeline.plan import conditions, plan

EXPERIMENTS = sorted(p.stem for p in (CONF_DIR / "experiment").glob("*.yaml"))

# The paper's settings per figure (sec. 3.1-3.3): body, growth pattern, trials, then the learner.
PAPER = {
    "fig4": dict(body="arm5", pattern="proportional", trials=20,
                 learner=dict(radius=0.2, variations=20, targets_per_epoch=15, steps=7),
                 epochs=100_000),
    "fig5": dict(body="arm5", pattern="nonproportional", trials=20,
                 learner=dict(radius=0.2, variations=20, targets_per_epoch=15, steps=7),
                 epochs=100_000),
    "fig7": dict(body="icub", pattern="proportional", trials=5,
                 learner=dict(radius=0.1, variations=20, targets_per_epoch=30, steps=10),
                 epochs=100_000),
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
    assert spec["body"]["name"] == want["body"]
    assert spec["growth"]["pattern"] == want["pattern"]
    assert spec["epochs"] == want["epochs"]
    assert spec["learner"]["name"] == "goal_babbling"
    for k, v in want["learner"].items():
        assert spec["learner"][k] == v, k
    growing = [t["spec"]["growth"] for t in trials if t["labels"]["growth"] != "none"]
    assert {(g["start_size"], g["end_size"]) for g in growing} == {(0.5, 1.0)}
    refs = {t["growth_label"]: t["spec"]["growth"] for t in trials
            if t["labels"]["growth"] == "none"}
    assert refs["const0.5"]["start_size"] == refs["const0.5"]["end_size"] == 0.5
    assert refs["const1.0"]["period"] == 0
    # the constant short body is shrunk the way the figure grows (Fig. 5: non-proportionally)
    assert refs["const0.5"]["pattern"] == want["pattern"]
    assert cfg.paper.final_abs_error in (0.02, 0.006)
    for t in trials:
        assert set(t) == {"labels", "spec", "seed", "code", "key", "figure", "condition",
                          "growth_label", "variant"}
        assert set(t["labels"]) == {"body", "learner", "growth", "growth_period", "trial"}
        assert t["figure"] == name and t["labels"]["learner"] == "goal_babbling"


def test_fig2_is_the_2dof_arm_with_snapshots():
    cfg = compose(["experiment=fig2"])
    trials = plan(cfg)
    assert len(trials) >= 3  # the extremes are judged over at least 3 trials
    trial = trials[0]
    assert trial["spec"]["body"]["name"] == "arm2" and trial["labels"]["growth"] == "none"
    assert len(trial["spec"]["snapshots"]) >= 3


def test_smoke_profile_shrinks_and_moves_outputs():
    cfg = compose(["experiment=fig7", "profile=smoke"])
    assert cfg.learner.epochs <= 2000 and cfg.trials.count <= 2
    assert Path(cfg.paths.out).name == "smoke"
    assert Path(cfg.paths.report) == Path(cfg.paths.out) / "latest"
    assert cfg.learner.radius == 0.1  # the experiment's values otherwise stay


def test_body_brings_its_learner_settings_unless_overridden():
    icub = compose(["body=icub"]).learner
    assert (icub.radius, icub.targets_per_epoch, icub.steps) == (0.1, 30, 10)
    assert compose(["body=icub", "learner.targets_per_epoch=15"]).learner.targets_per_epoch == 15
    # without the body's settings, the learner's own defaults (the planar arms')
    plain = compose(["body=icub", "~body_learner"]).learner
    assert (plain.radius, plain.targets_per_epoch) == (0.2, 15)
    assert compose(["body=arm5"]).learner.targets_per_epoch == 15


@pytest.mark.parametrize("learner", ["goal_babbling", "online_goal_babbling"])
def test_the_urdf_icub_takes_the_icubs_learner_settings(learner):
    """icub_urdf is the iCub from its URDF: each learner's settings are the DH iCub's."""
    dh, urdf = (compose([f"body={b}", f"learner={learner}"]).learner for b in ("icub", "icub_urdf"))
    assert (urdf.radius, urdf.targets_per_epoch, urdf.steps) == (0.1, 30, 10)
    assert {k: v for k, v in urdf.items() if k != "fast"} == \
        {k: v for k, v in dh.items() if k != "fast"}


def test_default_learning_rate_is_the_cores_or_the_bodys_rule():
    """arm5 takes the core's default; the other bodies their own 1 / W (their body settings)."""
    assert compose(["body=arm5"]).learner.learning_rate == goal_babbling.Params().learning_rate
    for body, W in (("arm2", 1931), ("icub", 1791), ("ergo_jr", 227.3)):
        assert compose([f"body={body}"]).learner.learning_rate == pytest.approx(1 / W, rel=1e-3)
    # online Goal Babbling's per-sample rate: measured on the iCub and the Ergo Jr, else 0.1
    for body, eta in (("arm5", 0.1), ("icub", 0.3), ("ergo_jr", 0.3)):
        assert compose([f"body={body}", "learner=online_goal_babbling"]).learner.learning_rate \
            == eta


def test_fast_is_a_learner_setting():
    cfg = compose(["learner.fast=false"])
    assert cfg.learner.fast is False and "fast" not in cfg
    assert plan(cfg)[0]["spec"]["learner"]["fast"] is False


def test_paths_are_rooted_at_the_repository_not_the_cwd(monkeypatch, tmp_path):
    monkeypatch.chdir(tmp_path)
    cfg = compose([])
    assert Path(cfg.paths.cache) == CONF_DIR.parent / "outputs" / "cache"
    assert Path(cfg.paths.published) == CONF_DIR.parent / "outputs" / "report"
    moved = compose([f"paths.root={tmp_path}"]).paths
    assert Path(moved.report) == tmp_path / "outputs/latest"
    assert Path(moved.published) == tmp_path / "outputs/report"


@pytest.mark.parametrize("override", ["learner.rate=0.1", "growth.period=1.5", "trials.count=two",
                                      "body=foo", "experiment=fig9", "learner=foo",
                                      "learner.fast=maybe", "fast=true"])
def test_wrong_key_or_type_fails_at_compose_time(override):
    with pytest.raises(ConfigCompositionException):
        compose([override])


@pytest.mark.parametrize("override, key", [
    ("growth.period=-1", "growth.period"), ("learner.epochs=0", "learner.epochs"),
    ("learner.radius=-0.1", "learner.radius"),
    ("body.units=grad", "body.units"), ("growth.pattern=sideways", "growth.pattern"),
    ("conditions.periods=[10,-5]", "conditions.periods"),
    ("learner.learning_rate=0", "learner.learning_rate"), ("learner.name=nope", "learner.name"),
    ("evaluation.points=nowhere", "evaluation.points"), ("figure=a/b", "figure"),
    ("learner.epochs=1000000000000", "learner.epochs"), ("paths.root=/etc/passwd", "paths.root"),
    ("conditions.references=[0]", "conditions.references"),
])
def test_bad_values_raise_one_line_naming_the_key(override, key):
    with pytest.raises(ConfigError) as err:
        plan(compose([override]))
    assert str(err.value).startswith(f"{key}=") and "\n" not in str(err.value)


@pytest.mark.parametrize("override, key", [("trials.count=0", "trials.count"),
                                           ("workers=0", "workers"),
                                           ("trials.root_seed=-1", "trials.root_seed")])
def test_bad_plan_values_are_config_errors(override, key):
    with pytest.raises(ConfigError) as err:
        plan(compose([override]))
    assert str(err.value).startswith(f"{key}=")


def test_bad_plan_values_are_one_line_naming_the_key_all_the_same():
    """Whatever their class (see the xfail above), they name the key in one line."""
    for override, key in [("trials.count=0", "trials.count"), ("workers=0", "workers")]:
        with pytest.raises(ValueError) as err:
            plan(compose([override]))
        assert str(err.value).startswith(f"{key}=") and "\n" not in str(err.value)


def test_non_proportional_growth_of_a_body_that_grows_everywhere_is_refused():
    for body in ("arm2", "icub"):
        with pytest.raises(ConfigError, match=r"^growth\.pattern='nonproportional'"):
            plan(compose([f"body={body}", "growth=nonproportional"]))


def test_seeds_and_keys_are_distinct_and_stable():
    cfg = compose(["experiment=fig4"])
    a, b = plan(cfg), plan(compose(["experiment=fig4"]))
    assert [t["key"] for t in a] == [t["key"] for t in b]
    assert len({t["key"] for t in a}) == len(a)
    assert len({tuple(t["seed"]["spawn_key"]) for t in a}) == len(a)
    # a trial is its content: under another figure's name it is the same trial (computed once)
    c = plan(compose(["experiment=fig4", "figure=other"]))
    assert [t["seed"] for t in c] == [t["seed"] for t in a]
    assert [t["key"] for t in c] == [t["key"] for t in a]
    # a change in what a trial uses changes its key, not its random numbers
    d = plan(compose(["experiment=fig4", "learner.radius=0.3"]))
    assert not {t["key"] for t in d} & {t["key"] for t in a}
    assert [t["seed"] for t in d] == [t["seed"] for t in a]
    # what does not change a trial (workers, the engine) does not change its key
    e = plan(compose(["experiment=fig4", "workers=1"]))
    assert [t["key"] for t in e] == [t["key"] for t in a]


def test_code_fingerprint_follows_the_code_not_its_comments(tmp_path):
    def source_fingerprint(files, root):
        return fingerprint_module.source_fingerprint(
            [(f.relative_to(root).as_posix(), f.read_text()) for f in files])

    module = tmp_path / "m.py"
    module.write_text('"""Doc."""\ndef f(x):\n    """Twice x."""\n    return 2 * x  # double\n')
    base = source_fingerprint([module], tmp_path)
    assert len(base) == 16 and len(code_fingerprint("goal_babbling")) == 16
    module.write_text('"""Other doc."""\n\ndef f(x):\n    # comment\n    return 2 * x\n')
    assert source_fingerprint([module], tmp_path) == base
    module.write_text('"""Doc."""\ndef f(x):\n    """Twice x."""\n    return 3 * x\n')
    assert source_fingerprint([module], tmp_path) != base
    (tmp_path / "n.py").write_text("y = 1\n")
    assert source_fingerprint([module, tmp_path / "n.py"], tmp_path) != base
    # a file's name is part of the code (a module moved is a module changed)
    module.write_text('"""Doc."""\ndef f(x):\n    """Twice x."""\n    return 2 * x  # double\n')
    moved = tmp_path / "sub" / "m.py"
    moved.parent.mkdir()
    moved.write_text(module.read_text())
    assert source_fingerprint([moved], tmp_path) != base


def test_every_trial_carries_its_learners_fingerprint():
    (t,) = plan(compose(["growth=none", "trials.count=1"]))
    assert t["code"] == code_fingerprint("goal_babbling")


def test_config_round_trips_to_yaml():
    cfg = compose(["experiment=fig5"])
    text = OmegaConf.to_yaml(cfg)
    assert "nonproportional" in text
    assert OmegaConf.create(text) == cfg


def test_make_runs_exactly_the_experiments_the_report_publishes():
    """Each experiment file declares its list and place (declares.group, declares.order); the
    Makefile's lists (PAPER, CHOICES, EXPLAIN, STUDIES: `make experiments`) and
    report.paper_experiments are read from those declarations, and every experiment in
    conf/experiment/ is in one of them: `make studies` computes what `report.publish=true` checks,
    and nothing is left out of either; `make reproduce` publishes exactly its part (PAPER,
    CHOICES, EXPLAIN) and checks that part."""
    import shutil
    import subprocess

    from pipeline.experiments import GROUPS, listed

    if shutil.which("make") is None:
        pytest.skip("no make on this machine")
    r = subprocess.run(["make", "-s", "experiments"], cwd=CONF_DIR.parent, capture_output=True,
                       text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    groups = dict(map(str.strip, ln.split("=", 1)) for ln in r.stdout.splitlines())
    assert list(groups) == ["PAPER", "CHOICES", "EXPLAIN", "STUDIES"]
    figures = [f for g in groups.values() for f in g.split()]
    assert [f for g in GROUPS for f in listed((CONF_DIR,), g)] == figures
    assert list(compose([]).report.paper_experiments) == figures
    assert sorted(figures) == sorted(p.stem for p in (CONF_DIR / "experiment").glob("*.yaml"))
    make = (CONF_DIR.parent / "Makefile").read_text()
    reproduce = make[make.index("\nreproduce:"):make.index("\nstudies:")]
    assert 'FIGURES="$(PAPER) $(CHOICES) $(EXPLAIN)"' in reproduce
    assert "report.paper_experiments=[$(shell echo $(PAPER) $(CHOICES) $(EXPLAIN)" in reproduce
