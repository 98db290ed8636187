"""The body inspector's proposed grid (pipeline.tools.body.propose_grid): on the 5-DOF arm, an
MJCF arm (Gymnasium's Pusher) and a URDF arm (tests/new_robots.py: Panda-like) it holds the hand's
home position, each side is a sane part of the reach, and every target is reached at full and
half size; a home on the edge of the workspace (the stretched arm) gets a grid beside it, said."""
import dataclasses

import numpy as np
import pytest
from omegaconf import OmegaConf

import gbmodel
import new_robots
from gbmodel import workspace
from pipeline.config import compose
from pipeline.tools import body as tool


def _body(name, tmp_path, *over):
    extra = []
    if name in new_robots.NAMES:
        new_robots.write(name, tmp_path)
        extra = [f"hydra.searchpath=[file://{tmp_path}/conf]"]
    return gbmodel.make_body(OmegaConf.to_container(compose(extra + [f"body={name}", *over]).body))


@pytest.mark.parametrize("name", ["arm5", "pusher", "panda_like"])
def test_the_proposed_grid_holds_home_and_is_sane_against_the_reach(name, tmp_path):
    body = _body(name, tmp_path)
    grid = tool.propose_grid(body)
    assert grid is not None and grid["num"] == [4] * body.n
    home = body.forward(body.home)
    assert all(lo <= h <= hi for lo, h, hi in zip(grid["lo"], home, grid["hi"])), (grid, home)
    sides = np.subtract(grid["hi"], grid["lo"]) / workspace.reach(body)
    assert (sides >= 0.15).all() and (sides <= 0.8 + 1e-3).all(), sides
    targets = gbmodel.bodies.grid_points(**grid)
    for size in (1.0, 0.5):
        assert gbmodel.bodies.unreachable(dataclasses.replace(body, targets=targets),
                                          np.random.default_rng(0), size=size).size == 0


def test_a_home_on_the_edge_of_the_workspace_gets_a_grid_beside_it_and_a_reason(tmp_path):
    """The stretched arm (home all zeros: the hand at the reach): no box holding home is reached
    everywhere, so the grid lies beside home, and the inspector says so."""
    body = _body("arm5", tmp_path, "body.home=[0,0,0,0,0]")
    grid = tool.propose_grid(body)
    home = body.forward(body.home)
    assert grid is not None and not all(
        lo <= h <= hi for lo, h, hi in zip(grid["lo"], home, grid["hi"]))
    lines = tool.describe(OmegaConf.to_container(compose(
        ["body=arm5", "body.home=[0,0,0,0,0]"]).body))
    assert "the hand at home is on the edge of the workspace" in lines[-2]
    assert lines[-1].startswith(f"  grid: {{lo: {grid['lo']}, hi: {grid['hi']}, num: ")
