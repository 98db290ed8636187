"""Results you can pick up (pipeline/studies/provenance.py): the trained models beside the
report, the provenance block and the credits; and the examples/ scripts, each run at tiny scale
on the same smoke run."""
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from conftest import run_cli, tiny_overrides
from pipeline import models
from pipeline.config import REPO_ROOT
from pipeline.studies import provenance

EXAMPLES = REPO_ROOT / "examples"
SPEC = dict(body={"name": "arm5"}, growth={}, learner={"name": "goal_babbling"}, evaluation={},
            epochs=1000, evals_per_decade=20, snapshots=[])


@pytest.fixture(scope="module")
def smoke(tmp_path_factory):
    """A two-condition figure (growing, constant), simulated, aggregated and reported."""
    root = tmp_path_factory.mktemp("prov")
    args = tiny_overrides(root, "figure=prov", "growth.period=10", "conditions.references=[0.5]",
                          "trials.count=2")
    for stage in ("pipeline.simulate", "pipeline.aggregate", "pipeline.report"):
        r = run_cli(stage, *args)
        assert r.returncode == 0, r.stderr[-2000:]
    out = root / "outputs" / "smoke"
    return dict(root=root, report=out / "latest" / "prov", aggregate=out / "aggregate")


def test_report_holds_the_final_models_and_they_reach_as_the_aggregate(smoke):
    path = smoke["report"] / "models" / "prov.json"
    data = json.loads(path.read_text())
    assert sorted(data["conditions"]) == ["TG10", "const0.5"]
    assert path.stat().st_size < 8000 * 2 * 2  # a few kB per condition and trial
    assert "models/prov.json" in (smoke["report"] / "report.md").read_text()
    full, compact = models.load("prov", smoke["aggregate"]), models.load("prov", smoke["report"])
    assert compact.labels == full.labels
    for label in full.labels:
        x = full[label].body.target_set(full[label].size)
        for trial in (0, 1):
            np.testing.assert_allclose(compact[label].posture(x, trial),
                                       full[label].posture(x, trial), atol=1e-6)
            np.testing.assert_allclose(compact[label].reach(x, trial),
                                       full[label].reach(x, trial), atol=1e-6)


def test_report_has_the_provenance_block_and_credits(smoke):
    md = (smoke["report"] / "report.md").read_text()
    block = md[md.index("## Provenance"):md.index("## Files")]
    assert f"commit: `{provenance.commit()}`" in block and len(provenance.commit()) >= 40
    import hashlib
    lock = hashlib.sha256((REPO_ROOT / "requirements.lock").read_bytes()).hexdigest()[:16]
    assert f"sha256 `{lock}`" in block
    import numpy
    assert f"numpy {numpy.__version__}" in block and f"python {sys.version.split()[0]}" in block
    assert f"CPU: {provenance.cpu_model()}" in block
    assert "| prov | 4 |" in block  # 2 conditions x 2 trials
    from pipeline import __version__
    made = next(ln for ln in block.splitlines() if ln.startswith("- made "))
    assert f"by gbgrowth {__version__}: `python -m pipeline.report profile=smoke " in made
    assert f"paths.root={smoke['root']}" in made and "figure=prov" in made
    # each stage's run kept its config and overrides (pipeline.cli.snapshot), under paths.root
    logs = smoke["root"] / "outputs" / "smoke" / "logs"
    for stage in ("simulate", "aggregate", "report"):
        (snap,) = logs.glob(f"{stage}/*/.hydra")
        assert "- figure=prov" in (snap / "overrides.yaml").read_text()
        assert f"root: {smoke['root']}" in (snap / "config.yaml").read_text()  # resolved
    row = next(ln for ln in block.splitlines() if ln.startswith("| prov |")).split("|")
    assert row[3].strip().endswith(" s") and "of" not in row[3]  # all 4 trials measured
    assert "## Credits" in block and "CC-BY-SA" not in block  # arm5 only: nothing to credit


def test_measured_cpu_time_sums_each_trials_own_record(tmp_path):
    from pipeline import cache
    cache.write_times(tmp_path, {"a": 1.5, "b": 2.0})
    cache.write_times(tmp_path, {"b": 3.0})  # a later run computed b again
    (tmp_path / "logs" / "times" / "zz-damaged.json").write_text("{")
    assert cache.write_times(tmp_path, {}) is None
    trials = {"0": {"key": "a"}, "1": {"key": "b"}, "2": {"key": "c"}}
    aggs = {"f": dict(models=dict(conditions={"c": dict(spec=SPEC, trials=trials)}))}
    assert provenance.costs(aggs, tmp_path)[0]["f"][:3] == (3, 2, 4.5)


def test_the_total_counts_a_trial_shared_by_two_figures_once(tmp_path):
    from pipeline import cache
    from pipeline.plan import cost
    cache.write_times(tmp_path, {"a": 1.5, "b": 2.0, "c": 4.0})
    spec = dict(body={"name": "arm5"}, growth={}, learner={"name": "goal_babbling"},
                evaluation={}, epochs=1000, evals_per_decade=20, snapshots=[])
    one = lambda *keys: dict(spec=spec, trials={str(i): {"key": k} for i, k in enumerate(keys)})
    aggs = {"f": dict(models=dict(conditions={"c": one("a", "b")})),
            "g": dict(models=dict(conditions={"c": one("b", "c", "d")}))}  # b: f's trial too
    n, k, spent, seconds = provenance.costs(aggs, tmp_path)[1]
    assert (n, k, spent) == (4, 3, 7.5)  # d not measured
    assert seconds == pytest.approx(provenance.cpu_seconds(4 * cost(dict(spec=spec)), 4))
    assert provenance.costs(aggs, None)[1][:3] == (4, 0, 0)
    block = "\n".join(provenance.markdown(aggs, tmp_path))
    assert "| all, each shared trial once | 4 | 7.5 s (3 of 4 trials) |" in block
    assert "| all but the replicate sets" not in block
    block = "\n".join(provenance.markdown(aggs, tmp_path, apart=("g",)))
    assert "| all but the replicate sets, each shared trial once | 2 | 3.5 s |" in block
    assert "| the replicate sets (g) | 3 | 6.0 s (2 of 3 trials) |" in block
    assert "| all, each shared trial once | 4 | 7.5 s (3 of 4 trials) |" in block


def test_credits_name_the_third_party_robots_used():
    # the credits come from each body's own file (conf/body/<name>.yaml), carried in its spec
    from gbmodel.bodies import read_description
    aggs = {f: dict(models=dict(conditions={"c": dict(spec=dict(body=read_description(b)))}))
            for f, b in (("a", "icub_urdf"), ("b", "ergo_jr"), ("c", "arm5"), ("d", "ergo_jr"))}
    lines = provenance.credits(aggs)
    assert any("iCub" in ln and "CC-BY-SA-4.0" in ln for ln in lines)
    assert any("Ergo Jr" in ln and "GPL-3.0" in ln for ln in lines) and len(lines) == 2
    assert provenance.credits({"c": aggs["c"]}) == []


def test_every_shipped_third_party_body_carries_its_credits():
    # a body read from a URDF or MJCF file of another project names its model, source, licence
    from gbmodel.bodies import read_description, shipped
    for name in shipped():
        desc = read_description(name)
        if desc.get("urdf") or desc.get("mjcf"):
            assert set(desc.get("credits") or {}) == {"model", "source", "licence"}, name


def test_estimated_cpu_time_follows_the_cost_model():
    from pipeline.plan import cost
    spec = dict(body={"name": "arm5"}, growth={}, learner={"name": "goal_babbling"},
                evaluation={}, epochs=1000, evals_per_decade=20, snapshots=[])
    aggs = {"f": dict(models=dict(conditions={"c": dict(spec=spec, trials={"0": {}, "1": {}})}))}
    n, _, _, seconds = provenance.costs(aggs, None)[0]["f"]
    assert n == 2 and seconds == pytest.approx(provenance.cpu_seconds(2 * cost(dict(spec=spec)), 2))


def _example(name, tmp_path, **env):
    e = dict(os.environ, MPLBACKEND="Agg", GBGROWTH_EXAMPLE_OUT=str(tmp_path),
             PYTHONPATH=str(REPO_ROOT), **env)
    r = subprocess.run([sys.executable, str(EXAMPLES / name)], capture_output=True, text=True,
                       cwd=tmp_path, env=e, timeout=300)
    assert r.returncode == 0, r.stderr[-2000:]
    return r.stdout


def test_example_committed_curves(smoke, tmp_path):
    out = _example("01_committed_curves.py", tmp_path,
                   GBGROWTH_CURVES=str(smoke["report"] / "curves.parquet"), GBGROWTH_FIGURE="prov")
    assert (tmp_path / "prov_abs_error.png").stat().st_size and "TG10" in out


def test_example_reach_with_a_model(smoke, tmp_path):
    out = _example("02_reach_with_a_model.py", tmp_path, GBGROWTH_FIGURE="prov",
                   GBGROWTH_MODELS=str(smoke["report"]))
    assert "mean miss over the grid" in out


def test_example_grow_your_own_urdf_arm(tmp_path):
    out = _example("03_grow_your_own_urdf_arm.py", tmp_path, GBGROWTH_EPOCHS="40")
    assert (tmp_path / "arm3_urdf_growth.png").stat().st_size and "final error" in out


def test_example_compare_two_learners(tmp_path):
    out = _example("04_compare_two_learners.py", tmp_path, GBGROWTH_EPOCHS="30",
                   GBGROWTH_TRIALS="1")
    assert (tmp_path / "learners.png").stat().st_size and "online_goal_babbling" in out


def test_examples_are_jupytext_percent_scripts():
    for p in sorted(EXAMPLES.glob("*.py")):
        text = p.read_text()
        assert text.startswith("# %% [markdown]") and text.count("# %%") >= 3, p.name
