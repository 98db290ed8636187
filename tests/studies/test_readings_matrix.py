"""The readings x figures matrix, the recommended reading and its check against the verdicts,
the readings page's block, and the readings figure's layout, on synthetic aggregates."""
import numpy as np
import pandas as pd
import pytest

from pipeline.config import REPO_ROOT
from pipeline.studies import claims, readings, sections
from pipeline.studies import scorecard as sc
from test_claims import EPOCHS, RISING, _figure

FLAT = list(np.linspace(0.5, 0.02, len(EPOCHS)))  # no rise during growth
DEFAULT = "this project's default (plain step, exact R, one batch step, grid)"


def _reading_agg(readings_curves: dict, n=4):
    """One readings aggregate: every reading's conditions named 'reading | condition'."""
    trials, summaries, curves = [], [], []
    for k, (label, (grown, choice)) in enumerate(readings_curves.items()):
        t, s = _figure(grown, periods=(10,), n=n, seed=k)
        for f in (t, s):
            f["condition"] = label + " | " + f["condition"]
        s["variant"], s["choice"], s["chosen"] = label, choice, choice == "default"
        c = t.groupby(["condition", "epoch"], as_index=False)["abs_error"].mean()
        curves.append(c.rename(columns={"abs_error": "abs_error_mean"}))
        trials.append(t)
        summaries.append(s)
    return dict(trials=pd.concat(trials, ignore_index=True),
                summary=pd.concat(summaries, ignore_index=True),
                curves=pd.concat(curves, ignore_index=True))


AGG = {"readings_fig4": _reading_agg({DEFAULT: (RISING, "default"),
                                      "eta = 0.1 / W": (FLAT, "learning rate")})}


@pytest.fixture(scope="module")
def cards():
    return readings.intervals(AGG)


def test_the_matrix_holds_the_scorecards_verdicts_for_the_papers_claims_only(cards):
    m = readings.matrix(cards)
    assert m["reading"].tolist() == [DEFAULT, "eta = 0.1 / W"]
    assert m["fig4 n"].tolist() == ["4", "4"]
    paper = cards[~cards["diagnostic"].astype(bool)]
    assert {c.split(" ", 1)[1] for c in m.columns if c.startswith("fig4 ")} == \
        set(paper["claim"]) | {"n"}
    for r in paper.to_dict("records"):
        row = m[m["reading"] == r["reading"]].iloc[0]
        assert row[f"fig4 {r['claim']}"] == r["verdict"]
    # the rising body reproduces the rise, the flat one does not
    assert m.set_index("reading").loc[DEFAULT, "fig4 rise"] == sc.REPRODUCED
    assert m.set_index("reading").loc["eta = 0.1 / W", "fig4 rise"] != sc.REPRODUCED


def test_the_markdown_is_the_csvs(cards, tmp_path):
    path = tmp_path / "readings_matrix.csv"
    path.write_text(readings.matrix(cards).to_csv(index=False))
    md = readings.matrix_markdown(readings.read_matrix(path))
    assert md == readings.matrix_markdown(readings.matrix(cards))
    assert "| eta = 0.1 / W | 4 |" in md and "✓ reproduced" in md


def test_the_readings_page_shows_the_committed_matrix_as_its_named_value():
    """docs/readings.md's readings table (the README links to it) is the named value
    readings.table (tests/studies/test_values.py renders every page from values.csv): here, that
    value is what the committed matrix gives."""
    from pipeline.studies import values

    csv = REPO_ROOT / "outputs" / "report" / "readings_matrix.csv"
    table = values.read(REPO_ROOT / "outputs" / "report" / values.FILE)["readings.table"]
    assert table == readings.matrix_markdown(readings.read_matrix(csv)).rstrip("\n")
    assert table in (REPO_ROOT / "docs" / "readings.md").read_text()
    templates = REPO_ROOT / "docs" / "templates"
    assert "{{ readings.table }}" in (templates / "docs" / "readings.md").read_text()
    assert "docs/readings.md#the-matrix" in (templates / "README.md").read_text()


def test_a_recommendation_the_verdicts_contradict_is_said_loudly(cards):
    recs = [dict(figure="fig4", reading="eta = 0.1 / W", reproduces=["rise", "final"], why="r")]
    found = readings.contradictions(cards, recs)
    assert len(found) >= 1 and "\"rise\" as reproduced" in found[0]
    md = readings.recommendations_markdown(cards, recs)
    assert "recommendation contradicted by the data: fig4, \"eta = 0.1 / W\"" in md
    # the same text for the reading that does reproduce the rise: no contradiction on it
    ok = [dict(recs[0], reading=DEFAULT, reproduces=["rise"])]
    assert readings.contradictions(cards, ok) == []
    assert "contradicted" not in readings.recommendations_markdown(cards, ok)
    gone = [dict(recs[0], reading="no such reading")]
    assert "is not in this run" in readings.contradictions(cards, gone)[0]
    # a figure not in this run is neither shown nor checked
    assert readings.contradictions(cards, [dict(recs[0], figure="fig7")]) == []


def test_the_committed_recommendations_name_the_papers_claims(tmp_path):
    t = readings.recommended()
    assert {r["figure"] for r in t} == {"fig4", "fig5", "fig7"}
    claims_only = claims.REGISTER.read_text().split("\nrecommended:", 1)[0]
    bad = tmp_path / "r.yaml"
    bad.write_text(claims_only + "\nrecommended:\n- {figure: fig4, reading: x, "
                   "reproduces: [above_refs], why: w}\n")
    with pytest.raises(ValueError, match="not a claim of the paper"):
        readings.recommended(bad)
    bad.write_text(claims_only + "\nrecommended:\n- {figure: fig9, reading: x, reproduces: [], "
                   "why: w}\n")
    with pytest.raises(ValueError, match="no readings figure"):
        readings.recommended(bad)
    bad.write_text(claims_only + "\nrecommended:\n- {figure: fig4, reading: x, reproduces: w}\n")
    with pytest.raises(ValueError, match="recommended"):  # the register's schema: one line
        readings.recommended(bad)


def test_the_readings_figure_shows_the_rate_and_solver_readings_and_fits():
    from test_figure_layout import _check_layout

    others = ["normalised step", "uniform amplitude", "path evaluation", "annealed rate",
              "online updates"]
    spec = {DEFAULT: (RISING, "default"), "eta = 0.1 / W": (FLAT, "learning rate (W)"),
            "least squares (solver=lstsq)": (FLAT, "solver"),
            **{o: (FLAT, o) for o in others}, "eta = 0.3 / W": (RISING, "learning rate (W)")}
    aggs = {s: _reading_agg(spec, n=2) for s in sections.reads("readings")}
    fig = readings.figure(aggs, "readings")
    titles = [ax.get_title() for ax in fig.axes if ax.get_visible()]
    assert len(titles) == 3 * 4
    assert not any(o in t for o in others for t in titles)
    _check_layout(fig)
    readings.figures.plt.close(fig)


def test_each_readings_final_errors_are_its_summary_rows():
    agg = dict(AGG["readings_fig4"])
    s = agg["summary"].assign(final_abs_error_mean=lambda f: 0.01 + 0.001 * np.arange(len(f)),
                              final_rel_error_mean=0.02)
    t = readings.finals({"readings_fig4": dict(agg, summary=s)})
    assert len(t) == len(s) and set(t["figure"]) == {"fig4"}
    assert set(t["reading"]) == {DEFAULT, "eta = 0.1 / W"}
    assert not t["condition"].str.contains(" | ").any()  # named as in the paper's figure
    assert np.allclose(sorted(t["final_abs_error_mean"]), sorted(s["final_abs_error_mean"]))


def test_a_reduced_scale_run_decides_no_reading_either(cards):
    """make smoke's readings run 5 trials on some readings (their own trials.count): at a reduced
    scale (report.scale) the readings study measures them and decides nothing, as the figures'
    scorecard and a rescored measures.parquet do."""
    assert {sc.REPRODUCED, sc.NOT} & set(cards["verdict"])  # decided at the paper's scale
    smoke = readings.intervals(AGG, scale="smoke")
    assert set(smoke["verdict"]) <= {sc.NOT_A_VERDICT, readings.claims.DIVERGED}
    assert (smoke["note"] == "a smoke run, not the paper's scale").all()


def test_a_reduced_scale_report_writes_no_readings_verdict(tmp_path):
    """The readings section of a smoke report: readings.csv, readings_scorecard.csv and
    readings_matrix.csv all say "not a verdict" (readings.csv was judged at full strength)."""
    from omegaconf import OmegaConf

    from pipeline.studies.sections import Context

    summary = AGG["readings_fig4"]["summary"].assign(final_abs_error_mean=0.02,
                                                     final_rel_error_mean=0.02)
    agg = dict(AGG["readings_fig4"], summary=summary,
               models=dict(paper=dict(claims=True, study="readings")))
    cfg = OmegaConf.create(dict(report=dict(scale="smoke", dpi=30)))
    readings.section(Context(cfg, tmp_path, "t", {"readings": {"readings_fig4": agg}}))
    for name in ("readings.csv", "readings_scorecard.csv"):
        assert set(pd.read_csv(tmp_path / name)["verdict"]) == {sc.NOT_A_VERDICT}, name
    m = pd.read_csv(tmp_path / "readings_matrix.csv", dtype=str)
    assert set(m[[c for c in m if c.startswith("fig4 ") and c != "fig4 n"]].stack()) == {
        sc.NOT_A_VERDICT}
