"""The batch kernel's floors (`make bench`): the vector operations of one sample column, stage by
stage and class, counted from the kernel's code (gbmodel/simd.py; goal_babbling's rollout.py and
core.py), the flops they make, and a stage's counted floor at bench.probe_ns's throughputs: the
units (vector pipes, divider, load ports, store port) work side by side, the busiest one binds.
"""
from __future__ import annotations

from numba import njit

from gbmodel.kinematics import chain_layout
from gbmodel.learners.goal_babbling.core import _TILE
from gbmodel.simd import LANES, W8, wide_vectors

# by class: logic (sign flips, sin/cos's quadrant), select (a compare and a blend), bcast (an
# array's element broadcast inside a loop over columns; splats of constants are hoisted: 0)
CLASSES = ("fma", "add", "mul", "logic", "select", "div", "sqrt", "load", "bcast", "store")
UNITS = {"vector": ("fma", "add", "mul", "logic", "select"), "divider": ("div", "sqrt"),
         "load": ("load", "bcast"), "store": ("store",)}
FLOPS = {"fma": 2, "add": 1, "mul": 1, "div": 1, "sqrt": 1}
# simd.sincos: kf, r (2), the polynomials (3 + 4) fma; z = r r, r z; k = kf - round; the quadrant
# (_quadrant): 2 selects, 9 integer ops (and, compare, shift, add, xor)
SINCOS = dict(fma=10, mul=2, add=1, select=2, logic=9)
# the chain step by kind (chain_kinematics: twist 0, +90, -90, any; a general chain's R p + t)
STEP = (dict(add=2), dict(add=2, logic=1), dict(add=2), dict(add=2, fma=2, mul=2), dict(fma=9))


def _plus(*parts, scale=1.0) -> dict:  # the sum of counts, `scale` times
    out = dict.fromkeys(CLASSES, 0.0)
    for part in parts:
        for k, v in part.items():
            out[k] += v * scale
    return out


def _predict_counts(m: int, p: int) -> dict:
    """core._predict of one column: rows in tiles of _TILE (a load of Phi per tile and feature,
    a broadcast of M's entry per row), a product and p - 1 fma per row, a store per row."""
    return dict(fma=m * (p - 1), mul=m, load=sum(divmod(m, _TILE)) * p, bcast=m * p, store=m)


def _gradient_counts(m: int, p: int, t: int) -> dict:
    """core._accumulate of one column in t x t tiles: one fma per entry, 2 t loads per full
    tile, 1 + t per row left over, 2 per feature left over."""
    mt, pt = m - m % t, p - p % t
    loads = (mt // t) * (pt // t) * 2 * t + (m - mt) * (pt // t) * (1 + t) + m * (p - pt) * 2
    return dict(fma=m * p, load=loads)


def sample_counts(m: int, n: int, p: int, V: int, T: int, kinds, normalized: bool,
                  saturates: bool, tile: int) -> dict:
    """Operations of one sample column by stage and class: m joints with chain steps `kinds`
    (STEP's index), V variations of T + 1 samples, tile x tile register tiles; g along the path
    (shared by the V variations) counted per sample, an epoch's fixed work left out."""
    features = dict(mul=p - 1, load=2 * (p - 1), store=p)
    path = -(-(T + 1) // LANES) * LANES / (V * (T + 1))  # path columns per sample
    sat = normalized and saturates
    # per joint: q (a load), its clip (2 selects, a store), theta (an fma, or an add), sin and
    # cos, P (3 loads, 3 stores), Rz (2 fma, 2 mul, a sign flip)
    joint = _plus(SINCOS, dict(load=4, store=3 + sat, select=2 * sat, fma=2, mul=2, logic=1),
                  {"fma": 1} if normalized else {"add": 1})
    return {
        # x* (n loads), per joint g (a load), b and A's row (broadcasts), an add, n fma, a store
        "commands": _plus(dict(load=n + m, bcast=m * (1 + n), add=m, fma=m * n, store=m),
                          _plus(features, _predict_counts(m, p), scale=path)),
        # per joint and its step; the block's P zeroed (3 stores); per output: 3 loads, 3 fma,
        # a store
        "kinematics": _plus(*(_plus(joint, STEP[k]) for k in kinds),
                            dict(store=3 + n, load=3 * n, fma=3 * n)),
        # eq. 1-3: dx, dot, |dx|^2 per output; dq, |dq|^2 per joint; 2 sqrt, 2 div, 5 selects
        "weights": dict(load=3 * n + 2 * m + 1, fma=2 * n + m, add=n + m + 1, mul=3, sqrt=2,
                        div=2, select=5, store=1),
        "features": features,
        "M_phi": _predict_counts(m, p),
        "error": dict(add=m, mul=m, load=m + sum(divmod(m, _TILE))),  # w (M phi - q)
        "gradient": _gradient_counts(m, p, tile),
    }


def flops(counts: dict) -> float:
    return sum(FLOPS.get(k, 0) * v for k, v in counts.items())


@njit(cache=True)
def _wide():
    return wide_vectors()


def body_counts(body, p: int, V: int, T: int) -> dict:
    """sample_counts of a body's chain, in this CPU's register tile (5 with AVX-512, else 2)."""
    ch = chain_layout(body)
    kinds = [4 if ch["general"] else {(1, 0): 0, (0, 1): 1, (0, -1): 2}.get(
        (ch["cos_alpha"][i], ch["sin_alpha"][i]), 3) for i in range(body.m)]
    return sample_counts(body.m, body.n, p, V, T, kinds, body.normalized, body.saturates,
                         _TILE if _wide() else 2)


def sample_flops(body, p: int, V: int, T: int) -> dict:
    """Flops of one sample of an epoch of the batch kernel (solver=gradient), stage by stage."""
    out = {k: flops(c) for k, c in body_counts(body, p, V, T).items()}
    out["total"] = sum(out.values())
    return out


def online_sample_flops(body, p: int, V: int, T: int) -> dict:
    """Flops of one sample with learner.updates=online: the rollout's stages of sample_flops,
    then the float64 step (goal_babbling/online.py) on W = m rounded up to W8 lanes: per pair of
    samples 6 W, per feature 8 W, then 4 W; per sample eta w (1), the features (p - 1) and
    phi_t . phi_t+1 (2 p - 1). A float64 flop counts as two float32 ones (half the lanes)."""
    batch = sample_flops(body, p, V, T)
    W = -(-body.m // W8) * W8
    step = 4 * W * p + 5 * W + 1 + (p - 1) + (2 * p - 1)
    out = {k: batch[k] for k in ("commands", "kinematics", "weights")}
    out["online_step_float64_x2"] = 2 * step
    out["total"] = sum(out.values())
    return out


def counted_floor(counts: dict, probe: dict) -> dict:
    """A stage's counts priced by probe_ns (logic as an add): ns per sample on each unit, the
    floor (the busiest unit: the units work side by side) and that unit."""
    units = {u: sum(counts.get(k, 0) * probe["add" if k == "logic" else k] for k in ks) / LANES
             for u, ks in UNITS.items()}
    bound = max(units, key=units.get)
    return {"counts": {k: counts.get(k, 0) for k in CLASSES}, "unit_ns": units,
            "floor_ns": units[bound], "bound": bound}
