"""python -m pipeline.tools.body (gbgrowth body): what it says of a body's chain."""
import importlib.util

import pytest
from omegaconf import OmegaConf

from pipeline.config import compose
from pipeline.tools import body as tool


def _lines(name: str) -> list[str]:
    return tool.describe(OmegaConf.to_container(compose([f"body={name}"]).body))


def test_a_dh_body_names_its_rows():
    lines = _lines("arm2")
    assert lines[1] == "chain: 2 DH rows (a, d, alpha, theta offset)"
    assert "row 1" in lines[4]


@pytest.mark.skipif(importlib.util.find_spec("gymnasium") is None,
                    reason="gymnasium is not installed (the test extra)")
def test_an_mjcf_body_is_named_as_one_with_its_joints():
    """An MJCF body was described as 'chain: 2 DH rows' with joints 'row 1', 'row 2'."""
    lines = _lines("reacher")
    assert lines[1].startswith("chain: MJCF ") and "body world -> fingertip" in lines[1]
    assert lines[1].endswith("2 commanded joints")
    assert "joint0" in lines[4] and "joint1" in lines[5]


def test_it_prints_and_writes_nothing(tmp_path):
    """The tool only reads and prints: no config snapshot (outputs/logs/body/) and no
    checked-plan note (outputs/planned/) under the root it runs in."""
    from conftest import run_cli

    r = run_cli("pipeline.tools.body", "body=arm2", f"paths.root={tmp_path}")
    assert r.returncode == 0, r.stderr
    assert "chain: 2 DH rows" in r.stdout
    assert list(tmp_path.rglob("*")) == []
