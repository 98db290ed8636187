"""Goal Babbling against SAC with hindsight relabelling on the same growing arm
(examples/06_sac_against_goal_babbling.py, the figure of docs/gym.md), at a tiny budget: both
learn, both are scored on the held-out targets in mm and % of reach at equal forward
evaluations. Slow (torch); needs the extra [rl] (make gym-figure installs it)."""
import importlib.util
import json

import pytest

from pipeline.config import REPO_ROOT


@pytest.mark.slow
def test_sac_and_goal_babbling_are_scored_alike_on_the_growing_arm(tmp_path):
    pytest.importorskip("torch", reason="the extra [rl]: make gym-figure")
    pytest.importorskip("stable_baselines3", reason="the extra [rl]: make gym-figure")
    path = REPO_ROOT / "examples" / "06_sac_against_goal_babbling.py"
    spec = importlib.util.spec_from_file_location("sac_example", path)
    example = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(example)
    numbers = example.main(["--steps", "600", "--seeds", "1", "--every", "200",
                            "--out", str(tmp_path)])
    assert (tmp_path / "sac_vs_goal_babbling.png").stat().st_size > 10_000
    assert json.loads((tmp_path / "sac_vs_goal_babbling.json").read_text()) == numbers
    assert numbers["budget_evaluations"] == 600 and numbers["growth_ends_after_evaluations"] == 300
    assert numbers["sac_her"]["at_evaluations"] == 600
    assert numbers["online_goal_babbling"]["at_evaluations"] <= 600
    for name in ("sac_her", "online_goal_babbling"):
        mm, pct = numbers[name]["heldout_mm"], numbers[name]["heldout_pct_reach"]
        assert 0 < mm < 2000 and pct == pytest.approx(mm / 10 / numbers["reach_m"], abs=0.01)
