"""The register of criteria (pipeline/studies/register.yaml): no criterion changes without a
changelog entry, every reading says why and since when."""
import yaml

from pipeline.studies import claims, paper


def test_every_criterion_is_the_one_its_latest_changelog_entry_records():
    assert claims.unlogged() == []


def test_a_criterion_changed_without_a_changelog_entry_is_caught(tmp_path):
    data = yaml.safe_load(claims.REGISTER.read_text())
    final = next(e for e in data["claims"] if e["id"] == "final")
    final["readings"][0]["params"]["factor"] = 2.0  # a looser "about"
    (tmp_path / "r.yaml").write_text(yaml.safe_dump(data))
    assert [p for p in claims.unlogged(tmp_path / "r.yaml") if p.startswith("final:")]
    final["changelog"].append(dict(date="2026-12-04", commit="x", reason="looser", before="a",
                                   after="b", hash=claims.criterion_hash(final)))
    (tmp_path / "r.yaml").write_text(yaml.safe_dump(data))
    assert claims.unlogged(tmp_path / "r.yaml") == []
    # a text (why) may change freely; the primary flag may not
    final["readings"][0]["why"] = "reworded"
    final["readings"][0]["primary"], final["readings"][1]["primary"] = False, True
    (tmp_path / "r.yaml").write_text(yaml.safe_dump(data))
    assert [p for p in claims.unlogged(tmp_path / "r.yaml") if p.startswith("final:")]


def test_the_final_error_is_primary_in_metres_and_per_unit_size_is_a_diagnostic():
    final = claims.BY_ID["final"]
    assert final.primary.params["scale"] == "metres"
    assert (final.primary.params["full"], final.primary.params["smaller"]) == ("two-sided",
                                                                               "at-most")
    per = next(r for r in final.readings if r.params.get("scale") == "size")
    assert per.diagnostic and not per.primary
    assert any(r.params["full"] == "at-most" for r in final.readings)  # "a stable, low level"


def test_the_whole_rise_claim_is_counted():
    assert claims.BY_ID["rise"].primary.params["up_to"] == 1000
    none = claims.BY_ID["rise_none"]
    assert none.primary.params["from"] == 10000 and not none.diagnostic


def test_every_reading_is_listed_with_why_and_when():
    md = paper.readings_markdown()
    for c in claims.CLAIMS:
        for r in c.readings:
            assert r.label in md and r.fixed_at in md
