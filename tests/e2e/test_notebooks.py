"""The notebooks (notebooks/*.py, jupytext's percent format: text in git, no outputs) run from
top to bottom in a Jupyter kernel. Needs the extra [notebooks] (make notebooks installs it);
without it the test skips and says so."""
from pathlib import Path

import pytest

from pipeline.config import REPO_ROOT

NOTEBOOKS = sorted((REPO_ROOT / "notebooks").glob("*.py"))


def test_every_notebook_is_a_jupytext_percent_script_without_outputs():
    assert NOTEBOOKS, "no notebook under notebooks/"
    for path in NOTEBOOKS:
        text = path.read_text()
        assert "formats: py:percent" in text and "# %% [markdown]" in text, path
        assert "execution_count" not in text, path


@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda p: p.stem)
def test_the_notebook_runs_in_a_kernel(path: Path, tmp_path, monkeypatch):
    jupytext = pytest.importorskip("jupytext", reason="the extra [notebooks]: make notebooks")
    nbclient = pytest.importorskip("nbclient", reason="the extra [notebooks]: make notebooks")
    pytest.importorskip("ipykernel", reason="the extra [notebooks]: make notebooks")
    pytest.importorskip("gymnasium")
    monkeypatch.setenv("MPLBACKEND", "Agg")
    nb = jupytext.read(path)
    client = nbclient.NotebookClient(nb, timeout=600, kernel_name="python3",
                                     resources={"metadata": {"path": str(path.parent)}})
    client.execute()
    printed = "".join(o.get("text", "") for c in nb.cells if c.cell_type == "code"
                      for o in c.get("outputs", []))
    assert "mean miss over the 66 targets" in printed and "random policy" in printed
