"""Online Goal Babbling, after Rolf, Steil & Gienger 2011 ("Online goal babbling for rapid
bootstrapping of inverse models in high dimensions"): one continuous movement, learned sample by
sample.

Taken from the 2011 paper (as we read it, and as the IRP group's open implementation `pygb`
realises it):
- a single continuous stream of goal-directed movements instead of V rollouts per epoch: the
  target moves along straight paths between targets drawn from the target set, and the path, the
  perturbation and the last sample carry over from epoch to epoch;
- the exploratory perturbation E_t(x) = A_t x + b_t drifts slowly: per sample, its parameters
  take a random-walk step that keeps their spread, P <- (P + drift xi) / sqrt(1 + drift^2),
  xi ~ N(0, 1), so that the entries of P = [A | b] stay N(0, 1)-distributed;
- one gradient step per sample on that sample's weighted error, w_t (g(x_t) - q_t)^2, weights
  w_dir * w_eff (eq. 1-3 of the 2010 paper) against the previous sample;
- after a target, a return to home with probability `home_probability`.

Chosen here:
- the paths are the 2010 paper's (eq. 9): L linear steps to each next target, the last one on it,
  the next target uniform over the other targets; an epoch is K targets, K L path samples;
- the perturbation's amplitude is the 2010 paper's (eq. 8): each row of [A | b] scaled so that
  max |E_i(x)| over the target box is exactly R (gbmodel.learners.goal_babbling.reference), so
  that R means what it means for Goal Babbling;
- a return home is one sample, the home example (q_home, x_home) with weight 1 (eq. 5 of 2010),
  and the next path starts at x_home (2011 moves home through joint space);
- the inverse estimate is Goal Babbling's polynomial (eq. 7), initialised the same way, and the
  step is plain per-sample gradient descent, M <- M - eta w_t (M Phi(x_t) - q_t) Phi(x_t)^T
  (2011 learns a local-linear map);
- samples per epoch: K L plus the returns home, K home_probability in expectation;
- goal_selection: random (the above: each next target uniform over the others) or progress
  (goal_babbling/goals.py: by the regions' recent change of error, not the 2011 paper's).

Two paths compute the same thing with the same draws (all random numbers come from `draw`):
`train_reference` below, plain numpy, is the readable statement; `_train_block`, the same
per-sample loop compiled with numba in float64 (no fastmath: every sum in a fixed order, so the
result does not depend on the CPU's vector width), is what runs by default. Its work on M runs on
explicit 8-lane float64 vectors, one lane per row of M (M kept transposed and padded), and one
pass over M per sample does the step and the next sample's prediction together; sin and cos
are its own polynomials (_sincos), and the evaluation's distances are compiled as well. They
agree to rounding (tests/test_learners.py). `Params.fast` picks the path. The random walk's
normals are drawn by numba's Generator from the trial's generator (`_normals`): numpy's very
numbers, at under half numpy's cost.
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
from llvmlite import ir
from numba import njit, types
from numba.core import cgutils
from numba.extending import intrinsic, models, register_model

from .. import evaluation
from ..features import exponents, features
from ..growth import SpecError, check_int, check_number
from .goal_babbling import goals
from .goal_babbling.fast import _chain as kernel_chain  # the kernels' layout of a chain
from .goal_babbling.reference import (NO_MOVEMENT, init_inverse, predict as predict_inverse,
                                      sample_weights, scale_perturbations)


@dataclass(frozen=True)
class Params:
    targets_per_epoch: int = 15  # K
    steps: int = 7  # L, linear steps to each next target (eq. 9)
    radius: float = 0.2  # R, max |E_i(x)| over the target box (eq. 8)
    # random-walk step of the perturbation's parameters per sample, relative to their spread:
    # 0.3 keeps a perturbation for about 23 samples (1 / ln sqrt(1 + drift^2)), 3 targets. On
    # arm5 (eta 0.1, seed 0), error after 500 epochs: drift 0.02 -> 102 mm, 0.1 -> 109,
    # 0.3 -> 35, 0.5 -> 26 mm: a perturbation held too long is learned as if it were the body
    drift: float = 0.3
    home_probability: float = 0.1  # chance of a return home after each target
    # eta of the per-sample step; on arm5 (drift 0.3, 500 epochs) 0.05 -> 38 mm, 0.1 -> 35 mm,
    # 0.2 -> 42 mm wavering 32-89 mm. The iCub's weights are smaller (normalised commands):
    # there 0.3 learns faster (40 epochs: 0.1 -> 0.12 m, 0.3 -> 0.081 m, 1.0 -> 0.087 m; 3.0
    # runs into the joint limits, 0.51 m)
    learning_rate: float = 0.1
    init_range: float = 0.1  # |g(x) - home| bound at initialisation (as Goal Babbling)
    degree: int = 3
    fast: bool = True  # the compiled per-sample loop (_train_block); False: the numpy reference
    # which targets (goal_babbling/goals.py): random (the paper's) or progress, and its settings
    goal_selection: str = "random"
    progress_period: int = 10
    progress_window: int = 3
    progress_share: float = 0.2

    def validate(self) -> "Params":
        for name in ("targets_per_epoch", "steps", "degree"):
            check_int(f"learner.{name}", getattr(self, name), 1)
        for name in ("radius", "drift", "init_range"):
            check_number(f"learner.{name}", getattr(self, name), 0.0)
        check_number("learner.learning_rate", self.learning_rate, 0.0, strict=True)
        check_number("learner.home_probability", self.home_probability, 0.0)
        if self.home_probability > 1:
            raise SpecError("learner.home_probability", self.home_probability, "must be <= 1")
        if not isinstance(self.fast, bool):
            raise SpecError("learner.fast", self.fast, "must be true or false")
        goals.check(self)
        return self


@dataclass(frozen=True)
class State:
    M: np.ndarray  # (m, p) the inverse estimate
    P: np.ndarray  # (m, n + 1) the perturbation's raw parameters [A | b]
    target: int  # index of the target last reached
    at_home: bool  # the last movement returned home: the next path starts at x_home
    last: tuple  # (x*, x, q) of the last sample, the predecessor of the next one's weight
    tracker: goals.Tracker | None = None  # the regions' errors (goal_selection=progress)


def _exps(params, body):
    return exponents(body.n, params.degree)


def init(params: Params, body, size: float, rng: np.random.Generator) -> State:
    """Goal Babbling's initial M, a random perturbation, the body at home."""
    M = init_inverse(body.home, *body.target_box(size), _exps(params, body), params.init_range,
                     rng)
    P = rng.standard_normal((body.m, body.n + 1))
    q_home = body.saturate(body.home)
    x_home = body.forward(q_home, size=size)
    tracker = None
    if params.goal_selection == "progress":
        errors = goals.reaching_errors(lambda x: predict_inverse(M, x, _exps(params, body)),
                                       body, size, np.ones(body.m))
        tracker = goals.start(body.targets).measured(errors, goals.regions(body.targets),
                                                     params.progress_window)
    return State(M, P, target=0, at_home=True, last=(x_home, x_home, q_home), tracker=tracker)


def draw(params: Params, body, B: int, rng: np.random.Generator) -> tuple:
    """Per epoch: hops to the next targets (B, K) in 1 ... N-1 (so each differs from the last),
    home coins (B, K) in [0, 1), random-walk steps (B, K L, m, n+1). With goal_selection=progress
    the first array holds uniform numbers (B, K) in [0, 1), turned into targets in train."""
    K = params.targets_per_epoch
    if params.goal_selection == "progress":
        hops = rng.uniform(0.0, 1.0, size=(B, K))
    else:
        hops = rng.integers(1, len(body.targets), size=(B, K))
    coins = rng.uniform(0.0, 1.0, size=(B, K))
    shape = (B, K * params.steps, body.m, body.n + 1)
    walk = _normals(rng, int(np.prod(shape))).reshape(shape)
    return hops, coins, walk


@njit(cache=True)
def _normals(rng, size):
    """rng.standard_normal(size), drawn by numba's Generator: numpy's algorithm on the same bit
    generator, so the same numbers and the same state after (tests/test_learners.py checks
    both), at about 7 ns a number against numpy's 16 ns on this project's machine. The random
    walk draws m (n + 1) of them per path sample, which made the draws alone cost about one
    batch epoch on arm5."""
    return rng.standard_normal(size)


def plan(state: State, params: Params, targets, x_home, hops, coins):
    """The epoch's intended positions x* (T, n), which of them are returns home (T,), and the
    state's target and at_home after it."""
    L = params.steps
    target, at_home, xs, home = state.target, state.at_home, [], []
    for hop, coin in zip(hops, coins):
        start = x_home if at_home else targets[target]
        target = (target + hop) % len(targets)
        frac = np.arange(1, L + 1)[:, None] / L
        xs.append(start + frac * (targets[target] - start))
        home += [False] * L
        at_home = coin < params.home_probability
        if at_home:
            xs.append(x_home[None])
            home.append(True)
    return np.concatenate(xs), np.array(home), target, at_home


def perturbations(P, walk, params: Params, lo, hi):
    """The perturbation of every path sample: A (T, m, n), b (T, m), and P after the walk."""
    keep = 1.0 / np.sqrt(1.0 + params.drift ** 2)
    raw = np.empty_like(walk)
    for t, step in enumerate(walk):
        P = keep * (P + params.drift * step)
        raw[t] = P
    A, b = scale_perturbations(raw, lo, hi, params.radius)
    return A, b, P


def train(state: State, params: Params, body, sizes, scales, draws, epochs=None) -> State:
    if params.goal_selection == "random":
        return _train(state, params, body, sizes, scales, draws)
    region, N = goals.regions(body.targets), len(body.targets)
    for lo, hi, measure in goals.chunks(epochs, params.progress_period):
        p = goals.probabilities(state.tracker.progress(params.progress_window), region,
                                params.progress_share)
        chosen = goals.choose(draws[0][lo:hi], p)  # (C, K) the targets, as hops from the last
        flat = np.concatenate([[state.target], chosen.ravel()])
        hops = (np.diff(flat) % N).reshape(chosen.shape)
        state = _train(state, params, body, sizes[lo:hi], scales[lo:hi],
                       (hops,) + tuple(d[lo:hi] for d in draws[1:]))
        if measure:
            errors = goals.reaching_errors(lambda x: predict(state, params, body, x), body,
                                           sizes[hi - 1], scales[hi - 1])
            state = replace(state, tracker=state.tracker.measured(errors, region,
                                                                  params.progress_window))
    return state


def _train(state: State, params: Params, body, sizes, scales, draws) -> State:
    if params.fast:
        return train_fast(state, params, body, sizes, scales, draws)
    return train_reference(state, params, body, sizes, scales, draws)


def train_reference(state: State, params: Params, body, sizes, scales, draws) -> State:
    """The epochs in plain numpy, sample by sample: the readable statement of `train`."""
    hops, coins, walk = draws
    exps = _exps(params, body)
    M, P = state.M.copy(), state.P
    for e in range(len(sizes)):
        q_home = body.saturate(body.home)
        x_home = body.forward(q_home, scale=scales[e])
        xstar, home, target, at_home = plan(state, params, body.target_set(sizes[e]), x_home,
                                            hops[e], coins[e])
        A, b, P = perturbations(P, walk[e], params, *body.target_box(sizes[e]))
        last, j = state.last, 0  # j: the next path sample's perturbation
        for xs, is_home in zip(xstar, home):
            if is_home:  # the home example, weight 1 (eq. 5)
                x, q, w = x_home, q_home, 1.0
            else:
                q = body.saturate(predict_inverse(M, xs, exps) + A[j] @ xs + b[j])
                x = body.forward(q, scale=scales[e])
                w = sample_weights(*(np.stack([a, c]) for a, c in zip(last, (xs, x, q))))[1]
                j += 1
            phi = features(x, exps)
            M -= (params.learning_rate * w) * np.outer(M @ phi - q, phi)
            last = (xs, x, q)
        state = State(M, P, target, at_home, last, state.tracker)
    return replace(state, M=M.copy())


# ---- the fast path: the same per-sample loop, compiled ------------------------------------------
# Plain float64, sequential: every sum runs in a fixed order (first term first), nothing is
# compiled with fastmath (no reassociation, no fused multiply-adds), so the results do not depend
# on the CPU's vector width; sin and cos are its own (_sincos), not the C library's. They differ
# from the numpy path's only by rounding, where numpy (or its BLAS) sums in another order or
# calls its own sin and cos.
_ARRAYS: dict = {}  # (id(body), degree) -> (body, arrays); the body kept so its id stays its own


def _kernel_arrays(body, params: Params) -> tuple:
    """(chain, joints, parent, coord) for the kernels: built once per body object (bodies are
    frozen) and degree, not at every call (a trial calls train and distances ~100 times)."""
    key = (id(body), params.degree)
    hit = _ARRAYS.get(key)
    if hit is None or hit[0] is not body:
        if len(_ARRAYS) >= 32:
            _ARRAYS.clear()
        hit = _ARRAYS[key] = (body, _body_arrays(body) + _parents(_exps(params, body)))
    return hit[1]


def _body_arrays(body) -> tuple:
    """The body as the kernel takes it, float64: the full-size chain (a, d, cos alpha, sin
    alpha, base, outputs, ty, R, general: the layout of goal_babbling's kernel, DH rows or a
    URDF's general chain) and the joint map (normalized, saturates, q_min, q_max - q_min,
    theta_offset)."""
    f8 = lambda x: np.ascontiguousarray(x, np.float64)  # noqa: E731
    full = kernel_chain(body)  # at full size: the kernel scales the translations epoch by epoch
    chain = tuple(f8(full[k]) for k in ("a", "d", "cos_alpha", "sin_alpha", "base")) \
        + (np.array(body.outputs, np.int64), f8(full["ty"]), f8(full["R"]),
           bool(full["general"]))
    normalized, zeros = body.normalized, np.zeros(body.m)
    joints = (normalized, bool(body.saturates), f8(body.q_min if normalized else zeros),
              f8(body.q_max - body.q_min if normalized else zeros), f8(body.theta_offset))
    return chain, joints


@njit(cache=True)
def _saturate(q, normalized, saturates):
    """body.saturate in place: clip to [-1, 1] (a NaN stays NaN)."""
    if normalized and saturates:
        for i in range(len(q)):
            if q[i] > 1.0:
                q[i] = 1.0
            elif q[i] < -1.0:
                q[i] = -1.0


# sin and cos of a joint angle: Cephes' double-precision kernels (sin.c: |r| <= pi/4) after a
# Cody-Waite reduction x = k pi/2 + r with pi/2 in three parts (the first two with trailing zero
# bits, so k times them is exact for |k| < 2^24), then the quadrant k mod 4 swaps and negates
# them. Plain float64 operations in a fixed order: the same result on every CPU and C library,
# within 2 ulp of the C library's (tests/test_learners.py). Inlined, and without a branch but the
# (always taken) range check, a pair costs 8.5 ns against the C library's 19.7 ns for sin and cos
# of independent angles on this project's machine: the kinematics of each sample (m pairs) were
# the loop's largest part.
_PIO2 = (1.57079625129699707031e0, 7.54978941586159635335e-8, 5.39030285815811905290e-15)
_ROUND = 6755399441055744.0  # 1.5 * 2^52: x + _ROUND - _ROUND rounds x to an integer
_SIN = (1.58962301576546568060e-10, -2.50507477628578072866e-8, 2.75573136213857245213e-6,
        -1.98412698295895385996e-4, 8.33333333332211858878e-3, -1.66666666666666307295e-1)
_COS = (-1.13585365213876817300e-11, 2.08757008419747316778e-9, -2.75573141792967388112e-7,
        2.48015872888517045348e-5, -1.38888888888730564116e-3, 4.16666666666665929218e-2)


@njit(cache=True)
def _sincos(x):
    """(sin x, cos x): the polynomials for |x| < 2^24, the C library beyond (a diverging
    command, NaN or inf: never a joint angle of a learning trial)."""
    if not abs(x) < 16777216.0:
        return np.sin(x), np.cos(x)
    k = (x * 0.63661977236758134308 + _ROUND) - _ROUND  # nearest integer to x / (pi/2)
    r = ((x - k * _PIO2[0]) - k * _PIO2[1]) - k * _PIO2[2]
    z = r * r
    ps = ((((_SIN[0] * z + _SIN[1]) * z + _SIN[2]) * z + _SIN[3]) * z + _SIN[4]) * z + _SIN[5]
    pc = ((((_COS[0] * z + _COS[1]) * z + _COS[2]) * z + _COS[3]) * z + _COS[4]) * z + _COS[5]
    s = r + r * z * ps
    c = (1.0 - 0.5 * z) + z * z * pc
    # quadrant 0: (s, c), 1: (c, -s), 2: (-s, -c), 3: (-c, s), without a branch (the angles'
    # quadrants are unpredictable): a swap by select, signs by exact products with +-1.
    quadrant = int(k) & 3
    swap = quadrant & 1
    a = c if swap else s
    b = s if swap else c
    return a * (1 - (quadrant & 2)), b * (1 - ((quadrant + 1) & 2))


@njit(cache=True)
def _forward(q, scale, chain, joints, out):
    """body.forward(q, scale=scale) into out (n,): the hand point carried backwards through the
    DH chain (gbmodel.kinematics.hand_position), operation by operation, or through a general
    chain (chain_position: p <- Rz(theta_i) (R_i p + (a, ty, d)_i), then the base)."""
    a, d, ca, sa, base, outputs, ty, R, general = chain
    normalized, _, q_min, q_span, offset = joints
    px = py = pz = 0.0
    for i in range(len(q) - 1, -1, -1):
        if normalized:
            theta = q_min[i] + 0.5 * (q[i] + 1.0) * q_span[i]
        else:
            theta = q[i]
        theta = theta + offset[i]
        if general:
            u = R[i, 0, 0] * px + R[i, 0, 1] * py + R[i, 0, 2] * pz + a[i] * scale[i]
            v = R[i, 1, 0] * px + R[i, 1, 1] * py + R[i, 1, 2] * pz + ty[i] * scale[i]
            w = R[i, 2, 0] * px + R[i, 2, 1] * py + R[i, 2, 2] * pz + d[i] * scale[i]
        else:
            u = px + a[i] * scale[i]
            v = ca[i] * py - sa[i] * pz
            w = sa[i] * py + ca[i] * pz + d[i] * scale[i]
        s, c = _sincos(theta)
        px, py, pz = c * u - s * v, s * u + c * v, w
    for j in range(len(outputs)):
        o = outputs[j]
        out[j] = px * base[o, 0] + py * base[o, 1] + pz * base[o, 2] + base[o, 3]


@njit(cache=True)
def _weight(lxs, lx, lq, xs, x, q):
    """sample_weights(...)[1]: w_dir * w_eff of sample (xs, x, q) against its predecessor."""
    sxs = sx = sq = dot = 0.0
    for j in range(len(xs)):
        dxs, dx = xs[j] - lxs[j], x[j] - lx[j]
        sxs += dxs * dxs
        sx += dx * dx
        dot += dxs * dx
    for i in range(len(q)):
        dq = q[i] - lq[i]
        sq += dq * dq
    nxs, nx, nq = np.sqrt(sxs), np.sqrt(sx), np.sqrt(sq)
    denom = nxs * nx
    cos = dot / denom if denom > 0 else 0.0
    if cos > 1.0:
        cos = 1.0
    elif cos < -1.0:
        cos = -1.0
    w_dir = 0.5 * (1.0 + cos) if nxs > NO_MOVEMENT else 0.0
    w_eff = nx / nq if nq > 0 else 0.0
    return w_dir * w_eff


def _parents(exps) -> tuple:
    """Per monomial k > 0 (rows of exps are ordered by total degree): a monomial of one degree
    less (parent[k]) and the coordinate (coord[k]) that multiplies it to give k, so that
    Phi_k = Phi_parent[k] * x_coord[k], one multiplication per feature."""
    rows = {tuple(e): k for k, e in enumerate(exps.tolist())}
    parent, coord = np.zeros(len(exps), np.int64), np.zeros(len(exps), np.int64)
    for k, e in enumerate(exps.tolist()[1:], start=1):
        j = max(i for i, v in enumerate(e) if v > 0)  # the last coordinate in it
        parent[k], coord[k] = rows[tuple(v - (i == j) for i, v in enumerate(e))], j
    return parent, coord


@njit(cache=True)
def _features_tree(x, parent, coord, phi):
    """Phi(x) into phi (p,): each monomial its parent times one coordinate (phi[0] = 1)."""
    phi[0] = 1.0
    for k in range(1, len(phi)):
        phi[k] = phi[parent[k]] * x[coord[k]]


# ---- float64 vectors over the entries of M -----------------------------------------------------
# The per-sample work on M (the residual M Phi - q, the step, the next prediction) runs on
# explicit 8-lane float64 vectors (LLVM <8 x double>: one zmm register, two ymm or four xmm
# halves), one lane per row of M, columns of M^T padded to a multiple of 8 rows: every lane's sum
# runs over k in order, with separate roundings of * and + (no fused multiply-add), so a lane
# computes exactly what the scalar loop computes, whatever the CPU's vector width. These are the
# float64 siblings of goal_babbling/fast.py's float32 primitives (vload, vstore, vsplat, vadd,
# vsub, vmul), named with a trailing 8; they would move beside them (gbmodel/simd.py) unchanged.
W8 = 8
_VEC8 = ir.VectorType(ir.DoubleType(), W8)


class F64x8Type(types.Type):
    """LLVM <8 x double>."""

    def __init__(self):
        super().__init__(name="F64x8")


F64x8 = F64x8Type()


@register_model(F64x8Type)
class _F64x8Model(models.PrimitiveModel):
    def __init__(self, dmm, fe_type):
        super().__init__(dmm, fe_type, _VEC8)


def _pointer8(context, builder, sig, args, n):
    """Address of element args[1:1 + n] of the float64 array args[0], as a vector pointer."""
    aryty = sig.args[0]
    inds = [context.cast(builder, v, t, types.intp) for v, t in zip(args[1:1 + n],
                                                                    sig.args[1:1 + n])]
    ptr = cgutils.get_item_pointer(context, builder, aryty,
                                   context.make_array(aryty)(context, builder, args[0]), inds)
    return builder.bitcast(ptr, _VEC8.as_pointer())


@intrinsic
def vload8(typingctx, a, k, i):
    """a[k, i:i + 8] of a 2-d float64 array with contiguous rows (no bounds check)."""
    def codegen(context, builder, sig, args):
        return builder.load(_pointer8(context, builder, sig, args, 2), align=8)
    return F64x8(a, k, i), codegen


@intrinsic
def vstore8(typingctx, a, k, i, v):
    """a[k, i:i + 8] = v."""
    def codegen(context, builder, sig, args):
        builder.store(args[3], _pointer8(context, builder, sig, args, 2), align=8)
        return context.get_dummy_value()
    return types.none(a, k, i, v), codegen


@intrinsic
def vload18(typingctx, a, i):
    """a[i:i + 8] of a contiguous 1-d float64 array (no bounds check)."""
    def codegen(context, builder, sig, args):
        return builder.load(_pointer8(context, builder, sig, args, 1), align=8)
    return F64x8(a, i), codegen


@intrinsic
def vstore18(typingctx, a, i, v):
    """a[i:i + 8] = v."""
    def codegen(context, builder, sig, args):
        builder.store(args[2], _pointer8(context, builder, sig, args, 1), align=8)
        return context.get_dummy_value()
    return types.none(a, i, v), codegen


@intrinsic
def vsplat8(typingctx, x):
    """Every lane x (as float64)."""
    def codegen(context, builder, sig, args):
        x = context.cast(builder, args[0], sig.args[0], types.float64)
        v = builder.insert_element(ir.Constant(_VEC8, ir.Undefined), x,
                                   ir.Constant(ir.IntType(32), 0))
        return builder.shuffle_vector(v, v, ir.Constant(ir.VectorType(ir.IntType(32), W8),
                                                         [0] * W8))
    return F64x8(x), codegen


@intrinsic
def vadd8(typingctx, a, b):
    return F64x8(a, b), lambda context, builder, sig, args: builder.fadd(*args)


@intrinsic
def vsub8(typingctx, a, b):
    return F64x8(a, b), lambda context, builder, sig, args: builder.fsub(*args)


@intrinsic
def vmul8(typingctx, a, b):
    return F64x8(a, b), lambda context, builder, sig, args: builder.fmul(*args)


@njit(cache=True)
def _predict_rows(MT, phi, g):
    """g = M Phi (g padded to MT's W columns), M stored transposed and padded, MT (p, W): lane i
    of block j sums M[8 j + i, k] Phi_k over k in order."""
    p, W = MT.shape
    for j in range(0, W, W8):
        acc = vsplat8(0.0)
        for k in range(p):
            acc = vadd8(acc, vmul8(vload8(MT, k, j), vsplat8(phi[k])))
        vstore18(g, j, acc)


@njit(cache=True)
def _step_predict(MT, phi, sr, psi, g, predict):
    """The step M <- M - (eta w r) Phi^T (sr = eta w r, padded with zeros), in place on M^T,
    and, in the same pass over M, the next sample's prediction g = M_new Psi when `predict`
    (Psi: its features): one pass over M per sample instead of two, every entry's update and
    every sum in the order of a separate update followed by a separate prediction."""
    p, W = MT.shape
    for j in range(0, W, W8):
        s = vload18(sr, j)
        acc = vsplat8(0.0)
        for k in range(p):
            v = vsub8(vload8(MT, k, j), vmul8(s, vsplat8(phi[k])))
            vstore8(MT, k, j, v)
            if predict:
                acc = vadd8(acc, vmul8(v, vsplat8(psi[k])))
        if predict:
            vstore18(g, j, acc)


@njit(cache=True)
def _train_block(MT, P, lxs, lx, lq, target, at_home, hops, coins, walk, sizes, scales, targets,
                 q_home, chain, joints, parent, coord, steps, radius, drift, keep,
                 home_probability, learning_rate):
    """train_reference's epochs: M^T (p, W) (padded with zero columns), P and the last sample (lxs, lx, lq) updated in
    place; returns the target last reached and whether the last movement returned home.

    Per epoch, the intended positions x* and the returns home are laid out first (the reference's
    `plan`), so that each sample's step can compute the next sample's prediction on its way."""
    p, W = MT.shape
    m = P.shape[0]
    n = targets.shape[1]
    N = targets.shape[0]
    K = hops.shape[1]
    normalized, saturates = joints[0], joints[1]
    phi, psi, r, sr, g = np.empty(p), np.empty(p), np.empty(W), np.zeros(W), np.empty(W)
    x_home, start = np.empty(n), np.empty(n)
    lo, hi, c, h = np.empty(n), np.empty(n), np.empty(n), np.empty(n)
    A, b = np.empty((m, n)), np.empty(m)
    x, q = np.empty(n), np.empty(m)
    xstar = np.empty((K * (steps + 1), n))
    home = np.zeros(K * (steps + 1), np.bool_)
    for e in range(len(sizes)):
        size, scale = sizes[e], scales[e]
        _forward(q_home, scale, chain, joints, x_home)
        for j in range(n):  # the target box at this size
            lo[j] = hi[j] = targets[0, j] * size
            for t in range(1, N):
                v = targets[t, j] * size
                lo[j] = min(lo[j], v)
                hi[j] = max(hi[j], v)
            c[j], h[j] = 0.5 * (lo[j] + hi[j]), 0.5 * (hi[j] - lo[j])
        T = 0  # the epoch's plan: x* of every sample, and which are returns home
        for kk in range(K):
            for j in range(n):
                start[j] = x_home[j] if at_home else targets[target, j] * size
            target = (target + hops[e, kk]) % N
            for l in range(1, steps + 1):
                frac = l / steps
                for j in range(n):
                    xstar[T, j] = start[j] + frac * (targets[target, j] * size - start[j])
                home[T] = False
                T += 1
            at_home = coins[e, kk] < home_probability
            if at_home:
                xstar[T] = x_home
                home[T] = True
                T += 1
        s = 0  # the path sample: its step of the random walk
        _features_tree(xstar[0], parent, coord, psi)  # the first sample is a path sample
        _predict_rows(MT, psi, g)
        for t in range(T):
            if home[t]:  # the home example, weight 1 (eq. 5)
                for j in range(n):
                    x[j] = x_home[j]
                for i in range(m):
                    q[i] = q_home[i]
                w = 1.0
            else:
                xs = xstar[t]
                # the perturbation: a random-walk step of P, each row scaled to peak at R
                for i in range(m):
                    for j in range(n + 1):
                        P[i, j] = keep * (P[i, j] + drift * walk[e, s, i, j])
                    Ac, Ah = 0.0, 0.0
                    for j in range(n):
                        Ac += P[i, j] * c[j]
                        Ah += abs(P[i, j]) * h[j]
                    k = radius / (abs(Ac + P[i, n]) + Ah)
                    for j in range(n):
                        A[i, j] = P[i, j] * k
                    b[i] = P[i, n] * k
                # the movement: q = saturate(g(x*) + A x* + b), x = f(q); g(x*) came with the
                # previous step (or before the first sample)
                for i in range(m):
                    Ax = 0.0
                    for j in range(n):
                        Ax += A[i, j] * xs[j]
                    q[i] = g[i] + Ax + b[i]
                _saturate(q, normalized, saturates)
                _forward(q, scale, chain, joints, x)
                w = _weight(lxs, lx, lq, xs, x, q)
                s += 1
            _features_tree(x, parent, coord, phi)
            _predict_rows(MT, phi, r)  # the residual M Phi(x) - q, times eta w
            for i in range(m):
                sr[i] = (learning_rate * w) * (r[i] - q[i])
            nxt = t + 1 < T and not home[t + 1]
            if nxt:
                _features_tree(xstar[t + 1], parent, coord, psi)
            _step_predict(MT, phi, sr, psi, g, nxt)
            for j in range(n):
                lxs[j], lx[j] = xstar[t, j], x[j]
            for i in range(m):
                lq[i] = q[i]
    return target, at_home


def train_fast(state: State, params: Params, body, sizes, scales, draws) -> State:
    """train on the compiled path: the same epochs, with the same draws, as train_reference."""
    hops, coins, walk = draws
    f8 = lambda x: np.array(x, dtype=np.float64, order="C")  # noqa: E731 (copies)
    m, p = state.M.shape
    MT = np.zeros((p, -(-m // W8) * W8))  # M^T, padded to whole vectors with zeros
    MT[:, :m] = state.M.T
    P = f8(state.P)
    lxs, lx, lq = (f8(a) for a in state.last)
    chain, joints, parent, coord = _kernel_arrays(body, params)
    target, at_home = _train_block(
        MT, P, lxs, lx, lq, int(state.target), bool(state.at_home),
        np.ascontiguousarray(hops, np.int64), np.ascontiguousarray(coins, np.float64),
        np.ascontiguousarray(walk, np.float64), np.ascontiguousarray(sizes, np.float64),
        np.ascontiguousarray(scales, np.float64).reshape(len(sizes), body.m),
        np.ascontiguousarray(body.targets, np.float64), f8(body.saturate(body.home)), chain,
        joints, parent, coord, int(params.steps), float(params.radius), float(params.drift),
        1.0 / np.sqrt(1.0 + params.drift ** 2), float(params.home_probability),
        float(params.learning_rate))
    return State(np.ascontiguousarray(MT[:, :m].T), P, int(target), bool(at_home), (lxs, lx, lq),
                 state.tracker)


def predict(state: State, params: Params, body, x) -> np.ndarray:
    return predict_inverse(state.M, x, _exps(params, body))


def distances(state: State, params: Params, body, scale, xs) -> np.ndarray:
    """|f(g(x*)) - x*| per point (rows of xs), the body at per-joint factors `scale`: on the
    fast path by `_distances` (the kernel's float64 features, prediction and kinematics, every
    sum in order), else by the shared numpy evaluation; they agree to rounding."""
    if not params.fast:
        return evaluation.distances(lambda x: predict(state, params, body, x), body, scale, xs)
    chain, joints, parent, coord = _kernel_arrays(body, params)
    out = np.empty(len(xs))
    _distances(np.ascontiguousarray(state.M, np.float64), np.ascontiguousarray(xs, np.float64),
               np.ascontiguousarray(scale, np.float64).reshape(body.m), chain, joints, parent,
               coord, out)
    return out


@njit(cache=True)
def _distances(M, xs, scale, chain, joints, parent, coord, out):
    """out[t] = |f(saturate(M Phi(xs[t]))) - xs[t]|, f the body at per-joint factors scale."""
    m, p = M.shape
    n = xs.shape[1]
    phi, q, x = np.empty(p), np.empty(m), np.empty(n)
    for t in range(len(xs)):
        _features_tree(xs[t], parent, coord, phi)
        for i in range(m):
            g = 0.0
            for k in range(p):
                g += M[i, k] * phi[k]
            q[i] = g
        _saturate(q, joints[0], joints[1])
        _forward(q, scale, chain, joints, x)
        d = 0.0
        for j in range(n):
            d += (x[j] - xs[t, j]) ** 2
        out[t] = np.sqrt(d)


def model(state: State) -> np.ndarray:
    return np.array(state.M, copy=True)


def samples_per_epoch(params: Params, body) -> int:
    """K L path samples plus the returns home, K home_probability in expectation (rounded)."""
    K = params.targets_per_epoch
    extra = goals.samples(body, params.progress_period) if params.goal_selection == "progress" \
        else 0
    return int(round(K * (params.steps + params.home_probability))) + extra
