"""The README a newcomer reads: no line over 100 characters, the glossary linked from its first
screen with every symbol and term it uses, the two headlines' totals explained with the counts
the committed report gives, where each profile writes, and its first-hour times from the
measurement (outputs/bench/first_hour.json, written by make first-hour)."""
import json
import re

from pipeline.config import REPO_ROOT
from pipeline.studies import values
from pipeline.tools import firsthour

README = (REPO_ROOT / "README.md").read_text()
GLOSSARY = (REPO_ROOT / "docs" / "glossary.md").read_text()
FLAT = re.sub(r"\s+", " ", README)  # the prose, its line breaks as spaces


def test_no_readme_line_is_over_100_characters():
    assert [ln for ln in README.splitlines() if len(ln) > 100] == []


def test_the_glossary_is_linked_from_the_first_screen_and_defines_every_term():
    assert "](docs/glossary.md)" in "\n".join(README.splitlines()[:25])
    rows = {m.strip() for m in re.findall(r"^\| ([^|]+) \|", GLOSSARY, re.M)}
    for term in ("V", "R", "K", "L", "T_G", "M", "g(x)", "epoch", "lstsq", "reading", "claim",
                 "reach", "held-out error", "profile", "diagnostic"):
        assert any(term == r or term in r.split(", ") for r in rows), term
    assert "eta, W, 1 / W" in rows
    assert "](docs/readings.md#the-matrix)" in README and "| eta = 0.1 / W |" not in README


def test_the_two_headlines_totals_are_the_cells_they_count():
    vals = values.read(REPO_ROOT / "outputs" / "report" / values.FILE)
    totals = [sum(int(n) for n in re.findall(r"\d+", vals[f"headline.{k}"]))
              for k in ("default", "recommended")]
    assert f"The default, {totals[0]} cells," in FLAT
    assert f"the recommended, {totals[1]} cells," in FLAT
    assert f"default headline counts {totals[0]} cells and the recommended one {totals[1]}" in \
        re.sub(r"\s+", " ", GLOSSARY)


def test_the_readme_says_where_each_profile_writes():
    for where in ("outputs/aggregate/", "outputs/latest/", "outputs/smoke/", "outputs/report/"):
        assert where in FLAT, where


def test_the_first_hour_times_are_the_measured_ones():
    doc = json.loads((REPO_ROOT / firsthour.OUT).read_text())
    assert doc["setup"]["rc"] == doc["smoke"]["rc"] == 0
    counts = firsthour.values(REPO_ROOT / firsthour.OUT)["first_hour.test.counts"]
    assert counts.startswith(f"{doc['test']['passed']:,} passed, ") and f"; {counts} (" in FLAT
    assert counts.endswith(f", {doc['test']['skipped']:,} skipped")
    assert f"`make smoke`: {doc['smoke']['trials']:,} short trials" in FLAT
    assert f"{doc['test']['cpu_min']:.0f} CPU-min, {doc['test']['wall_min']:.0f} min wall" in FLAT
    assert f"{doc['smoke']['cpu_min']:.1f} CPU-min" in FLAT and doc["commit"] in FLAT
    assert set(firsthour.values(REPO_ROOT / firsthour.OUT)) >= {
        "first_hour.setup.wall_min", "first_hour.test.cpu_min", "first_hour.date"}


def test_the_measurement_reads_pytests_counts_and_names_its_values(tmp_path):
    """make first-hour's pieces: pytest's summary line to counts; the JSON to named values (a
    failed test is said beside the passed ones, never left out)."""
    assert firsthour.pytest_counts("== 3 failed, 1150 passed, 34 skipped, 2 errors in 81.2s ==") \
        == {"failed": 3, "passed": 1150, "skipped": 34, "error": 2}
    assert firsthour.pytest_counts("FAILED tests/a.py::t - x\n= 1 failed, 2 passed in 1s =") == {
        "failed": 1, "passed": 2, "failures": ["tests/a.py::t"]}
    assert firsthour.pytest_counts("no summary") == {}
    doc = dict(commit="abc1234", machine=dict(cores=2, load_average=[3.5, 2, 1],
                                              date="2026-12-07 00:10 UTC"),
               setup=dict(wall_min=4.3, rc=0), smoke=dict(cpu_min=1.9, trials=921, rc=0),
               test=dict(wall_min=14.0, passed=1156, failed=1, skipped=34, rc=1,
                         failures=["tests/a.py::t"]))
    (tmp_path / "f.json").write_text(json.dumps(doc))
    got = firsthour.values(tmp_path / "f.json")
    assert got["first_hour.test.counts"] == "1,156 passed, 1 failed, 34 skipped"
    assert got["first_hour.test.failures"] == "`tests/a.py::t`"
    assert got["first_hour.smoke.trials"] == 921.0 and got["first_hour.machine.load_1min"] == 3.5
    assert got["first_hour.date"] == "2026-12-07" and got["first_hour.commit"] == "abc1234"
    assert firsthour.values(tmp_path / "none.json") == {}
