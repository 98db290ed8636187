"""Named values: every number the pages quote from the report is a value a report section named
where it computed it (values.csv), and every committed page is its template rendered with them
(pipeline/studies/values.py, pipeline/tools/render.py)."""
import re
from pathlib import Path

import pandas as pd
import pytest

from pipeline.config import REPO_ROOT
from pipeline.studies import sections, values
from pipeline.tools import firsthour, render

REPORT = REPO_ROOT / "outputs" / "report"
PAGES = [REPO_ROOT / "README.md", *sorted((REPO_ROOT / "docs").glob("*.md"))]
NAMES = set(values.read(REPORT / values.FILE))  # the committed report's


# ---- the repository's pages --------------------------------------------------------------------
def test_every_committed_page_equals_its_rendering():
    pages = render.rendered(REPO_ROOT)
    assert {str(p) for p in pages} >= {"README.md", "docs/choices.md", "docs/scorecard.md"}
    assert render.differing(REPO_ROOT, pages) == [], \
        "edit docs/templates/, then run python -m pipeline.tools.render (make docs)"


def test_every_committed_value_is_named_by_the_code_that_computes_it():
    """values.csv's names are the literal names the sections (and the report stage) give, so a
    regenerated report holds the same names: each appears in their code as a string."""
    code = "".join(p.read_text() for p in [*(REPO_ROOT / "pipeline" / "studies").glob("*.py"),
                                           REPO_ROOT / "pipeline" / "report.py"])
    assert {n for n in NAMES if f'"{n}"' not in code and f"'{n}'" not in code} == set()


def test_every_reference_is_a_name_and_every_name_is_referenced():
    sources = [*(REPO_ROOT / render.TEMPLATES).rglob("*.md"),
               REPO_ROOT / "pipeline" / "studies" / "findings.md"]
    used = set().union(*(values.references(p.read_text()) for p in sources))
    measured = set(firsthour.values(REPO_ROOT / firsthour.OUT))  # make first-hour's times
    assert measured and used - NAMES - measured == set()
    assert NAMES - used == set(), "a name no page quotes: stop naming it in its section"


def test_no_page_holds_a_quote_marker_or_an_unrendered_reference():
    marker = re.compile(r"<!--\s*q:|readings-table:begin|coverage table: pipeline")
    for p in PAGES + [REPO_ROOT / "pipeline" / "studies" / "findings.md",
                      *(REPO_ROOT / render.TEMPLATES).rglob("*.md")]:
        assert not marker.search(p.read_text()), p
    names = NAMES
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


# ---- naming -----------------------------------------------------------------------------------
def _ctx(tmp_path):
    return sections.Context(cfg=None, out=Path(tmp_path), title="t", groups={})


def test_a_section_names_a_tables_number_as_the_table_prints_it(tmp_path):
    ctx = _ctx(tmp_path)
    t = pd.DataFrame(dict(figure=["fig4", "fig4"], condition=["const0.5", "const1.0"],
                          final=[0.012395123, 0.0179]))
    ctx.quote(t, ("figure", "condition"), {"a.mm": ("fig4", "const0.5", "final", 1e3),
                                           "b": ("fig4", "const1.0", "final"),
                                           "c": ("fig5", "const1.0", "final")})
    assert ctx.values == {"a.mm": float("0.0123951") * 1e3, "b": 0.0179}  # no fig5: no c
    ctx.value("t", "| x |")
    assert values.read(_written(tmp_path, ctx.values)) == ctx.values


@pytest.mark.parametrize("name, says", [("a.mm", "named twice"), ("a b", "a name is")])
def test_a_bad_name_is_an_error(tmp_path, name, says):
    ctx = _ctx(tmp_path)
    ctx.value("a.mm", 2.0)
    with pytest.raises(ValueError, match=says):
        ctx.value(name, 1.0)


def test_a_number_that_is_not_finite_names_nothing(tmp_path):
    """A run of one trial has no interval: its bounds are not named (the pages need the
    report of the full runs)."""
    ctx = _ctx(tmp_path)
    ctx.value("n", float("nan"))
    ctx.quote(pd.DataFrame(dict(figure=["fig4"], low=[float("nan")])), ("figure",),
              {"low": ("fig4", "low", 100)})
    assert ctx.values == {}


def test_a_quoted_row_that_is_not_one_row_is_an_error(tmp_path):
    t = pd.DataFrame(dict(figure=["fig4", "fig4"], v=[1.0, 2.0]))
    with pytest.raises(ValueError, match="2 rows"):
        _ctx(tmp_path).quote(t, ("figure",), {"x": ("fig4", "v")})


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


def test_the_headlines_are_the_reports_own():
    """headline.default and headline.recommended (README's two headlines) are the words of the
    committed report's scorecard, judged again from its measures.parquet by the same code
    (pipeline.tools.rescore)."""
    from pipeline.studies import scorecard
    from pipeline.tools import rescore

    text = (REPORT / "report.md").read_text()
    vals = values.read(REPORT / values.FILE)
    assert f"each under its primary reading: **{vals['headline.default']}**" in text
    assert f": **{vals['headline.recommended']}**." in text
    again = rescore.rescore(REPORT, rescore.claims.REGISTER)
    assert scorecard.headline_text(again["default"]) == vals["headline.default"]
    assert scorecard.headline_text(again["recommended"]) == vals["headline.recommended"]
