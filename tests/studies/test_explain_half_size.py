"""The explanations of the half-size arm's slower learning and of the rise per rate, on
synthetic aggregates with known answers; both skip when their experiment is not in the run."""
import numpy as np
import pandas as pd

from pipeline.studies import explain

EPOCHS = np.array([1, 10, 100, 1000, 10000, 20000])


def _half_size_agg(slower: dict, n=5, seed=0):
    """explain_fig4_half_size: per variant (label -> (rate, solver, half/full ratio per epoch)),
    a full-size arm falling as 1 / epoch and a half-size one `ratio` times it per unit size."""
    rng = np.random.default_rng(seed)
    rows, summ, conds = [], [], {}
    for k, (label, (rate, solver, ratio)) in enumerate(slower.items()):
        for size in (0.5, 1.0):
            name = f"{label} | const{size}"
            for t in range(n):
                full = 0.5 / EPOCHS ** 0.3 * (1 + 0.01 * rng.standard_normal(len(EPOCHS)))
                rel = full * (np.asarray(ratio) if size == 0.5 else 1.0)
                rows += [dict(condition=name, trial=t, epoch=e, rel_error=v, abs_error=v * size)
                         for e, v in zip(EPOCHS, rel)]
            summ.append(dict(condition=name, variant=label, choice="how M learns",
                             chosen=k == 0, growth="none", growth_period=0, end_size=size,
                             n_trials=n))
            conds[name] = {"spec": {"learner": {"learning_rate": rate, "solver": solver}}}
    return dict(trials=pd.DataFrame(rows), summary=pd.DataFrame(summ),
                models={"conditions": conds})


SLOW = [1.2, 1.5, 2.0, 1.9, 1.3, 0.95]  # above from epoch 1 to 10,000
SAME = [1.0, 1.0, 1.0, 0.99, 1.0, 1.0]


def test_the_ratio_is_read_at_its_epochs_with_the_last_epoch_above():
    h = explain.half_size(_half_size_agg({"d": (1.0, "gradient", SLOW)}))
    assert len(h) == 1 and h[0]["kind"] == "default" and h[0]["trials"] == 5
    assert list(h[0]["at"]) == [100, 1000, 10000]
    assert abs(h[0]["at"][1000]["value"] - 1.9) < 0.02
    assert h[0]["at"][1000]["low"] < 1.9 < h[0]["at"][1000]["high"]
    assert h[0]["last_above"] == 10000


def _paragraph(default, doubled=None, lstsq=None):
    """The half-size paragraph for ratio curves of the default, the doubled rate and lstsq."""
    variants = {"d": (1.0, "gradient", default)}
    if doubled is not None:
        variants["2/W"] = (2.0, "gradient", doubled)
    if lstsq is not None:
        variants["ls"] = (1.0, "lstsq", lstsq)
    return explain.half_size_text(explain.half_size(_half_size_agg(variants)))


def test_the_paragraph_follows_the_numbers():
    closes = _paragraph(SLOW, SAME, SAME)
    assert "plain step's size dependence" in closes and "epoch 1,000 1.89 [" in closes
    assert "plain step at 2 / W: epoch 100 1.0" in closes and "least squares: epoch" in closes
    assert "but not with the doubled rate" in _paragraph(SLOW, SLOW, SAME)
    late = _paragraph(SLOW, [1.6, 1.5, 1.5, 0.5, 0.3, 0.3], SAME)
    assert "closes it only after epoch" in late and "plain step's size dependence" in late
    assert "gap remains under least squares" in _paragraph(SLOW, SAME, SLOW)
    assert "does not learn slower" in _paragraph(SAME, lstsq=SAME)


def _rise_agg(rise_by_rate: dict, n=6, seed=1):
    """readings_fig4: per reading (label -> (rate, solver, choice, {T_G: rise})), trials whose
    absolute error falls, rises by `rise` during growth, and falls again."""
    rng = np.random.default_rng(seed)
    ep = np.array([1, 2, 5, 10, 11, 20, 50, 100, 101, 200, 1000, 1001, 2000, 10000, 10001, 20000])
    rows, summ, conds = [], [], {}
    for k, (label, (rate, solver, choice, rises)) in enumerate(rise_by_rate.items()):
        for tg, up in rises.items():
            name = f"{label} | TG{tg}"
            for t in range(n):
                e = 0.4 / ep ** 0.2
                i = np.searchsorted(ep, tg)
                e[i] = e[i - 1] * (1 + up + 0.01 * rng.standard_normal())
                rows += [dict(condition=name, trial=t, epoch=x, abs_error=v, rel_error=v)
                         for x, v in zip(ep, e)]
            summ.append(dict(condition=name, variant=label, choice=choice, chosen=k == 0,
                             growth="proportional", growth_period=tg, end_size=1.0, n_trials=n))
            conds[name] = {"spec": {"learner": {"learning_rate": rate, "solver": solver}}}
    return dict(trials=pd.DataFrame(rows), summary=pd.DataFrame(summ),
                models={"conditions": conds})


def test_the_rise_per_rate_is_the_scorecards_measure_and_its_paragraph_follows_it():
    agg = _rise_agg({"default": (1.0, "gradient", "default", {1000: 0.02, 10000: 0.3}),
                     "eta = 0.1 / W": (0.1, "gradient", "learning rate", {1000: 0.3,
                                                                          10000: 0.02}),
                     "lstsq": (1.0, "lstsq", "solver", {1000: 0.2, 10000: 0.2}),
                     "online": (1.0, "gradient", "updates per epoch", {1000: 0.5, 10000: 0.5})})
    r = explain.rises(agg)
    assert {x["reading"] for x in r} == {"default", "eta = 0.1 / W", "lstsq"}
    d = {(x["reading"], x["T_G"]): x for x in r}
    assert abs(d[("default", 10000)]["value"] - 0.3) < 0.02
    assert d[("default", 10000)]["low"] < 0.3 < d[("default", 10000)]["high"]
    text = explain.rises_text(r)
    assert "above the bound at 1 / W" in text and "below the bound at 0.1 / W" in text
    assert "falls below the bound as the rate falls" in text
    md = explain.rises_markdown(r)
    assert "| default (6 trials) |" in md and "T_G = 10,000" in md


def test_the_explanations_skip_what_the_run_lacks():
    assert explain.rows({}) == []
    rows = explain.rows({"explain_fig4_half_size": _half_size_agg({"d": (1.0, "gradient",
                                                                         SLOW)})})
    assert [r["experiment"].split(" ")[0] for r in rows] == ["half"]
