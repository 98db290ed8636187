"""Named values: every number the pages quote from the report is a named value of values.csv, and
every committed page is its template rendered with them (pipeline/studies/values.py,
pipeline/tools/render.py)."""
import re

import pytest

from pipeline.config import REPO_ROOT
from pipeline.studies import values
from pipeline.tools import firsthour, render

SUMMARY = ("figure,condition,final_abs_error_mean,measured\n"
           "fig4,const0.5,0.0123951,\"mean 4.9 mm, worst +16.5 mm, 10,000 epochs\"\n"
           "fig4,const1.0,0.0179,\"\"\n"
           "fig5,const1.0,0.0179,\"\"\n")
Q = "summary.csv figure=fig4 condition=const0.5"
REPORT = REPO_ROOT / "outputs" / "report"
PAGES = [REPO_ROOT / "README.md", *sorted((REPO_ROOT / "docs").glob("*.md"))]


@pytest.fixture
def report(tmp_path):
    (tmp_path / "summary.csv").write_text(SUMMARY)
    return tmp_path


# ---- the repository's pages --------------------------------------------------------------------
def test_every_committed_page_equals_its_rendering():
    pages = render.rendered(REPO_ROOT)
    assert {str(p) for p in pages} >= {"README.md", "docs/choices.md", "docs/scorecard.md"}
    assert render.differing(REPO_ROOT, pages) == [], \
        "edit docs/templates/, then run python -m pipeline.tools.render (make docs)"


def test_the_committed_values_are_the_registry_evaluated_over_the_committed_report():
    """values.csv is what the report stage writes: every name of values.yaml and every generated
    table, each the value its cell holds in the committed tables (the coverage table: the
    committed pipeline/studies/coverage.csv, the readings table: readings_matrix.csv)."""
    got, missing = values.evaluate(REPORT)
    assert missing == {}
    assert values.read(REPORT / values.FILE) == got
    assert set(got) == set(values.registry()) | set(values.TABLES)


def test_every_reference_is_a_name_and_every_name_is_referenced():
    sources = [*(REPO_ROOT / render.TEMPLATES).rglob("*.md"),
               REPO_ROOT / "pipeline" / "studies" / "findings.md"]
    used = set().union(*(values.references(p.read_text()) for p in sources))
    names = set(values.registry()) | set(values.TABLES)
    measured = set(firsthour.values(REPO_ROOT / firsthour.OUT))  # make first-hour's times
    assert measured and used - names - measured == set()
    assert names - used == set(), "a name no page quotes: remove it from values.yaml"


def test_no_page_holds_a_quote_marker_or_an_unrendered_reference():
    marker = re.compile(r"<!--\s*q:|readings-table:begin|coverage table: pipeline")
    for p in PAGES + [REPO_ROOT / "pipeline" / "studies" / "findings.md",
                      *(REPO_ROOT / render.TEMPLATES).rglob("*.md")]:
        assert not marker.search(p.read_text()), p
    names = set(values.registry()) | set(values.TABLES)
    plain = [p for p in PAGES if not (REPO_ROOT / render.TEMPLATES / p.relative_to(REPO_ROOT))
             .exists()]  # a page without a template may show the syntax, never quote a value so
    assert REPO_ROOT / "docs" / "core.md" in plain
    for p in plain:
        assert not names & values.references(p.read_text()), p


# ---- formats and references --------------------------------------------------------------------
@pytest.mark.parametrize("x, fmt, want", [
    (12.3951, ".1f", "12.4"), (74.5, ".0f", "75"), (0.125, ".2f", "0.13"), (-0.04, ".1f", "0.0"),
    (28.2, "+.0f", "+28"), (-3.26, "+.1f", "-3.3"), (10000.0, ",.0f", "10,000"),
    (0.0, "+.0f", "+0"),
])
def test_a_number_is_written_in_its_format_rounded_half_away_from_zero(x, fmt, want):
    assert values.formatted(x, fmt) == want


def test_a_page_references_numbers_with_a_format_and_tables_without():
    vals = {"a.mm": 12.3951, "t": "| x |\n|---|"}
    assert values.render("ends at {{ a.mm:.1f }} mm\n{{t}}\n", vals, "p.md") == \
        "ends at 12.4 mm\n| x |\n|---|\n"


@pytest.mark.parametrize("text, says", [
    ("x\n{{ nosuch:.1f }}", "p.md:2: no value named 'nosuch'"),
    ("{{ a.mm }}", "p.md:1: a.mm is a number: give its format"),
    ("{{ t:.1f }}", "p.md:1: t is a table, not a number"),
    ("{{ a.mm:.1 }}", "p.md:1: a.mm: format '.1'"),
    ("{{ a.mm:.30f }}", "at most 15 decimals"),
    ("a {{ a.mm:.1f } b", "p.md:1: a '{{' that opens no reference"),
])
def test_a_bad_reference_is_an_error_naming_page_and_line(text, says):
    with pytest.raises(values.BadValue, match=re.escape(says)):
        values.render(text, {"a.mm": 1.0, "t": "| x |"}, "p.md")


def test_the_reports_discussion_is_left_out_when_it_quotes_a_value_the_report_lacks():
    part = "## Discussion\n\nends at {{ a.mm:.1f }} mm and {{ b:.0f }}\n"
    assert values.rendered_part(part, {"a.mm": 1.25, "b": 3.0}) == \
        "## Discussion\n\nends at 1.3 mm and 3\n"
    note = values.rendered_part(part, {"a.mm": 1.25})
    assert "quotes b, which this report does not hold" in note and "{{" not in note
    assert values.rendered_part("no reference", {}) == "no reference"


# ---- the cells ---------------------------------------------------------------------------------
def test_a_cell_is_read_with_its_filters_position_scale_and_ratio(report):
    assert values.value(f"{Q} final_abs_error_mean*1e3", report) == pytest.approx(12.3951)
    assert [values.value(f"{Q} measured#{k}", report) for k in (1, 2, 3)] == [4.9, 16.5, 10000]
    assert values.value("summary.csv measured~\"worst +16\" final_abs_error_mean",
                        report) == 0.0123951
    assert values.value(f"{Q} final_abs_error_mean / summary.csv figure=fig4 condition=const1.0 "
                        "final_abs_error_mean", report) == pytest.approx(0.0123951 / 0.0179)


@pytest.mark.parametrize("cell, why", [
    ("summary.csv figure=fig9 final_abs_error_mean", "selects 0 rows"),
    ("summary.csv condition=const1.0 final_abs_error_mean", "selects 2 rows"),
    (f"{Q} nosuch", "no column 'nosuch'"),
    (f"{Q} measured", "is not a number"),
    (f"{Q} measured#7", "holds 3 numbers, not #7"),
    ("nosuch.csv figure=fig4 x", "no such table"),
    ("figure=fig4 final_abs_error_mean", "starts with its table"),
])
def test_a_cell_that_names_no_single_number_is_an_error(report, cell, why):
    with pytest.raises(values.BadValue, match=why):
        values.value(cell, report)


def test_a_report_of_fewer_tables_holds_fewer_names(report):
    got, missing = values.evaluate(report, {"a": f"{Q} final_abs_error_mean*1e3",
                                            "b": "choices.csv figure=x v"})
    assert got["a"] == pytest.approx(12.3951) and "b" not in got
    assert "no such table" in missing["b"] and "readings.table" in missing
    assert values.read(_written(report, got)) == got


def _written(folder, vals):
    path = folder / values.FILE
    path.write_text(values.to_csv(vals))
    return path


# ---- the command -------------------------------------------------------------------------------
def _repo(tmp_path, template: str, page: str | None = None):
    (tmp_path / "outputs" / "report").mkdir(parents=True)
    _written(tmp_path / "outputs" / "report", {"a.mm": 12.3951, "t": "| x |"})
    (tmp_path / "docs" / "templates" / "docs").mkdir(parents=True)
    (tmp_path / "docs" / "templates" / "docs" / "p.md").write_text(template)
    if page is not None:
        (tmp_path / "docs" / "p.md").write_text(page)
    return tmp_path


def test_the_command_checks_then_writes_every_page(tmp_path, capsys):
    root = _repo(tmp_path, "ends at {{ a.mm:.1f }} mm\n\n{{ t }}\n", "ends at 10.0 mm\n")
    assert render.main(["--check"], root=root) == 1
    assert capsys.readouterr().out == ("docs/p.md: differs from its rendering of docs/templates/"
                                       "docs/p.md (python -m pipeline.tools.render)\n")
    assert render.main([], root=root) == 0
    assert (root / "docs" / "p.md").read_text() == "ends at 12.4 mm\n\n| x |\n"
    assert render.main(["--check"], root=root) == 0


def test_the_command_writes_nothing_on_a_bad_reference(tmp_path, capsys):
    root = _repo(tmp_path, "ends at {{ a.mm:.1f }} mm\n")
    (root / "docs" / "templates" / "docs" / "q.md").write_text("x\n{{ nosuch:.1f }}\n")
    assert render.main([], root=root) == 2
    err = capsys.readouterr().err
    assert err == "error: docs/templates/docs/q.md:2: no value named 'nosuch'\n"
    assert not (root / "docs" / "p.md").exists()


def test_values_from_tables_refuses_a_report_that_lacks_a_name(tmp_path, capsys):
    root = _repo(tmp_path, "ends at {{ a.mm:.1f }} mm\n", "ends at 10.0 mm\n")
    before = (root / "outputs" / "report" / values.FILE).read_text()
    assert render.main(["--values-from-tables"], root=root) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: ") and "no value for " in err and err.count("\n") == 1
    assert (root / "outputs" / "report" / values.FILE).read_text() == before
    assert (root / "docs" / "p.md").read_text() == "ends at 10.0 mm\n"


def test_the_headlines_are_the_reports_own():
    """headline.default and headline.recommended (README's two headlines) are the words of the
    committed report's scorecard, computed again from its claims.csv, readings.csv and
    measures.parquet."""
    report = REPO_ROOT / "outputs" / "report"
    text = (report / "report.md").read_text()
    vals = values.read(report / values.FILE)
    assert f"this project's default reading: **{vals['headline.default']}**" in text
    assert f": **{vals['headline.recommended']}**." in text
    for name in ("headline.default", "headline.recommended"):
        assert values.TABLES[name](report) == vals[name]
