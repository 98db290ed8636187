"""models.load by a figure's name finds the results of every profile (the full one's aggregate,
then make smoke's outputs/smoke/aggregate, then a report's models/), or says in one line where it
looked and which figures those folders hold."""
import pytest

import pipeline.config
from pipeline import models


@pytest.fixture
def root(tmp_path, monkeypatch):
    """paths.root is tmp_path, as an installed package's working directory."""
    monkeypatch.setattr(pipeline.config, "default_root", lambda: str(tmp_path))
    return tmp_path / "outputs"


def _put(path):
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text("{}")
    return path


def test_a_smoke_result_is_found_by_name(root):
    smoke = _put(root / "smoke" / "aggregate" / "fig4" / "models.json")
    assert models.locate("fig4") == smoke


def test_the_full_profile_comes_first_then_smoke_then_the_report(root):
    report = _put(root / "report" / "models" / "fig4.json")
    assert models.locate("fig4") == report
    smoke = _put(root / "smoke" / "aggregate" / "fig4" / "models.json")
    assert models.locate("fig4") == smoke
    full = _put(root / "aggregate" / "fig4" / "models.json")
    assert models.locate("fig4") == full


def test_a_missing_figure_says_where_it_looked_and_what_exists(root):
    _put(root / "smoke" / "aggregate" / "fig4" / "models.json")
    _put(root / "report" / "models" / "fig2.json")
    with pytest.raises(FileNotFoundError) as e:
        models.locate("vsweep")
    msg = str(e.value)
    assert "\n" not in msg and msg.startswith("vsweep: no models under ")
    for where in ("outputs/aggregate", "outputs/smoke/aggregate", "outputs/report"):
        assert where in msg
    assert "they hold: fig2, fig4;" in msg


def test_a_given_folder_is_the_only_one_searched(root):
    _put(root / "smoke" / "aggregate" / "fig4" / "models.json")
    with pytest.raises(FileNotFoundError, match=r"they hold: none;"):
        models.locate("fig4", root / "aggregate")
