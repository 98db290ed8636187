"""A body as the pipeline sees it, before a first run: its chain, joints, limits and reach, the
workspace its hand reaches within the limits (gbmodel.workspace: sampled postures), whether its
target grid lies in it, and a grid around home that does (paste its `grid:` line into the body
file); it writes nothing. After a run, --within PCT: each trial's held-out error at the last
epoch in % of the reach, the trials above PCT named (exit 1).

    python -m pipeline.tools.body body=arm5
    python -m pipeline.tools.body 'hydra.searchpath=[file:///abs/my_conf]' body=my_arm
    python -m pipeline.tools.body figure=my_arm --within 1.5
"""
from __future__ import annotations

import sys
from pathlib import Path

import hydra
import numpy as np
from omegaconf import DictConfig, OmegaConf

import gbmodel
import gbmodel.mjcf
import gbmodel.urdf
from gbmodel import workspace

from .. import cli, io
from ..config import CONFIG_PATH, ConfigError
from . import fail

AXES = "xyz"
WITHIN = "--within"
_WITHIN: list = [None]  # the percentage of --within (take_flags), None: describe the body


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
    x, reach = workspace.hand_samples(body), workspace.reach(body)
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
    grid = propose_grid(body, g.get("num"))
    if grid is None:
        out.append("proposed grid: none found around home (too few sampled hand positions near "
                   "it); choose one inside the workspace above")
    else:
        sides = ", ".join(f"{AXES[k]} {h - lo:.3f} m" for k, lo, h in
                          zip(body.outputs, grid["lo"], grid["hi"]))
        widest = 100 * max(np.subtract(grid["hi"], grid["lo"])) / reach
        holds = all(lo <= h <= hi for lo, h, hi in zip(grid["lo"], body.forward(body.home),
                                                        grid["hi"]))
        out.append(f"proposed grid ({sides}: {widest:.0f} % of the reach at most; every target "
                   "reached at full and half size; "
                   + ("it holds the hand at home" if holds else
                      "the hand at home is on the edge of the workspace, where no box holds it: "
                      "this one lies beside it (or choose a bent home)")
                   + "; paste it into the body file):")
        out.append(f"  grid: {{lo: {grid['lo']}, hi: {grid['hi']}, num: {grid['num']}}}")
    return out


def propose_grid(body, num=None, near: float = 0.5, tail: float = 5.0, side: float = 0.8,
                 seed: int = workspace.SEED) -> dict | None:
    """A grid (a body file's `grid:`) holding the hand's home h, every target reached at full and
    half size: the `tail` ... 100 - `tail` percentiles of the sampled hand positions within
    `near` x the reach of h, widened to hold h, each side at most `side` x the reach, shrunk
    towards h until every target is reached; or, home on the workspace's edge, the same about
    those samples' middle. num: points per axis (the body's grid's, else 4). None: neither."""
    x = workspace.hand_samples(body, seed=seed)
    n = x.shape[1]
    num = [int(k) for k in num] if num is not None and len(num) == n else [4] * n
    home = np.asarray(body.forward(body.home), np.float64).reshape(n)
    reach = 0.5 * workspace.diameter(x)
    close = x[np.linalg.norm(x - home, axis=1) <= near * reach]
    if len(close) < 10 * n:
        return None
    lo, hi = np.percentile(close, tail, axis=0), np.percentile(close, 100 - tail, axis=0)
    for anchor in (home, np.median(close, axis=0)):
        grid = _box(body, anchor, np.minimum(lo, anchor), np.maximum(hi, anchor), side * reach,
                    num, seed)
        if grid is not None:
            return grid
    return None


def _box(body, anchor, lo, hi, longest: float, num: list, seed: int) -> dict | None:
    """The box lo ... hi, each side cut to `longest` about anchor, shrunk towards it until every
    target of its grid is reached at full and half size (bounds rounded out to the millimetre)."""
    from dataclasses import replace

    cut = np.minimum(1.0, longest / np.maximum(hi - lo, 1e-12))
    lo, hi = anchor + cut * (lo - anchor), anchor + cut * (hi - anchor)
    for shrink in (1.0, 0.8, 0.6, 0.4, 0.2):
        g_lo = np.floor(1e3 * (anchor + shrink * (lo - anchor)) + 1e-9) / 1e3
        g_hi = np.ceil(1e3 * (anchor + shrink * (hi - anchor)) - 1e-9) / 1e3
        if np.any(g_hi <= g_lo):
            return None
        grid = dict(lo=[round(float(v), 3) for v in g_lo],
                    hi=[round(float(v), 3) for v in g_hi], num=num)
        candidate = replace(body, targets=gbmodel.bodies.grid_points(**grid))
        if all(gbmodel.bodies.unreachable(candidate, np.random.default_rng(seed), size=s).size
               == 0 for s in (1.0, 0.5)):
            return grid
    return None


def trials_within(folder, figure: str, pct: float) -> tuple[list[str], int]:
    """(the lines, the trials above pct): each trial's held-out error at its last epoch in % of
    its condition's reach."""
    d = io.set_of(folder)
    trials = io.read_table(d / "trials.parquet").to_pandas()
    reach = dict(zip(*io.read_table(d / "summary.parquet").select(
        ["condition", "reach"]).to_pydict().values()))
    last = trials.sort_values("epoch").groupby(["condition", "trial"], sort=True).tail(1)
    out, missed = [], []
    for _, t in last.sort_values(["condition", "trial"]).iterrows():
        p = 100 * t["heldout_abs_error"] / reach[t["condition"]]
        out.append(f"[{figure}] {t['condition']} trial {t['trial']}: held out "
                   f"{1e3 * t['heldout_abs_error']:.1f} mm = {p:.2f} % of the reach")
        if not p <= pct:  # NaN (a diverged trial) misses too
            missed.append(f"{t['condition']} trial {t['trial']} ({p:.2f} %)")
    out.append(f"[{figure}] every one of {len(last)} trials within {pct:g} % of the reach"
               if not missed else f"[{figure}] {len(missed)} of {len(last)} trials above "
               f"{pct:g} % of the reach: {', '.join(missed)}")
    return out, len(missed)


def run(cfg: DictConfig) -> int:
    if _WITHIN[0] is not None:
        folder = Path(cfg.paths.aggregate) / io.safe_name("figure", cfg.figure)
        if not folder.exists():
            raise FileNotFoundError(f"{folder}: figure={cfg.figure} is not aggregated (run "
                                    f"pipeline.aggregate figure={cfg.figure})")
        lines, missed = trials_within(folder, cfg.figure, _WITHIN[0])
        print("\n".join(lines), flush=True)
        return 1 if missed else 0
    print("\n".join(describe(OmegaConf.to_container(cfg.body))), flush=True)
    return 0


def take_flags(argv: list[str]) -> list[str]:
    """argv without `--within PCT` (Hydra's parser would refuse it), noted; a bad PCT exits 2."""
    if WITHIN not in argv:
        return argv
    k = argv.index(WITHIN)
    try:
        _WITHIN[0] = float(argv[k + 1])
    except (IndexError, ValueError):
        _WITHIN[0] = 0.0
    if not _WITHIN[0] > 0:
        sys.exit(fail(f"{WITHIN} takes a percentage of the reach above 0 (--within 1.5)"))
    return argv[:k] + argv[k + 2:]


@hydra.main(config_path=CONFIG_PATH, config_name="config", version_base="1.3")
def main(cfg: DictConfig) -> None:
    cli.finish(run, cfg, record=False)  # it only prints: no snapshot, no checked-plan note


if __name__ == "__main__":
    if len(sys.argv) == 1:
        print(__doc__.split("\n\n")[1], file=sys.stderr)
    sys.argv = [sys.argv[0], *take_flags(sys.argv[1:])]
    cli.main(main)
