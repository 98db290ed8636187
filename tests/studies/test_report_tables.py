"""Every Markdown table of a report keeps its header's cells in every row, even where a
sweep's condition labels carry a `|` (`R=0.1 | TG10`: a sweep over the radius and the growth
period): the cells are escaped where the tables are written."""
import re
from pathlib import Path

import pytest

from pipeline import aggregate, report, simulate

_CELL_BORDER = re.compile(r"(?<!\\)\|")  # a pipe that is not escaped ends a cell


def cells(row: str) -> int:
    return len(_CELL_BORDER.split(row.strip().strip("|")))


def tables(text: str) -> list[list[str]]:
    """Each Markdown table of `text`: its consecutive lines that start with a pipe."""
    out, current = [], []
    for line in text.splitlines() + [""]:
        if line.startswith("|"):
            current.append(line)
        elif current:
            out.append(current)
            current = []
    return out


@pytest.fixture(scope="module")
def sweep_report(tmp_path_factory):
    """A sweep over growth.period and learner.radius (4 jobs of one multirun group), its
    aggregate and its report (figure=rgrid)."""
    from conftest import tiny_overrides
    from pipeline.config import compose

    root = tmp_path_factory.mktemp("tables")
    combos = [(r, p) for r in (0.1, 0.2) for p in (10, 20)]
    for job, (r, p) in enumerate(combos):
        cfg = compose(tiny_overrides(root, "figure=rgrid", f"learner.radius={r}",
                                     f"growth.period={p}", "report.animate=false"))
        summary = simulate.simulate(cfg, group="sweep-tables", job=job)
        assert not summary.failed
    assert aggregate.aggregate(cfg, True) == []
    report.report(cfg, explicit=True)
    return Path(cfg.paths.report) / "rgrid"


def test_the_sweep_labels_carry_a_pipe(sweep_report):
    text = (sweep_report / "summary.csv").read_text()
    assert "R=0.1 | TG10" in text and "R=0.2 | TG20" in text


@pytest.mark.parametrize("name", ["report.md", "summary.md"])
def test_every_row_has_its_headers_cells(sweep_report, name):
    found = tables((sweep_report / name).read_text())
    assert found, name
    rows = 0
    for table in found:
        width = cells(table[0])
        for row in table[1:]:
            assert cells(row) == width, f"{name}: {row!r} against {table[0]!r}"
            rows += 1
    assert rows >= 4  # the four conditions at least


def test_the_summary_shows_the_held_out_error_in_mm_and_in_percent_of_the_reach(sweep_report):
    import pandas as pd

    summary = pd.read_csv(sweep_report / "summary.csv")
    assert (summary["reach"].between(0.9, 1.0)).all()  # arm5: 1 m of links, sampled
    pct = 100 * summary["final_heldout_abs_error_mean"] / summary["reach"]
    assert ((summary["final_heldout_abs_error_pct_reach"] - pct).abs() <= 1e-5 * pct).all()  # %.6g
    text = (sweep_report / "summary.md").read_text()
    assert "| held-out error [mm] (% of reach) |" in text
    first = summary.iloc[0]  # one trial per condition: no std, the mean and its % of the reach
    assert (f"| {1e3 * first['final_heldout_abs_error_mean']:.1f} "
            f"({first['final_heldout_abs_error_pct_reach']:.2f} %) |") in text
