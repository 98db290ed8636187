"""Nothing computed twice: the same condition draws the same numbers wherever it is planned
(its seed follows its content and the trial index, never the figure's name), so two experiments
that hold it share its trials, and the cache runs them once (issue 43 item 2)."""
from __future__ import annotations

import json
from pathlib import Path

import pandas as pd
import pytest

from pipeline import aggregate, cache, simulate
from pipeline.config import compose
from pipeline.plan import plan


def _by_label(trials, label, variant=None):
    return [t for t in trials if t["growth_label"] == label
            and (t.get("variant") or {}).get("label") == variant]


def test_fig4_and_fig5_hold_the_same_full_size_trials():
    """Fig. 5's full-size reference (planned under non-proportional growth) is Fig. 4's: the
    same body, every segment at full length; its trials are Fig. 4's, key by key. Its half-size
    reference is another body (the held segments stay at full length), with other keys."""
    fig4, fig5 = plan(compose(["experiment=fig4"])), plan(compose(["experiment=fig5"]))
    full4, full5 = _by_label(fig4, "const1.0"), _by_label(fig5, "const1.0")
    assert len(full4) == len(full5) == 20
    assert [t["key"] for t in full4] == [t["key"] for t in full5]
    assert full5[0]["spec"]["growth"]["pattern"] == "proportional"  # the one constant growth
    half4, half5 = _by_label(fig4, "const0.5"), _by_label(fig5, "const0.5")
    assert not {t["key"] for t in half4} & {t["key"] for t in half5}
    assert half5[0]["spec"]["growth"]["pattern"] == "nonproportional"
    # the growing conditions of the two figures are other bodies: other draws
    assert not {json.dumps(t["seed"]) for t in _by_label(fig4, "TG1000")} \
        & {json.dumps(t["seed"]) for t in _by_label(fig5, "TG1000")}


def test_the_common_start_reading_at_half_size_is_fig4s_half_size_body():
    """readings_fig5's "common start body" (fixed_scale=0.5) at half size is every segment at
    half length: Fig. 4's half-size reference, shared."""
    fig4 = plan(compose(["experiment=fig4"]))
    readings = plan(compose(["experiment=readings_fig5"]))
    common = _by_label(readings, "const0.5", "common start body")
    assert common and {t["key"] for t in common} <= {t["key"] for t in _by_label(fig4, "const0.5")}


def test_the_stream_follows_the_content_not_the_epochs_the_learner_or_the_name():
    """The seed of a condition does not change with the epochs (a shorter run draws the first
    blocks of a longer one), the learner or a body's variant fields (variants share draws) or
    the figure's name; it changes with the body and the growth."""
    base = ["body=arm5", "growth=proportional", "growth.period=100", "trials.count=3"]
    seeds = lambda over: [t["seed"] for t in plan(compose([*base, *over]))]  # noqa: E731
    first = seeds([])
    assert seeds(["learner.epochs=2000"]) == first
    assert seeds(["learner.radius=0.1", "learner.solver=lstsq"]) == first
    assert seeds(["figure=elsewhere"]) == first
    assert seeds(["body.home=[0.1,0.2,0.3,0.4,0.5]"]) == first
    assert seeds(["body=arm2"]) != first
    assert seeds(["growth.period=1000"]) != first
    assert len({json.dumps(s) for s in first}) == 3


@pytest.fixture
def tiny(tmp_path):
    return ["profile=smoke", "workers=1", f"paths.root={tmp_path}"]  # 1000 epochs, 2 trials


def test_a_trial_two_experiments_share_is_run_once(tiny):
    """fig4 then fig5 on one cache: fig5 finds its full-size reference cached; both in one run
    count it once; both figures aggregate it, with the same curve."""
    first = simulate.simulate(compose(["experiment=fig4", *tiny]))
    assert (first.total, first.ran) == (12, 12)
    second = simulate.simulate(compose(["experiment=fig5", *tiny]))
    assert (second.total, second.cached, second.ran) == (12, 2, 10)
    both = simulate.simulate(compose(["experiments=[fig4,fig5]", *tiny]),
                             ["experiments=[fig4,fig5]", *tiny])
    assert (both.total, both.cached, both.ran) == (22, 22, 0)
    cfg = compose(tiny)
    assert not aggregate.aggregate(cfg)
    curves = {fig: pd.read_parquet(f"{cfg.paths.aggregate}/{fig}/trials.parquet")
              for fig in ("fig4", "fig5")}
    full = [c[c["condition"] == "const1.0"].sort_values(["trial", "epoch"])
            for c in curves.values()]
    assert len(full[0]) and full[0]["abs_error"].tolist() == full[1]["abs_error"].tolist()


def _sidecars(cfg) -> dict:
    return {p.stem: json.loads(p.read_bytes())
            for p in (Path(cfg.paths.cache) / "trials").glob("*/*.json")}


def test_trials_whose_learning_is_anothers_first_epochs_learn_once(tmp_path, caplog):
    """Issue 57 item 3: a variant that changes the evaluation, or runs fewer epochs (a multiple
    of the draw block), is scored on the way by the longest run of its learning
    (pipeline.simulate.with_views), each trial cached under its own key with the bytes it has
    when run alone; its CPU is counted in the trial that learned for it."""
    base = ["profile=smoke", "learner.epochs=2000", "trials.count=2", "workers=1",
            "growth=proportional", "growth.period=500"]
    settings = [[], ["evaluation.points=path", "evaluation.path_steps=4"],
                ["evaluation.formula=rms", "learner.epochs=1000"]]
    variants = ",".join(f"{{label:v{i},choice:x,set:[%s]}}" % ",".join(f"'{o}'" for o in s)
                        for i, s in enumerate(settings))
    cfg = compose([*base, f"paths.root={tmp_path / 'together'}", "figure=views",
                   f"conditions.variants=[{variants}]"])
    with caplog.at_level("INFO", logger="pipeline.simulate"):
        together = simulate.simulate(cfg)
    n = len(plan(cfg))
    assert f"{n} to run on 1 worker(s) ({2 * n // 3} scored on another's learning: about " \
        in caplog.text and "of CPU not spent)" in caplog.text
    assert (together.total, together.ran, together.failed) == (n, n, {})
    shared = _sidecars(cfg)
    assert len(shared) == n
    apart = {}
    for i, s in enumerate(settings):  # each setting in a run of its own: no views
        c = compose([*base, f"paths.root={tmp_path / str(i)}", "figure=views", *s])
        assert simulate.simulate(c).ran == n // 3
        apart.update(_sidecars(c))
    assert apart == shared  # the same keys, curves (their sha256), models and jumps
    times = cache.read_times(cfg.paths.out)
    assert sorted(times.values()).count(0.0) == 2 * n // 3  # the views'
