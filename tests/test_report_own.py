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
