"""The report never depends on the last bit: the hand-written discussion is kept when the numbers
agree within the stated tolerance (and every verdict is the same), and left out otherwise."""
import numpy as np
import pandas as pd

from pipeline.studies import discussion, paper


def _run():
    summary = pd.DataFrame(dict(figure=["fig4", "fig4"], condition=["TG10", "const1.0"],
                                final_abs_error_mean=[0.0171234567, 0.0175],
                                final_rel_error_mean=[0.0171234567, 0.0175],
                                peak_abs_error_growth=[0.21, np.nan]))
    claim_rows = [dict(figure="fig4", claim="final error about 20.0 mm", verdict="reproduced")]
    return summary, claim_rows


def test_discussion_survives_a_1e7_perturbation_but_not_a_changed_number(tmp_path, monkeypatch):
    monkeypatch.setattr(discussion, "FINDINGS_NUMBERS", tmp_path / "numbers.csv")
    monkeypatch.setattr(discussion, "FINDINGS", tmp_path / "findings.md")
    (tmp_path / "findings.md").write_text("## Why\n\nthe discussion\n")
    summary, claim_rows = _run()
    discussion.stamp_findings(summary, claim_rows)
    assert "the discussion" in discussion.findings(summary, claim_rows)

    nudged = summary.copy()
    cols = ["final_abs_error_mean", "final_rel_error_mean", "peak_abs_error_growth"]
    nudged[cols] = nudged[cols] * (1 + 1e-7)
    assert "the discussion" in discussion.findings(nudged, claim_rows)

    changed = summary.copy()
    changed.loc[0, "final_abs_error_mean"] *= 1.001
    assert "left out" in discussion.findings(changed, claim_rows)
    other_verdict = [dict(claim_rows[0], verdict="not reproduced: TG10")]
    assert "left out" in discussion.findings(summary, other_verdict)
