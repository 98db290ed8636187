"""Quote markers: every number of the prose that comes from a report table is checked against it."""
import pytest

from pipeline.config import REPO_ROOT
from pipeline.tools import quotes

SUMMARY = ("figure,condition,final_abs_error_mean,measured\n"
           "fig4,const0.5,0.0123951,\"mean 4.9 mm, worst +16.5 mm, 10,000 epochs\"\n"
           "fig4,const1.0,0.0179,\"\"\n"
           "fig5,const1.0,0.0179,\"\"\n")
Q = "summary.csv figure=fig4 condition=const0.5"


@pytest.fixture
def root(tmp_path):
    (tmp_path / "outputs" / "report").mkdir(parents=True)
    (tmp_path / "outputs" / "report" / "summary.csv").write_text(SUMMARY)
    return tmp_path


def _page(root, text, name="page.md"):
    p = root / name
    p.write_text(text)
    return p


def _check(root, text, **kw):
    return quotes.check([_page(root, text)], root=root, blocks=[], unscanned={}, **kw)


def test_a_quoted_number_that_matches_its_cell_at_its_own_decimals_passes(root):
    assert _check(root, f"ends at 12.4 mm<!-- q: {Q} final_abs_error_mean*1e3 --> here.\n"
                        f"or 12.40 mm<!-- q: {Q} final_abs_error_mean*1e3 -->, 12 mm"
                        f"<!-- q: {Q} final_abs_error_mean*1e3 -->\n") == []


def test_a_drifted_number_is_named_with_page_line_and_the_tables_value(root):
    out = _check(root, f"line one\nends at 10.7 mm<!-- q: {Q} final_abs_error_mean*1e3 -->\n")
    assert out == ["page.md:2: quoted 10.7, summary.csv gives 12.4"]


def test_fix_rewrites_each_drifted_number_at_its_precision_and_nothing_else(root):
    text = (f"a 10.7<!-- q: not data: the old run --> -> 1.0 mm<!-- q: {Q} final_abs_error_mean*1e3 --> and 0.5<!-- q: {Q} "
            f"final_abs_error_mean / summary.csv figure=fig4 condition=const1.0 "
            "final_abs_error_mean -->x\n")
    _check(root, text, fix=True)
    fixed = (root / "page.md").read_text()
    assert fixed == text.replace("1.0 mm", "12.4 mm").replace("0.5<", "0.7<")
    assert _check(root, fixed) == []


def test_a_number_of_a_text_cell_is_picked_by_its_position_with_sign_and_commas(root):
    m = f"<!-- q: {Q} measured#{{}} -->"
    assert _check(root, f"worst +16.5 mm{m.format(2)} after 10,000{m.format(3)} epochs, "
                        f"mean 4.9 mm{m.format(1)}\n") == []
    assert _check(root, f"worst 16.4 mm{m.format(2)}\n") == [
        "page.md:1: quoted 16.4, summary.csv gives 16.5"]


def test_a_filter_by_substring_selects_a_row(root):
    assert _check(root, "12.4 mm<!-- q: summary.csv measured~\"worst +16\" "
                        "final_abs_error_mean*1e3 -->\n") == []


@pytest.mark.parametrize("marker, why", [
    ("summary.csv figure=fig9 final_abs_error_mean", "selects 0 rows"),
    ("summary.csv condition=const1.0 final_abs_error_mean", "selects 2 rows"),
    ("summary.csv figure=fig4 condition=const0.5 nosuch", "no column 'nosuch'"),
    ("summary.csv figure=fig4 condition=const0.5 measured", "is not a number"),
    ("summary.csv figure=fig4 condition=const0.5 measured#7", "holds 3 numbers, not #7"),
    ("nosuch.csv figure=fig4 x", "no such table"),
    ("figure=fig4 final_abs_error_mean", "starts with its table"),
    ("not data:", "says why"),
])
def test_a_marker_that_names_no_single_cell_is_an_error(root, marker, why):
    with pytest.raises(quotes.BadMarker, match=why):
        _check(root, f"text\n1.0 mm<!-- q: {marker} -->\n")


def test_a_bad_marker_stops_fix_before_it_writes_anything(root):
    text = (f"10.7 mm<!-- q: {Q} final_abs_error_mean*1e3 -->\n"
            "1.0 mm<!-- q: summary.csv figure=fig9 final_abs_error_mean -->\n")
    with pytest.raises(quotes.BadMarker, match=r"page.md:2: summary.csv: .* selects 0 rows"):
        _check(root, text, fix=True)
    assert (root / "page.md").read_text() == text


def test_the_scanner_names_every_unmarked_number_with_an_error_like_unit(root):
    text = ("ends at 12.4 mm, or 1.24x, within x1.5, +28 %, 17.1-17.9 mm and 12.4 / 12.9 mm;\n"
            "not these: 4 epochs, 1 x 1/W, `12 mm` in code\n"
            "```\n13 mm in a code block\n```\n")
    assert [(i, n) for i, n in quotes.unmarked("p", text, blocks=[])] == sorted({
        (1, "12.4"), (1, "1.24"), (1, "1.5"), (1, "+28"), (1, "17.1"), (1, "17.9"), (1, "12.9")})
    out = _check(root, text)
    assert out[0] == ("page.md:1: +28 has no quote marker (<!-- q: ... --> or "
                      "<!-- q: not data: why -->)") and len(out) == 7


def test_marked_and_exempted_numbers_are_complete_and_an_exemption_is_not_checked(root):
    m = f"<!-- q: {Q} final_abs_error_mean*1e3 -->"
    text = (f"12.4{m} / 12.4 mm{m}; the paper's 20 mm<!-- q: not data: the paper's text -->\n"
            "within x1.5<!-- q: not data: a criterion -->, 2 cm, 3 %<!-- q: not data on this "
            "line: settings -->\n")
    assert _check(root, text) == []


def test_a_generated_block_is_not_scanned(root):
    text = "<!-- begin -->\n| 93 % |\n<!-- end -->\n94 %\n"
    assert quotes.unmarked("p", text, blocks=[("<!-- begin -->", "<!-- end -->")]) == [(4, "94")]


def test_the_command_exits_1_on_a_drift_and_2_on_a_bad_marker(root, monkeypatch, capsys):
    monkeypatch.setattr(quotes, "REPO_ROOT", root)
    good = _page(root, f"12.4 mm<!-- q: {Q} final_abs_error_mean*1e3 -->\n", "good.md")
    bad = _page(root, f"12.5 mm<!-- q: {Q} final_abs_error_mean*1e3 -->\n", "bad.md")
    broken = _page(root, "12.5 mm<!-- q: summary.csv final_abs_error_mean -->\n", "broken.md")
    assert quotes.main([str(good)]) == 0
    assert quotes.main([str(bad)]) == 1
    assert "bad.md:1: quoted 12.5, summary.csv gives 12.4" in capsys.readouterr().out
    assert quotes.main([str(broken)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: broken.md:1: summary.csv:") and err.count("\n") == 1
    assert quotes.main(["--fix", str(bad)]) == 0
    assert bad.read_text().startswith("12.4 mm")
    assert quotes.main([str(root / "nosuch.md")]) == 2


def test_every_number_of_the_repositorys_pages_is_its_tables_and_every_one_is_marked():
    problems = quotes.check(quotes.pages())
    assert problems == [], "\n".join(problems)


def test_the_pages_left_unscanned_exist():
    for page in quotes.UNSCANNED_PAGES:
        assert (REPO_ROOT / page).is_file(), page


def test_a_page_on_the_unscanned_lists_is_scanned_when_named(root, monkeypatch, capsys):
    monkeypatch.setattr(quotes, "REPO_ROOT", root)
    monkeypatch.setattr(quotes, "UNSCANNED_PAGES", {"docs/readings.md": "being rewritten"})
    (root / "docs").mkdir()
    page = _page(root, "ends at 12.4 mm\n", "docs/readings.md")
    assert quotes.check([page], root=root, blocks=[]) == []
    assert quotes.main([str(page)]) == 1
    assert "docs/readings.md:1: 12.4 has no quote marker" in capsys.readouterr().out


def test_the_generated_blocks_are_the_coverage_and_readings_tables_markers():
    from pipeline.studies import coverage, readings
    from pipeline.tools import quotes

    assert quotes.generated_blocks() == [(coverage.BEGIN, coverage.END),
                                         (readings.BEGIN, readings.END)]
