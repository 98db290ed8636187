"""A report of one's own figure: what made it, no paper boilerplate, and one figure's report
never removes another's."""
from pathlib import Path

from pipeline import aggregate, report, simulate


def test_two_figures_reports_one_after_the_other_are_both_found(tmp_path, compose_tiny):
    cfgs = {name: compose_tiny(tmp_path, f"figure={name}", "growth=none", *extra)
            for name, extra in (("vsweep", ["learner.radius=0.15"]), ("grid", []))}
    for name, cfg in cfgs.items():
        simulate.simulate(cfg)
        aggregate.aggregate(cfg, True)
    for name, cfg in cfgs.items():
        report.report(cfg, explicit=True)
    root = Path(cfgs["grid"].paths.report)
    for name in cfgs:
        text = (root / name / "report.md").read_text()
        assert (root / name / f"{name}_curves.png").stat().st_size > 0
        assert all((root / name / f).exists() for f in report.listed_files(root / name / "report.md"))
        assert "make reproduce" not in text and "Discussion" not in text
    own = (root / "vsweep" / "report.md").read_text()
    assert "learner.radius=0.15" in own  # the setting that made it, per condition
    assert "learner.radius" not in (root / "grid" / "report.md").read_text()


def test_a_toy_study_joins_the_report_through_the_registry(tmp_path, compose_tiny, monkeypatch):
    import pytest

    from pipeline.studies import sections

    monkeypatch.setattr(sections, "SECTIONS", dict(sections.SECTIONS))
    sections._load()

    @sections.register("toy", 99)
    def toy(ctx):
        figs = ctx.of("toy")
        if not figs:
            return []
        ctx.text("toy.csv", "figure\n" + "\n".join(figs) + "\n")
        return ["## A toy study", "", f"{len(figs)} figure(s): {', '.join(figs)}", ""]

    cfg = compose_tiny(tmp_path, "figure=toyfig", "growth=none", "paper.study=toy")
    simulate.simulate(cfg)
    aggregate.aggregate(cfg)
    report.report(cfg)
    out = Path(cfg.paths.report)
    text = (out / "report.md").read_text()
    assert "## A toy study" in text and "1 figure(s): toyfig" in text
    assert "toy.csv" in report.listed_files(out / "report.md")
    # the named values of the tables it holds (pipeline/studies/values.py): no paper figure, no
    # readings study here, so none of their names; the coverage table it reads
    from pipeline.studies import values
    assert values.FILE in report.listed_files(out / "report.md")
    held = values.read(out / values.FILE)
    assert "coverage.table" in held and "readings.table" not in held
    assert set(held) == {"coverage.table"}  # no section of this report names a number
    assert "toyfig_curves.png" not in report.listed_files(out / "report.md")  # not a figure
    del sections.SECTIONS["toy"]
    with pytest.raises(ValueError, match="paper.study='toy' names no report section"):
        sections.group(report.load_aggregates(cfg.paths.aggregate))


def test_a_narrower_report_into_the_same_folder_says_which_files_it_drops(tmp_path, compose_tiny,
                                                                           caplog):
    import logging

    cfgs = [compose_tiny(tmp_path, "figure=wide", "growth=none"),
            compose_tiny(tmp_path, "figure=narrow", "growth=none", "learner.radius=0.15")]
    for cfg in cfgs:
        simulate.simulate(cfg)
        aggregate.aggregate(cfg)
    report.report(cfgs[1])  # every aggregated figure: wide and narrow
    assert "wide_curves.png" in report.listed_files(Path(cfgs[1].paths.report) / "report.md")
    (Path(cfgs[0].paths.aggregate) / "wide").unlink()  # a later run without the wide figure
    caplog.clear()
    with caplog.at_level(logging.WARNING, logger=report.log.name):
        report.report(cfgs[1])
    lost = [r.getMessage() for r in caplog.records if "are not in this one" in r.getMessage()]
    assert lost and "wide_curves.png" in lost[0], caplog.text


def test_a_plain_report_after_two_figure_reports_leaves_both(tmp_path, compose_tiny):
    """`report figure=A`, `report figure=B`, then a plain report with other settings
    (report.dpi=100): outputs/latest/A/ and B/ are still there, whole, beside it."""
    cfgs = {name: compose_tiny(tmp_path, f"figure={name}", "growth=none")
            for name in ("fig_a", "fig_b")}
    for cfg in cfgs.values():
        simulate.simulate(cfg)
        aggregate.aggregate(cfg, True)
        report.report(cfg, explicit=True)
    root = Path(cfgs["fig_a"].paths.report)
    before = {n: (root / n / "report.md").read_text() for n in cfgs}
    plain = compose_tiny(tmp_path, "report.dpi=100")
    assert report.report(plain)  # every aggregated figure, into root itself
    assert {"fig_a_curves.png", "fig_b_curves.png"} <= set(report.listed_files(root / "report.md"))
    for name in cfgs:
        assert (root / name / "report.md").read_text() == before[name]
        assert all((root / name / f).is_file()
                   for f in report.listed_files(root / name / "report.md"))
        assert report.report(cfgs[name], explicit=True) == []  # still up to date: its record kept
    assert report.report(plain) == []


def test_an_edited_register_of_criteria_makes_the_report_again(tmp_path, compose_tiny,
                                                               monkeypatch):
    """register.yaml holds the criteria the report's verdicts come from: a report made before a
    criterion changed is not up to date (it was: the report's code digest read the studies'
    .py, .md and .csv files, not the register)."""
    cfg = compose_tiny(tmp_path)
    before = report.inputs_digest(cfg, {"fig": "its aggregate"})
    read = Path.read_bytes

    def edited(self):
        data = read(self)
        return data.replace(b"factor: 1.5", b"factor: 2.0") if self.name == "register.yaml" \
            else data
    monkeypatch.setattr(Path, "read_bytes", edited)
    assert report.inputs_digest(cfg, {"fig": "its aggregate"}) != before


def test_the_report_follows_what_the_experiment_files_declare(tmp_path, compose_tiny,
                                                              monkeypatch):
    """report.paper_experiments is ${experiments:} (each file's declares.group): a declaration
    changed makes the report again (the digest held the interpolation's text, unresolved)."""
    import importlib

    composing = importlib.import_module("pipeline.config.compose")  # the module, not its function
    cfg = compose_tiny(tmp_path)
    before = report.inputs_digest(cfg, {"fig": "its aggregate"})
    monkeypatch.setattr(composing, "listed", lambda folders, *groups: ["fig4"])
    assert report.inputs_digest(cfg, {"fig": "its aggregate"}) != before
