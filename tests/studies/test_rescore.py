"""python -m pipeline.tools.rescore: a report's per-trial measures judged again under an edited
register, without a trial."""
import numpy as np
import pandas as pd
import yaml

from pipeline.studies import claims, measures_table
from pipeline.studies import scorecard as sc
from pipeline.tools import rescore
from test_claims import RISING, _figure


def _report(tmp_path):
    """A report folder holding measures.parquet and claims.csv of a 20-trial figure whose
    half-size reference ends at 0.5x the paper's value in metres (1.0x per unit size)."""
    trials, summary = _figure(RISING, periods=(10, 100, 10000), n=20, noise=0.05)
    summary["n_trials"] = 20
    ms = claims.measures("figX", trials, summary)
    measures_table.write(tmp_path / measures_table.NAME,
                         [measures_table.frame(ms, "figures", counted=True)])
    cards = sc.cells(sc.judged(ms))
    sc.claims_table(cards).to_csv(tmp_path / "claims.csv", index=False)
    return cards


def _edited(tmp_path, edit):
    data = yaml.safe_load(claims.REGISTER.read_text())
    edit({e["id"]: e for e in data["claims"]})
    path = tmp_path / "register.yaml"
    path.write_text(yaml.safe_dump(data))
    return path


def test_the_same_register_gives_the_reports_verdicts(tmp_path, capsys):
    cards = _report(tmp_path)
    out = rescore.rescore(tmp_path, claims.REGISTER)
    assert out["changed"] == []
    assert out["default"] == sc.headline(cards, ["figX"])
    assert rescore.main([str(tmp_path)]) == 0
    assert "no cell changed" in capsys.readouterr().out


def test_an_edited_criterion_changes_the_headline_without_a_trial(tmp_path, capsys):
    _report(tmp_path)

    def two_sided(by):  # the half-size reference two-sided in metres: 0.5x fails
        next(r for r in by["final"]["readings"] if r.get("primary"))["params"]["smaller"] = \
            "two-sided"
    assert rescore.main([str(tmp_path), "--register", str(_edited(tmp_path, two_sided))]) == 0
    text = capsys.readouterr().out
    assert "changed: figX final: reproduced -> not reproduced" in text
    assert "default reading on figX:" in text


def test_bad_input_is_one_line_and_exit_2(tmp_path, capsys):
    assert rescore.main([str(tmp_path)]) == 2
    assert capsys.readouterr().err.startswith("error: ")
    _report(tmp_path)
    (tmp_path / "bad.yaml").write_text("claims:\n- id: final\n  readings: []\n")
    assert rescore.main([str(tmp_path), "--register", str(tmp_path / "bad.yaml")]) == 2
    assert capsys.readouterr().err.count("\n") == 1


def test_the_measures_table_round_trips(tmp_path):
    trials, summary = _figure(RISING, periods=(10,), n=5)
    ms = claims.measures("figX", trials, summary)
    measures_table.write(tmp_path / "m.parquet", [measures_table.frame(ms, "figures")])
    back = measures_table.measures(measures_table.read(tmp_path / "m.parquet"))
    again = back[("figures", "", "figX")]
    assert [(m.claim, m.where) for m in again] == [(m.claim, m.where) for m in ms]
    for a, b in zip(again, ms):
        assert np.array_equal(a.values, b.values) and a.size == b.size
        assert (a.control is None) == (b.control is None)
        if a.control is not None:
            assert np.array_equal(a.control, b.control)


def test_a_reduced_scale_run_is_no_verdict_when_rescored_either(tmp_path):
    trials, summary = _figure(RISING, periods=(10,), n=20, noise=0.05)
    ms = claims.measures("figX", trials, summary)
    measures_table.write(tmp_path / measures_table.NAME,
                         [measures_table.frame(ms, "figures", counted=True)], scale="smoke")
    out = rescore.rescore(tmp_path, claims.REGISTER)
    n = out["default"]
    assert n[sc.NOT_A_VERDICT] > 0 and n[sc.REPRODUCED] == n[sc.NOT] == n[sc.INCONCLUSIVE] == 0


def test_rescoring_draws_no_fresh_samples(tmp_path, monkeypatch):
    """The t level of each measure is stored with it: rescoring reuses it."""
    _report(tmp_path)
    from pipeline.studies import coverage

    def fail(*a, **k):
        raise AssertionError("fresh samples drawn while rescoring")
    monkeypatch.setattr(coverage, "row", fail)
    coverage._FRESH.clear()
    assert rescore.rescore(tmp_path, claims.REGISTER)["changed"] == []


def test_the_edited_registers_readings_are_the_ones_shown(tmp_path):
    """The cells take which readings they show from the register being rescored, not the
    shipped one: every reading of the final error marked always_shown appears in the cell."""
    _report(tmp_path)
    ids = []

    def show_all(by):
        for rd in by["final"]["readings"]:
            rd["always_shown"] = True
            if not rd.get("primary"):
                ids.append(rd["id"])
    out = rescore.rescore(tmp_path, _edited(tmp_path, show_all))
    cell = out["cells"].set_index("claim").loc["final"]
    assert len(ids) > 2
    assert all(f"{i}: " in cell["others"] for i in ids), cell["others"]


def test_a_report_without_the_new_points_names_the_readings_that_judge_nothing(tmp_path, capsys):
    """A report made before the path targets and uniform points were scored: the readings that
    measure there judge nothing, and rescore says which instead of dropping them silently."""
    _report(tmp_path)
    assert rescore.rescore(tmp_path, claims.REGISTER)["unmeasured"] == []
    t = pd.read_parquet(tmp_path / measures_table.NAME)
    old = t[(t["points"] == "grid") & (t["span"] == "end")].drop(columns=["points", "span"])
    old.to_parquet(tmp_path / measures_table.NAME)
    out = rescore.rescore(tmp_path, claims.REGISTER)
    assert "final: path targets, full size two-sided" in out["unmeasured"]
    assert "rise_none: uniform points" in out["unmeasured"]
    assert not any(u.startswith(("blend", "after")) for u in out["unmeasured"])
    assert rescore.main([str(tmp_path)]) == 0
    assert "judge nothing (regenerate the report): final: path targets" in capsys.readouterr().out
