"""Reports of one's own experiments: every body and growth pattern goes through simulate,
aggregate and report at a tiny scale, gets its curves, summary and posture panels, and a title
that names it; the paper's claims appear only on experiments that declare them."""
import itertools

import pandas as pd
import pytest

from pipeline import aggregate, report, simulate

BODIES = ("arm2", "arm5", "icub")
GROWTHS = ("proportional", "nonproportional", "proximal_first", "none")
# every pairing the config accepts: every segment of arm2 and of the iCub grows, so their
# nonproportional growth is refused when the config is composed (it would equal proportional)
COMBOS = [(b, g) for b, g in itertools.product(BODIES, GROWTHS)
          if (b, g) not in {("arm2", "nonproportional"), ("icub", "nonproportional")}]


@pytest.fixture(scope="module")
def tree(tmp_path_factory):
    from pipeline.config import compose
    root = tmp_path_factory.mktemp("bodies")
    cfg = None
    for body, growth in COMBOS:
        cfg = compose(["learner.epochs=20", "trials.count=1", "workers=1", f"paths.root={root}",
                       f"body={body}", f"growth={growth}", f"figure={body}_{growth}",
                       "report.explain=false"]
                      + ([] if growth == "none" else ["growth.period=10"]))
        simulate.simulate(cfg)
    aggregate.aggregate(cfg)
    report.report(cfg)
    return cfg


@pytest.mark.parametrize("body,growth", COMBOS)
def test_every_body_and_growth_pattern_is_reported(tree, body, growth):
    from pathlib import Path
    out = Path(tree.paths.report)
    name = f"{body}_{growth}"
    assert (out / f"{name}_curves.png").stat().st_size > 0
    assert (out / f"{name}_postures.png").stat().st_size > 0
    summary = pd.read_csv(out / "summary.csv")
    row = summary[summary["figure"] == name]
    assert len(row) == 1 and row["body"].iloc[0] == body
    text = (out / "report.md").read_text()
    assert f"![{name}]({name}_curves.png)" in text and f"({name}_postures.png)" in text


def test_a_custom_report_is_titled_by_its_experiments_without_the_papers_verdicts(tree):
    from pathlib import Path
    out = Path(tree.paths.report)
    text = (out / "report.md").read_text()
    first = text.splitlines()[0]
    assert first.startswith("# Experiment ") and "arm2_none" in first
    assert "Reproduction" not in text and "claims" not in first
    assert "Scorecard" not in text and not (out / "claims.csv").exists()
    assert not (out / "scorecard.png").exists()
