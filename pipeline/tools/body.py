"""A body as the pipeline sees it, before a first run: its chain, joints, limits and reach, the
workspace its hand can reach within the limits, whether its target grid lies in it, and a grid
that does (gbmodel.workspace: sampled postures, not a guess from the link lengths).

    python -m pipeline.tools.body body=arm5
    python -m pipeline.tools.body 'hydra.searchpath=[file:///abs/my_conf]' body=my_arm

The proposed grid is a box around the hand's home position (where Goal Babbling starts) whose
every target a posture within the limits reaches, at full and at half size: paste its `grid:`
line into the body file. It prints to stdout and writes nothing.
"""
from __future__ import annotations

import sys

import hydra
import numpy as np
from omegaconf import DictConfig, OmegaConf

import gbmodel
import gbmodel.mjcf
import gbmodel.urdf
from gbmodel import workspace

from .. import cli
from ..config import CONFIG_PATH, ConfigError

AXES = "xyz"


def _fmt(values, digits: int = 3) -> str:
    return "[" + ", ".join(f"{float(v):.{digits}f}" for v in values) + "]"


def describe(desc: dict) -> list[str]:
    """The lines the tool prints for a body description (conf/body/<name>.yaml's fields)."""
    try:
        body = gbmodel.make_body(desc)
    except ValueError as err:
        raise ConfigError(str(err)) from None
    out = [f"body {body.name}: {body.description or '(no description)'}"]
    kind = next((k for k in ("urdf", "mjcf") if isinstance(desc.get(k), dict)
                 and "file" in desc[k]), None)
    loop = desc.get("callable")
    if kind is not None:  # a URDF or an MJCF model: its chain and its joints' names
        section = desc[kind]
        module = gbmodel.urdf if kind == "urdf" else gbmodel.mjcf
        names = list(module.read_chain(**section)["names"])
        out.append(f"chain: {kind.upper()} {section['file']}, "
                   f"{'link' if kind == 'urdf' else 'body'} {section['root']} -> "
                   f"{section['tip']}, {body.m} commanded joints")
    elif isinstance(loop, dict) and loop.get("factory"):
        names = [f"joint {i + 1}" for i in range(body.m)]
        out.append(f"chain: a forward function in the loop, {loop['factory']}, {body.m} joints")
    else:
        names = [f"row {i + 1}" for i in range(body.m)]
        out.append(f"chain: {body.m} DH rows (a, d, alpha, theta offset)")
    hand = ", ".join(AXES[k] for k in body.outputs)
    out.append(f"controls: the hand's {hand} (outputs {list(body.outputs)}); commands "
               + ("normalised: -1 ... 1 spans each joint's limits"
                  + (", clipped there (saturate: true)" if body.saturates else
                     " (saturate: false: not clipped)") if body.normalized
                  else "in radians, no limits"))
    seg = body.segment_lengths
    out.append("  joint  name                 segment [m]  limits [rad]         limits [deg]"
               "         home")
    for i in range(body.m):
        if body.normalized:
            lim = f"{body.q_min[i]:+8.3f} {body.q_max[i]:+8.3f}   "
            deg = f"{np.degrees(body.q_min[i]):+7.1f} {np.degrees(body.q_max[i]):+7.1f}    "
        else:
            lim, deg = f"{'none':<20}", f"{'none':<20}"
        out.append(f"  {i + 1:<5}  {names[i][:20]:<20} {seg[i]:11.3f}  {lim} {deg} "
                   f"{body.home[i]:+.3f}")
    x = workspace.hand_samples(body)
    reach = workspace.reach(body)
    out.append(f"reach: {reach:.3f} m (half the largest distance between two hand positions over "
               f"{workspace.SAMPLES:,} postures within the limits)")
    out.append("workspace (sampled), per axis 1 % ... 99 %: " + ", ".join(
        f"{AXES[k]} {lo:.3f} ... {hi:.3f} m" for k, lo, hi in
        zip(body.outputs, np.percentile(x, 1, axis=0), np.percentile(x, 99, axis=0))))
    out.append(f"home: the hand at {_fmt(body.forward(body.home))} m")
    g = desc.get("grid") or {}
    missed = gbmodel.bodies.unreachable(body, np.random.default_rng(0))
    out.append(f"grid now: lo {list(g.get('lo', []))}, hi {list(g.get('hi', []))}, num "
               f"{list(g.get('num', []))}: {len(body.targets)} targets, "
               + (f"{len(missed)} reached by no posture within 1 mm (e.g. "
                  f"{_fmt(body.targets[missed[0]])})" if len(missed) else
                  "every one reached by a posture within the limits"))
    grid = workspace.propose_grid(body, g.get("num"))
    if grid is None:
        out.append("proposed grid: none found around home (a home posture at a joint limit or "
                   "in a thin part of the workspace?); choose one inside the workspace above")
    else:
        out.append("proposed grid (around the hand at home, every target reached at full and "
                   "half size; paste it into the body file):")
        out.append(f"  grid: {{lo: {grid['lo']}, hi: {grid['hi']}, num: {grid['num']}}}")
    return out


def run(cfg: DictConfig) -> int:
    print("\n".join(describe(OmegaConf.to_container(cfg.body))), flush=True)
    return 0


@hydra.main(config_path=CONFIG_PATH, config_name="config", version_base="1.3")
def main(cfg: DictConfig) -> None:
    cli.finish(run, cfg, record=False)  # it only prints: no snapshot, no checked-plan note


if __name__ == "__main__":
    if len(sys.argv) == 1:
        print(__doc__.split("\n\n")[1], file=sys.stderr)
    cli.main(main)
