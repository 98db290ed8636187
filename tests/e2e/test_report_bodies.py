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
# the URDF bodies: their postures are drawn through the general chain (Body.frame_points)
COMBOS += [("icub_urdf", "proximal_first"), ("ergo_jr", "proportional")]


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


@pytest.mark.parametrize("name", ["ergo_jr", "icub_urdf", "icub"])
def test_the_drawn_links_end_at_the_hand_and_have_the_segments_lengths(name):
    """The posture figures' points: base to hand, the last one Body.forward's hand, consecutive
    points a grown segment's length apart (DH rows and URDF chains alike)."""
    import numpy as np

    import gbmodel
    body = gbmodel.make_body(name)
    q = body.saturate(body.home + 0.2)
    growth = gbmodel.Growth(pattern="proximal_first", start_size=0.5, period=10)
    points = body.frame_points(q, growth.scales(body, 0.7))
    assert points.shape == (body.m + 1, 3)
    np.testing.assert_allclose(points[-1][list(body.outputs)],
                               body.forward(q, growth.scales(body, 0.7)), atol=1e-15)
    if body.general:  # a DH row's frames need not lie a segment apart (a d along z)
        np.testing.assert_allclose(np.linalg.norm(np.diff(points, axis=0), axis=1),
                                   body.segment_lengths * growth.scales(body, 0.7), atol=1e-15)
