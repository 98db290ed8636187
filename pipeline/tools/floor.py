"""The batch kernel's floors (part of `make bench`): what one sample's formula needs, counted from
the kernel's code, at the speed of the CPU the bench runs on.

`sample_counts` counts, stage by stage, the vector operations of one sample column as the code
writes them (gbmodel/simd.py: chain_kinematics, sincos; gbmodel/learners/goal_babbling:
rollout._commands and _weights, core._features, _predict and _accumulate), by class: fma, add
(add, subtract), mul, logic (sign flips, the integer ops of sin/cos's quadrant), select (a
compare and a blend: vwhere, the clips), div, sqrt, load, bcast (a broadcast of an array's
element inside a loop over columns, such as M's entries in M Phi: a load of its own; splats of
constants are hoisted and count 0) and store. A block's or an epoch's fixed work (the zeroing of the gradient's lanes, the eq. 8 scaling, the
path) is left out; g along the path (once per path column, shared by the V variations) is
counted per sample. `sample_flops` follows from the counts: an fma 2 flops; an add, mul, div or
sqrt 1; logic, select, load, bcast and store 0.

`probe_ns` measures, on the running CPU, the CPU time of one F32x16 operation of each class at
full throughput (compiled microkernels: 6 independent chains of the operation, or 12 loads or
12 broadcasts per step from L1, or 6 stores of registers; the best of `tries`). `counted_floor`
prices a stage's counts with them (logic as an add: no probe of its own): the operations of each
unit (the vector pipes: fma, add, mul, logic and select; the divider: div and sqrt; the load
ports: load and bcast; the store port) add up, the units work side by side, and the stage's floor is its busiest unit's time. The epoch's
floor is the sum of its stages' floors (they run one after another).
"""
from __future__ import annotations

import time

import numpy as np
from numba import njit

from gbmodel.kinematics import chain_layout
from gbmodel.learners.goal_babbling.core import _BLOCK, _TILE
from gbmodel.simd import (
    F4, LANES, W8, vadd, vdiv, vfma, vload, vmul, vsplat, vsqrt, vstore, vsum, vwhere,
    wide_vectors,
)

CLASSES = ("fma", "add", "mul", "logic", "select", "div", "sqrt", "load", "bcast", "store")
UNITS = {"vector": ("fma", "add", "mul", "logic", "select"), "divider": ("div", "sqrt"),
         "load": ("load", "bcast"), "store": ("store",)}
FLOPS = {"fma": 2, "add": 1, "mul": 1, "div": 1, "sqrt": 1}
# simd.sincos: kf, r (2), the polynomials (3 + 4) fma; z = r r, r z; k = kf - round; the quadrant
# (_quadrant): 2 selects, 9 integer ops (and, compare, shift, add, xor)
SINCOS = dict(fma=10, mul=2, add=1, select=2, logic=9)
# the chain step by kind (chain_kinematics: twist 0, +90, -90, any; a general chain's R p + t)
STEP = (dict(add=2), dict(add=2, logic=1), dict(add=2), dict(add=2, fma=2, mul=2), dict(fma=9))


def _plus(*parts, scale=1.0) -> dict:
    out = dict.fromkeys(CLASSES, 0.0)
    for part in parts:
        for k, v in part.items():
            out[k] += v * scale
    return out


def _predict(m: int, p: int) -> dict:
    """core._predict of one column: rows in tiles of _TILE (a load of Phi per tile and feature,
    a broadcast of M's entry per row), a product and p - 1 fma per row, a store per row."""
    return dict(fma=m * (p - 1), mul=m, load=sum(divmod(m, _TILE)) * p, bcast=m * p, store=m)


def _gradient(m: int, p: int, t: int) -> dict:
    """core._accumulate of one column in t x t tiles: one fma per entry, 2 t loads per full
    tile, 1 + t per row left over, 2 per feature left over."""
    mt, pt = m - m % t, p - p % t
    loads = (mt // t) * (pt // t) * 2 * t + (m - mt) * (pt // t) * (1 + t) + m * (p - pt) * 2
    return dict(fma=m * p, load=loads)


def sample_counts(m: int, n: int, p: int, V: int, T: int, kinds, normalized: bool,
                  saturates: bool, tile: int) -> dict:
    """Operations of one sample column by stage and class (see the module): m joints with
    chain steps `kinds` (STEP's index, per joint), n outputs, p features, V variations of T + 1
    samples, the gradient in tile x tile register tiles."""
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
                          _plus(features, _predict(m, p), scale=path)),
        # per joint and its step; the block's P zeroed (3 stores); per output: 3 loads, 3 fma,
        # a store
        "kinematics": _plus(*(_plus(joint, STEP[k]) for k in kinds),
                            dict(store=3 + n, load=3 * n, fma=3 * n)),
        # eq. 1-3: dx, dot, |dx|^2 per output; dq, |dq|^2 per joint; 2 sqrt, 2 div, 5 selects
        "weights": dict(load=3 * n + 2 * m + 1, fma=2 * n + m, add=n + m + 1, mul=3, sqrt=2,
                        div=2, select=5, store=1),
        "features": features,
        "M_phi": _predict(m, p),
        "error": dict(add=m, mul=m, load=m + sum(divmod(m, _TILE))),  # w (M phi - q)
        "gradient": _gradient(m, p, tile),
    }


def flops(counts: dict) -> float:
    return sum(FLOPS.get(k, 0) * v for k, v in counts.items())


@njit(cache=True)
def _wide():
    return wide_vectors()


def tile() -> int:
    """The gradient's register tile on this CPU (core._accumulate: 5 with AVX-512, else 2)."""
    return _TILE if _wide() else 2


def body_counts(body, p: int, V: int, T: int, t: int | None = None) -> dict:
    """sample_counts of a body's chain (chain_layout: its kind of step per joint)."""
    ch = chain_layout(body)
    kinds = [4 if ch["general"] else {(1, 0): 0, (0, 1): 1, (0, -1): 2}.get(
        (ch["cos_alpha"][i], ch["sin_alpha"][i]), 3) for i in range(body.m)]
    return sample_counts(body.m, body.n, p, V, T, kinds, body.normalized, body.saturates,
                         tile() if t is None else t)


def sample_flops(body, p: int, V: int, T: int) -> dict:
    """Flops of one sample of an epoch of the batch kernel (solver=gradient), stage by stage."""
    out = {k: flops(c) for k, c in body_counts(body, p, V, T).items()}
    out["total"] = sum(out.values())
    return out


def online_sample_flops(body, p: int, V: int, T: int) -> dict:
    """Flops of one sample of an epoch with learner.updates=online: the rollout's stages of
    sample_flops (the same float32 kernel), then the online step in float64
    (goal_babbling/online.py), counted from its code on the W = m rounded up to W8 lanes it
    computes: per pair of samples s_t, g_t+1, s_t+1 (6 W), per feature the two steps and the two
    predictions (4 fma: 8 W p), then g and P (4 W); per sample eta w (1), the features (p - 1)
    and d = phi_t . phi_t+1 (2 p - 1). A float64 flop counts as two float32 ones: a vector holds
    half as many lanes, and the peak is measured in float32."""
    batch = sample_flops(body, p, V, T)
    W = -(-body.m // W8) * W8
    step = 4 * W * p + 5 * W + 1 + (p - 1) + (2 * p - 1)
    out = {k: batch[k] for k in ("commands", "kinematics", "weights")}
    out["online_step_float64_x2"] = 2 * step
    out["total"] = sum(out.values())
    return out


def counted_floor(counts: dict, probe: dict) -> dict:
    """A stage's counts priced by probe_ns (ns per F32x16 operation, class by class): ns per
    sample on each unit, the floor (the busiest unit) and that unit."""
    units = {u: sum(counts.get(k, 0) * probe["add" if k == "logic" else k] for k in ks) / LANES
             for u, ks in UNITS.items()}
    bound = max(units, key=units.get)
    return {"counts": {k: counts.get(k, 0) for k in CLASSES}, "unit_ns": units,
            "floor_ns": units[bound], "bound": bound}


# ---- the probes: one class of operation at full throughput ----------------------------------
@njit(cache=True)
def _probe(what, iters):
    """`iters` steps of 6 independent chains of one operation (what: an index of CLASSES but
    logic; load: 12 loads per step, 2 per fma, from two rows in L1; store: 6 vector stores of
    registers per step). Returns a value that depends on every step."""
    c, d = vsplat(F4(0.999)), vsplat(F4(0.001))
    a0, a1, a2 = vsplat(1.0), vsplat(1.1), vsplat(1.2)
    a3, a4, a5 = vsplat(1.3), vsplat(1.4), vsplat(1.5)
    raw = np.ones(12 * 256 + LANES, np.float32)  # rows on 64-byte boundaries: no split lines
    off = (-(raw.ctypes.data // 4)) % LANES
    buf = raw[off:off + 12 * 256].reshape((12, 256))
    for it in range(iters):
        if what == 0:
            a0, a1, a2 = vfma(a0, c, d), vfma(a1, c, d), vfma(a2, c, d)
            a3, a4, a5 = vfma(a3, c, d), vfma(a4, c, d), vfma(a5, c, d)
        elif what == 1:
            a0, a1, a2, a3, a4, a5 = (vadd(a0, d), vadd(a1, d), vadd(a2, d), vadd(a3, d),
                                      vadd(a4, d), vadd(a5, d))
        elif what == 2:
            a0, a1, a2, a3, a4, a5 = (vmul(a0, c), vmul(a1, c), vmul(a2, c), vmul(a3, c),
                                      vmul(a4, c), vmul(a5, c))
        elif what == 4:  # each chain picks between two others: nothing to fold
            a0, a1, a2, a3, a4, a5 = (vwhere(a0, a1, a2, a3), vwhere(a1, a2, a3, a4),
                                      vwhere(a2, a3, a4, a5), vwhere(a3, a4, a5, a0),
                                      vwhere(a4, a5, a0, a1), vwhere(a5, a0, a1, a2))
        elif what == 5:  # x <- 1 / (x + 0.001): a full mantissa
            a0, a1, a2 = vdiv(c, vadd(a0, d)), vdiv(c, vadd(a1, d)), vdiv(c, vadd(a2, d))
            a3, a4, a5 = vdiv(c, vadd(a3, d)), vdiv(c, vadd(a4, d)), vdiv(c, vadd(a5, d))
        elif what == 6:
            a0, a1, a2 = vsqrt(vadd(a0, d)), vsqrt(vadd(a1, d)), vsqrt(vadd(a2, d))
            a3, a4, a5 = vsqrt(vadd(a3, d)), vsqrt(vadd(a4, d)), vsqrt(vadd(a5, d))
        elif what == 8:  # 12 broadcasts of an array's element per step
            o = (it * LANES) % 256
            a0 = vfma(vsplat(buf[0, o]), vsplat(buf[6, o]), a0)
            a1 = vfma(vsplat(buf[1, o]), vsplat(buf[7, o]), a1)
            a2 = vfma(vsplat(buf[2, o]), vsplat(buf[8, o]), a2)
            a3 = vfma(vsplat(buf[3, o]), vsplat(buf[9, o]), a3)
            a4 = vfma(vsplat(buf[4, o]), vsplat(buf[10, o]), a4)
            a5 = vfma(vsplat(buf[5, o]), vsplat(buf[11, o]), a5)
        elif what == 7:
            o = (it * LANES) % 256
            a0 = vfma(vload(buf, 0, o), vload(buf, 6, o), a0)
            a1 = vfma(vload(buf, 1, o), vload(buf, 7, o), a1)
            a2 = vfma(vload(buf, 2, o), vload(buf, 8, o), a2)
            a3 = vfma(vload(buf, 3, o), vload(buf, 9, o), a3)
            a4 = vfma(vload(buf, 4, o), vload(buf, 10, o), a4)
            a5 = vfma(vload(buf, 5, o), vload(buf, 11, o), a5)
        elif what == 9:
            o = (it * LANES) % 256
            vstore(buf, 0, o, a0)
            vstore(buf, 1, o, a1)
            vstore(buf, 2, o, a2)
            vstore(buf, 3, o, a3)
            vstore(buf, 4, o, a4)
            vstore(buf, 5, o, a5)
            if o == 0:
                a0 = vadd(a0, d)
    return vsum(vadd(vadd(vadd(a0, a1), vadd(a2, a3)), vadd(a4, a5))) + buf.sum()


# operations per step of _probe by class (logic is priced as an add: no probe of its own)
_PROBED = {"fma": 6, "add": 6, "mul": 6, "select": 6, "div": 6, "sqrt": 6, "load": 12,
           "bcast": 12, "store": 6}


def probe_ns(iters: int = 200_000, tries: int = 3) -> dict:
    """ns of CPU time per F32x16 operation of each class at full throughput, on this CPU: the
    best of `tries` runs of _probe (a few ms each)."""
    out = {}
    for name, ops in _PROBED.items():
        what = CLASSES.index(name)
        _probe(what, 10)  # compiled or loaded outside the timing
        best = np.inf
        for _ in range(tries):
            c0 = time.process_time()
            _probe(what, iters)
            best = min(best, time.process_time() - c0)
        out[name] = 1e9 * max(best, 1e-9) / (iters * ops)
    return out


@njit(cache=True)
def _fma_chains(iters):
    """6 independent chains of vfma on the kernel's vector type (F32x16: 12 ymm or 6 zmm
    registers), iters steps each: 6 * LANES * 2 flops per step."""
    m, c = vsplat(F4(0.999)), vsplat(F4(0.001))
    a0, a1, a2, a3 = vsplat(1.0), vsplat(1.1), vsplat(1.2), vsplat(1.3)
    a4, a5 = vsplat(1.4), vsplat(1.5)
    for _ in range(iters):
        a0, a1, a2 = vfma(a0, m, c), vfma(a1, m, c), vfma(a2, m, c)
        a3, a4, a5 = vfma(a3, m, c), vfma(a4, m, c), vfma(a5, m, c)
    return vsum(vadd(vadd(vadd(a0, a1), vadd(a2, a3)), vadd(a4, a5)))


@njit(cache=True)
def _fma_chains8(iters):
    """8 chains (for a CPU whose fma latency times its fma units exceeds 6 vectors)."""
    m, c = vsplat(F4(0.999)), vsplat(F4(0.001))
    a0, a1, a2, a3 = vsplat(1.0), vsplat(1.1), vsplat(1.2), vsplat(1.3)
    a4, a5, a6, a7 = vsplat(1.4), vsplat(1.5), vsplat(1.6), vsplat(1.7)
    for _ in range(iters):
        a0, a1, a2, a3 = vfma(a0, m, c), vfma(a1, m, c), vfma(a2, m, c), vfma(a3, m, c)
        a4, a5, a6, a7 = vfma(a4, m, c), vfma(a5, m, c), vfma(a6, m, c), vfma(a7, m, c)
    return vsum(vadd(vadd(vadd(a0, a1), vadd(a2, a3)), vadd(vadd(a4, a5), vadd(a6, a7))))


def peak_gflops(iters: int = 2_000_000, tries: int = 3) -> float:
    """The peak of one core in float32 GFLOP/s, measured: the best CPU-time rate of `tries` runs
    of 6 and of 8 independent fma chains on F32x16 (about 10 ms each at 100 GFLOP/s)."""
    best = 0.0
    for fn, chains in ((_fma_chains, 6), (_fma_chains8, 8)):
        fn(10)  # compiled or loaded outside the timing
        for _ in range(tries):
            c0 = time.process_time()
            fn(iters)
            dt = time.process_time() - c0
            if dt > 0:
                best = max(best, iters * chains * LANES * 2 / dt / 1e9)
    return best
