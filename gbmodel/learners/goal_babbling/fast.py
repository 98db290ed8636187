"""The fast path of Goal Babbling: whole blocks of epochs in one compiled (numba) call.

It computes what `reference.py` states, epoch by epoch and with the same random numbers, in
float32 loops over the N samples of an epoch that the compiler vectorises:

- samples are laid out variation-major, one block of Bv columns per variation: column 0 the home
  example, columns 1 ... T the path, and the rest up to a multiple of LANES padding (the home
  posture again, weight 0, so it adds exactly nothing); the weight of a sample only looks at the
  column before it;
- the variations are processed in groups of about _GROUP columns (rollout, weights, features,
  residuals, gradient), so that a group's arrays stay in the L1/L2 cache;
- the rollout runs in float32; M stays float64 and is updated once per epoch. Positions agree
  with the float64 reference to ~1e-6 m (tests/test_fast.py states the tolerances);
- the hand is carried backwards through the DH chain, one rotation about z per joint, from
  separate input and output arrays (an in-place update defeats the compiler's alias analysis);
- sin and cos are a branch-free polynomial (fdlibm's kernels after a Cody-Waite reduction), which
  vectorises where libm's sinf/cosf would be one scalar call per element;
- features are built monomial by monomial, each a parent monomial times one coordinate.

Bit-identical results on every x86-64 CPU with AVX2 and FMA, with or without AVX-512 (tested by
tests/test_kernel_targets.py): the compiler may not reassociate floating-point sums (no
`reassoc`, so the order of a sum never depends on the vector width of the CPU) nor use
approximate reciprocals (no `arcp`); every sum over samples (the gradient, sum w) is written with
explicit LANES-wide vector accumulators (`F32x16` below, LLVM <16 x float>, which a CPU without
AVX-512 runs as two 8-wide halves with the same result), added up in a fixed order at the end;
multiply-adds of those sums are explicit fused multiply-adds (llvm.fma). Elementwise loops are
left to the vectoriser with `contract` (a * b + c may become one fused multiply-add, the same
on every FMA CPU). No threads.
"""
from __future__ import annotations

import numba
import numpy as np
from llvmlite import ir
from numba import njit, types
from numba.core import cgutils
from numba.extending import intrinsic, models, register_model

from .reference import NO_MOVEMENT


def _prefer_wide_vectors():
    """Let LLVM use full 512-bit vectors where the CPU has them.

    LLVM tunes AVX-512 CPUs to prefer 256-bit vectors; the elementwise loops here are long,
    regular and float32 and run faster on 16 lanes. This sets numba's CPU features for the
    process, before anything is compiled, and only if nobody else has. Results do not depend on
    it (no sum is reassociated; tests/test_kernel_targets.py), only speed does.
    """
    import llvmlite.binding as ll

    if numba.config.CPU_FEATURES is None:
        features = ll.get_host_cpu_features().flatten()
        if "+avx512f" in features.split(","):
            numba.config.CPU_FEATURES = features + ",-prefer-256-bit"


_prefer_wide_vectors()

F4 = np.float32
# `contract` only: no reassociation, no approximate reciprocals, no NaN/inf assumptions (a
# diverging learner stays visible)
_FLAGS = {"contract"}
LANES = 16  # width of the explicit vector accumulators (F32x16)
_GROUP = 512  # columns (samples) per group of variations: the group's arrays stay in cache
_TILE = 5  # rows x columns of a register tile of the gradient (m = 5, 10; p = 10, 20)

# ---- explicit float32 vectors: LANES lanes, each lane a sum in a fixed order -------------------
_VEC = ir.VectorType(ir.FloatType(), LANES)


class F32x16Type(types.Type):
    """LLVM <16 x float>: a value in vector registers (one zmm, or two ymm without AVX-512)."""

    def __init__(self):
        super().__init__(name="F32x16")


F32x16 = F32x16Type()


@register_model(F32x16Type)
class _F32x16Model(models.PrimitiveModel):
    def __init__(self, dmm, fe_type):
        super().__init__(dmm, fe_type, _VEC)


def _address(context, builder, aryty, ary, inds):
    inds = [context.cast(builder, i, t, types.intp) for i, t in inds]
    ptr = cgutils.get_item_pointer(context, builder, aryty,
                                   context.make_array(aryty)(context, builder, ary), inds)
    return builder.bitcast(ptr, _VEC.as_pointer())


@intrinsic
def vload(typingctx, a, k, i):
    """a[k, i:i + LANES] of a 2-d float32 array whose rows are contiguous (no bounds check)."""
    def codegen(context, builder, sig, args):
        ptr = _address(context, builder, sig.args[0], args[0],
                       [(args[1], sig.args[1]), (args[2], sig.args[2])])
        return builder.load(ptr, align=4)
    return F32x16(a, k, i), codegen


@intrinsic
def vload1(typingctx, a, i):
    """a[i:i + LANES] of a contiguous 1-d float32 array (no bounds check)."""
    def codegen(context, builder, sig, args):
        ptr = _address(context, builder, sig.args[0], args[0], [(args[1], sig.args[1])])
        return builder.load(ptr, align=4)
    return F32x16(a, i), codegen


@intrinsic
def vstore(typingctx, a, k, i, v):
    """a[k, i:i + LANES] = v."""
    def codegen(context, builder, sig, args):
        ptr = _address(context, builder, sig.args[0], args[0],
                       [(args[1], sig.args[1]), (args[2], sig.args[2])])
        builder.store(args[3], ptr, align=4)
        return context.get_dummy_value()
    return types.none(a, k, i, v), codegen


@intrinsic
def vsplat(typingctx, x):
    """Every lane x (a float32)."""
    def codegen(context, builder, sig, args):
        x = context.cast(builder, args[0], sig.args[0], types.float32)
        v = builder.insert_element(ir.Constant(_VEC, ir.Undefined), x, ir.Constant(ir.IntType(32), 0))
        return builder.shuffle_vector(v, v, ir.Constant(ir.VectorType(ir.IntType(32), LANES),
                                                         [0] * LANES))
    return F32x16(x), codegen


@intrinsic
def vzero(typingctx):
    def codegen(context, builder, sig, args):
        return ir.Constant(_VEC, [0.0] * LANES)
    return F32x16(), codegen


@intrinsic
def vfma(typingctx, a, b, c):
    """a * b + c, rounded once (llvm.fma: one instruction on every FMA CPU)."""
    def codegen(context, builder, sig, args):
        fn = cgutils.get_or_insert_function(builder.module, ir.FunctionType(_VEC, [_VEC] * 3),
                                            "llvm.fma.v16f32")
        return builder.call(fn, args)
    return F32x16(a, b, c), codegen


def _binary(op):
    @intrinsic
    def vop(typingctx, a, b):
        def codegen(context, builder, sig, args):
            return getattr(builder, op)(*args)
        return F32x16(a, b), codegen
    return vop


vadd, vsub, vmul = _binary("fadd"), _binary("fsub"), _binary("fmul")


@intrinsic
def vsum(typingctx, v):
    """The lanes' sum in float64, lane 0 first."""
    def codegen(context, builder, sig, args):
        total = ir.Constant(ir.DoubleType(), 0.0)
        for lane in range(LANES):
            x = builder.extract_element(args[0], ir.Constant(ir.IntType(32), lane))
            total = builder.fadd(total, builder.fpext(x, ir.DoubleType()))
        return total
    return types.float64(v), codegen


# ---- kinematics --------------------------------------------------------------------------------
_0, _HALF, _1, _2, _QUARTER, _4 = F4(0.0), F4(0.5), F4(1.0), F4(2.0), F4(0.25), F4(4.0)
# fdlibm's kernel coefficients for sin and cos on [-pi/4, pi/4], to float precision
_S1, _S2 = F4(-1.66666666666666324348e-01), F4(8.33333333332248946124e-03)
_S3, _S4 = F4(-1.98412698298579493134e-04), F4(2.75573137070700676789e-06)
_C1, _C2 = F4(4.16666666666666019037e-02), F4(-1.38888888888741095749e-03)
_C3, _C4 = F4(2.48015872894767294178e-05), F4(-2.75573143513906633035e-07)
_TWO_OVER_PI = F4(6.36619772367581382433e-01)
_PIO2_HI, _PIO2_LO = F4(1.5707963705062866), F4(-4.371139000186243e-08)  # pi/2 = HI + LO


@njit(fastmath=_FLAGS, inline="always", cache=True)
def sincos(x):
    """(sin x, cos x) of a float32, within 2e-6 for |x| < 10 (joint angles), branch-free."""
    k = np.floor(x * _TWO_OVER_PI + _HALF)
    r = (x - k * _PIO2_HI) - k * _PIO2_LO
    z = r * r
    s = r + r * z * (_S1 + z * (_S2 + z * (_S3 + z * _S4)))
    c = _1 - _HALF * z + z * z * (_C1 + z * (_C2 + z * (_C3 + z * _C4)))
    # quadrant 0..3: swap sin and cos in odd quadrants, then fix the signs, all by arithmetic
    quadrant = k - _4 * np.floor(_QUARTER * k)
    odd = quadrant - _2 * np.floor(_HALF * quadrant)
    upper = np.floor(_HALF * quadrant)  # quadrants 2, 3
    sn = (s + odd * (c - s)) * (_1 - _2 * upper)
    cs = (c + odd * (s - c)) * (_1 - _2 * np.abs(odd - upper))
    return sn, cs


@njit(fastmath=_FLAGS, cache=True)
def _angles(Q, c0, C, joints, theta):
    """Saturate commands Q[:, c0:c0 + C] in place (if the body does) and turn them into DH joint
    angles theta[:, :C]: theta = offset + lo + (q + 1) / 2 * span, or offset + q."""
    normalized, saturates, q_lo, q_span, offset = joints
    for i in range(Q.shape[0]):
        qi, ti = Q[i, c0:c0 + C], theta[i, :C]
        if normalized:
            lo, span, off = q_lo[i], q_span[i], offset[i]
            if saturates:
                for r in range(C):
                    qi[r] = min(max(qi[r], -_1), _1)
            for r in range(C):
                ti[r] = off + lo + _HALF * (qi[r] + _1) * span
        else:
            off = offset[i]
            for r in range(C):
                ti[r] = off + qi[r]


@njit(fastmath=_FLAGS, cache=True)
def _joint(theta, a, d, ca, sa, px, py, pz, qx, qy, qz):
    """(qx, qy, qz) = A_i (px, py, pz) for one joint over all samples."""
    for r in range(len(theta)):
        u = px[r] + a
        v = ca * py[r] - sa * pz[r]
        w = sa * py[r] + ca * pz[r] + d
        s, c = sincos(theta[r])
        qx[r] = c * u - s * v
        qy[r] = s * u + c * v
        qz[r] = w


@njit(fastmath=_FLAGS, cache=True)
def _forward(theta, C, body, X, c0, P0, P1):
    """Hand positions X[:, c0:c0 + C] of joint angles theta[:, :C]; P0, P1 are (3, >= C) work
    arrays."""
    a, d, ca, sa, base, outputs = body
    P0[:, :C] = _0
    for i in range(theta.shape[0] - 1, -1, -1):
        _joint(theta[i, :C], a[i], d[i], ca[i], sa[i], P0[0, :C], P0[1, :C], P0[2, :C],
               P1[0, :C], P1[1, :C], P1[2, :C])
        P0, P1 = P1, P0
    for j in range(len(outputs)):
        o = outputs[j]
        b0, b1, b2, b3 = base[o, 0], base[o, 1], base[o, 2], base[o, 3]
        xj, p0, p1, p2 = X[j, c0:c0 + C], P0[0], P0[1], P0[2]
        for r in range(C):
            xj[r] = b0 * p0[r] + b1 * p1[r] + b2 * p2[r] + b3


@njit(fastmath=_FLAGS, cache=True)
def _features(X, c0, C, parent, var, Phi):
    """Phi[:, :C] of X[:, c0:c0 + C]: monomial k = monomial parent[k] * x[var[k]], the constant
    first."""
    Phi[0, :C] = _1
    for k in range(1, Phi.shape[0]):
        src, x, dst = Phi[parent[k], :C], X[var[k], c0:c0 + C], Phi[k, :C]
        for r in range(C):
            dst[r] = src[r] * x[r]


@njit(fastmath=_FLAGS, cache=True)
def _matmul(M, Phi, out):
    """out (m, N) = M (m, p) Phi (p, N), float32, summed over k in order."""
    for i in range(M.shape[0]):
        oi = out[i]
        oi[:] = _0
        for k in range(M.shape[1]):
            mik, pk = M[i, k], Phi[k]
            for r in range(len(oi)):
                oi[r] += mik * pk[r]


# ---- one epoch ---------------------------------------------------------------------------------
@njit(fastmath=_FLAGS, cache=True)
def _disturbances(raw, s, centre, half, radius, A, b):
    """Eq. 8: rows of [A | b] scaled so that max |A_i x + b_i| = radius over the target box
    (float64; stored as float32)."""
    m, n = A.shape
    for i in range(m):
        at_centre = raw[i, n]
        spread = 0.0
        for j in range(n):
            at_centre += raw[i, j] * s * centre[j]
            spread += abs(raw[i, j]) * s * half[j]
        k_i = radius / (abs(at_centre) + spread)
        for j in range(n):
            A[i, j] = raw[i, j] * k_i
        b[i] = raw[i, n] * k_i


@njit(fastmath=_FLAGS, cache=True)
def _commands(gpath, path, A, b, home, r0, Bv, Q):
    """Commands of one variation in Q[:, r0:r0 + Bv]: home, g + A x* + b along the path, home
    again as padding."""
    m, T = gpath.shape
    for i in range(m):
        qi, gi, bi = Q[i, r0:r0 + Bv], gpath[i], b[i]
        qi[0] = home[i]
        for t in range(T):
            qi[1 + t] = gi[t] + bi
        for j in range(path.shape[0]):
            aij, pj = A[i, j], path[j]
            for t in range(T):
                qi[1 + t] += aij * pj[t]
        for t in range(T + 1, Bv):
            qi[t] = home[i]


@njit(fastmath=_FLAGS, cache=True)
def _weights(path, dxs, nxs, X, Q, r0, Bv, w, tmp):
    """w_dir * w_eff (eq. 1-3) of every column of one variation against the column before; the
    home column weighs 1 (eq. 5), the padding 0. dxs, nxs: the intended steps and their squared
    lengths (the same for every variation); the first starts at the home position."""
    n, T = dxs.shape
    no_move2 = F4(NO_MOVEMENT * NO_MOVEMENT)
    nxs[0] = _0
    for j in range(n):
        dxs[j, 0] = path[j, 0] - X[j, r0]
        nxs[0] += dxs[j, 0] * dxs[j, 0]
    dot, nx, nq = tmp[0], tmp[1], tmp[2]
    dot[:] = _0
    nx[:] = _0
    nq[:] = _0
    for j in range(n):
        xj, dj = X[j, r0:r0 + T + 1], dxs[j]
        for t in range(T):
            dx = xj[t + 1] - xj[t]
            dot[t] += dj[t] * dx
            nx[t] += dx * dx
    for i in range(Q.shape[0]):
        qi = Q[i, r0:r0 + T + 1]
        for t in range(T):
            dq = qi[t + 1] - qi[t]
            nq[t] += dq * dq
    wv = w[r0 + 1:r0 + T + 1]
    for t in range(T):
        den = np.sqrt(nxs[t] * nx[t])
        cos = dot[t] / den if den > _0 else _0
        w_dir = _HALF * (_1 + min(max(cos, -_1), _1)) if nxs[t] > no_move2 else _0
        w_eff = np.sqrt(nx[t] / nq[t]) if nq[t] > _0 else _0
        wv[t] = w_dir * w_eff
    w[r0] = _1
    w[r0 + T + 1:r0 + Bv] = _0


@njit(cache=True)
def _lane_sum(w, c0, C):
    """sum w[c0:c0 + C] (C a multiple of LANES): LANES partial sums, then lane by lane."""
    acc = vzero()
    for c in range(c0, c0 + C, LANES):
        acc = vadd(acc, vload1(w, c))
    return vsum(acc)


@njit(cache=True)
def _residual(M32, Phi, Q, w, c0, C, Rw):
    """Rw[i, c] = w (M Phi - q) of the columns c0 + c, c < C (a multiple of LANES): rows in
    tiles of _TILE, the tile's LANES columns in registers while k runs."""
    m, p = M32.shape
    mt = m - m % _TILE
    for i in range(0, mt, _TILE):
        for c in range(0, C, LANES):
            f = vload(Phi, 0, c)
            a0, a1 = vmul(vsplat(M32[i, 0]), f), vmul(vsplat(M32[i + 1, 0]), f)
            a2, a3 = vmul(vsplat(M32[i + 2, 0]), f), vmul(vsplat(M32[i + 3, 0]), f)
            a4 = vmul(vsplat(M32[i + 4, 0]), f)
            for k in range(1, p):
                f = vload(Phi, k, c)
                a0 = vfma(vsplat(M32[i, k]), f, a0)
                a1 = vfma(vsplat(M32[i + 1, k]), f, a1)
                a2 = vfma(vsplat(M32[i + 2, k]), f, a2)
                a3 = vfma(vsplat(M32[i + 3, k]), f, a3)
                a4 = vfma(vsplat(M32[i + 4, k]), f, a4)
            wc = vload1(w, c0 + c)
            vstore(Rw, i, c, vmul(vsub(a0, vload(Q, i, c0 + c)), wc))
            vstore(Rw, i + 1, c, vmul(vsub(a1, vload(Q, i + 1, c0 + c)), wc))
            vstore(Rw, i + 2, c, vmul(vsub(a2, vload(Q, i + 2, c0 + c)), wc))
            vstore(Rw, i + 3, c, vmul(vsub(a3, vload(Q, i + 3, c0 + c)), wc))
            vstore(Rw, i + 4, c, vmul(vsub(a4, vload(Q, i + 4, c0 + c)), wc))
    for i in range(mt, m):
        for c in range(0, C, LANES):
            a0 = vmul(vsplat(M32[i, 0]), vload(Phi, 0, c))
            for k in range(1, p):
                a0 = vfma(vsplat(M32[i, k]), vload(Phi, k, c), a0)
            vstore(Rw, i, c, vmul(vsub(a0, vload(Q, i, c0 + c)), vload1(w, c0 + c)))


@njit(inline="always")
def _flush(GL, i, k, b0, b1, b2, b3, b4):
    """GL[i, lanes of k ... k + 4] += b0 ... b4."""
    o = k * LANES
    vstore(GL, i, o, vadd(vload(GL, i, o), b0))
    vstore(GL, i, o + LANES, vadd(vload(GL, i, o + LANES), b1))
    vstore(GL, i, o + 2 * LANES, vadd(vload(GL, i, o + 2 * LANES), b2))
    vstore(GL, i, o + 3 * LANES, vadd(vload(GL, i, o + 3 * LANES), b3))
    vstore(GL, i, o + 4 * LANES, vadd(vload(GL, i, o + 4 * LANES), b4))


@njit(cache=True)
def _tile5x5(Rw, Phi, C, i, k, GL):
    """Lanes of G[i:i+5, k:k+5] += Rw[i:i+5, :C] Phi[k:k+5, :C]^T: 25 vector accumulators, 10
    loads per 25 fused multiply-adds."""
    a00 = a01 = a02 = a03 = a04 = vzero()
    a10 = a11 = a12 = a13 = a14 = vzero()
    a20 = a21 = a22 = a23 = a24 = vzero()
    a30 = a31 = a32 = a33 = a34 = vzero()
    a40 = a41 = a42 = a43 = a44 = vzero()
    for c in range(0, C, LANES):
        x0, x1, x2 = vload(Rw, i, c), vload(Rw, i + 1, c), vload(Rw, i + 2, c)
        x3, x4 = vload(Rw, i + 3, c), vload(Rw, i + 4, c)
        y = vload(Phi, k, c)
        a00, a10, a20 = vfma(x0, y, a00), vfma(x1, y, a10), vfma(x2, y, a20)
        a30, a40 = vfma(x3, y, a30), vfma(x4, y, a40)
        y = vload(Phi, k + 1, c)
        a01, a11, a21 = vfma(x0, y, a01), vfma(x1, y, a11), vfma(x2, y, a21)
        a31, a41 = vfma(x3, y, a31), vfma(x4, y, a41)
        y = vload(Phi, k + 2, c)
        a02, a12, a22 = vfma(x0, y, a02), vfma(x1, y, a12), vfma(x2, y, a22)
        a32, a42 = vfma(x3, y, a32), vfma(x4, y, a42)
        y = vload(Phi, k + 3, c)
        a03, a13, a23 = vfma(x0, y, a03), vfma(x1, y, a13), vfma(x2, y, a23)
        a33, a43 = vfma(x3, y, a33), vfma(x4, y, a43)
        y = vload(Phi, k + 4, c)
        a04, a14, a24 = vfma(x0, y, a04), vfma(x1, y, a14), vfma(x2, y, a24)
        a34, a44 = vfma(x3, y, a34), vfma(x4, y, a44)
    _flush(GL, i, k, a00, a01, a02, a03, a04)
    _flush(GL, i + 1, k, a10, a11, a12, a13, a14)
    _flush(GL, i + 2, k, a20, a21, a22, a23, a24)
    _flush(GL, i + 3, k, a30, a31, a32, a33, a34)
    _flush(GL, i + 4, k, a40, a41, a42, a43, a44)


@njit(cache=True)
def _tile1x5(Rw, Phi, C, i, k, GL):
    """Lanes of G[i, k:k+5] += Rw[i, :C] Phi[k:k+5, :C]^T."""
    a0 = a1 = a2 = a3 = a4 = vzero()
    for c in range(0, C, LANES):
        x = vload(Rw, i, c)
        a0, a1 = vfma(x, vload(Phi, k, c), a0), vfma(x, vload(Phi, k + 1, c), a1)
        a2, a3 = vfma(x, vload(Phi, k + 2, c), a2), vfma(x, vload(Phi, k + 3, c), a3)
        a4 = vfma(x, vload(Phi, k + 4, c), a4)
    _flush(GL, i, k, a0, a1, a2, a3, a4)


@njit(cache=True)
def _tile1x1(Rw, Phi, C, i, k, GL):
    """Lanes of G[i, k] += Rw[i, :C] . Phi[k, :C]."""
    a = vzero()
    for c in range(0, C, LANES):
        a = vfma(vload(Rw, i, c), vload(Phi, k, c), a)
    vstore(GL, i, k * LANES, vadd(vload(GL, i, k * LANES), a))


@njit(cache=True)
def _accumulate(Rw, Phi, C, GL):
    """Lanes of the gradient, GL (m, p * LANES) += Rw[:, :C] Phi[:, :C]^T: lane l of G[i, k]
    sums the columns c = l (mod LANES) in order, whatever the CPU's vector width."""
    m, p = Rw.shape[0], Phi.shape[0]
    mt, pt = m - m % _TILE, p - p % _TILE
    for i in range(0, mt, _TILE):
        for k in range(0, pt, _TILE):
            _tile5x5(Rw, Phi, C, i, k, GL)
    for i in range(mt, m):
        for k in range(0, pt, _TILE):
            _tile1x5(Rw, Phi, C, i, k, GL)
    for i in range(m):
        for k in range(pt, p):
            _tile1x1(Rw, Phi, C, i, k, GL)


@njit(fastmath=_FLAGS, cache=True)
def _epoch(M, idx, raw, s, body, targets, home, parent, var, joints, radius, steps,
           learning_rate, work):
    """One epoch (see reference.epoch): rolls out, weights, updates M in place.

    Leaves the samples in work: Q (m, N) postures, X (n, N) reached positions, w (N) weights,
    variation v in columns v * Bv ... v * Bv + T.
    """
    (Q, X, w, theta, P0, P1, Phi, Rw, path, Phip, gpath, dxs, nxs, wtmp, A, b, M32,
     GL) = work
    m, p = M.shape
    n = targets.shape[1]
    V = raw.shape[0]
    T = path.shape[1]
    Bv = Q.shape[1] // V
    VG = theta.shape[1] // Bv  # variations per group
    s4 = F4(s)
    # target path (eq. 9) at the current size, and g along it
    for k in range(len(idx) - 1):
        t0, t1 = idx[k], idx[k + 1]
        for l in range(steps):
            f = F4(l) / F4(steps)
            for j in range(n):
                path[j, k * steps + l] = s4 * ((_1 - f) * targets[t0, j] + f * targets[t1, j])
    for i in range(m):
        for k in range(p):
            M32[i, k] = M[i, k]
    _features(path, 0, T, parent, var, Phip)
    _matmul(M32, Phip, gpath)
    # the intended steps after the first (the first starts at home: _weights)
    nxs[:] = _0
    for j in range(n):
        for t in range(1, T):
            dxs[j, t] = path[j, t] - path[j, t - 1]
            nxs[t] += dxs[j, t] * dxs[j, t]
    # the variations' disturbances (eq. 8)
    centre = np.empty(n)
    half = np.empty(n)
    for j in range(n):
        lo, hi = targets[:, j].min(), targets[:, j].max()
        centre[j], half[j] = 0.5 * (lo + hi), 0.5 * (hi - lo)
    A64 = np.empty((m, n))
    b64 = np.empty(m)
    for v in range(V):
        _disturbances(raw[v], s, centre, half, radius, A64, b64)
        for i in range(m):
            b[v, i] = b64[i]
            for j in range(n):
                A[v, i, j] = A64[i, j]
    # groups of variations: rollout, weights, residuals, gradient lanes
    GL[:] = _0
    wsum = 0.0
    for v0 in range(0, V, VG):
        v1 = min(v0 + VG, V)
        c0, C = v0 * Bv, (v1 - v0) * Bv
        for v in range(v0, v1):
            _commands(gpath, path, A[v], b[v], home, v * Bv, Bv, Q)
        _angles(Q, c0, C, joints, theta)
        _forward(theta, C, body, X, c0, P0, P1)
        for v in range(v0, v1):
            _weights(path, dxs, nxs, X, Q, v * Bv, Bv, w, wtmp)
        wsum += _lane_sum(w, c0, C)
        _features(X, c0, C, parent, var, Phi)
        _residual(M32, Phi, Q, w, c0, C, Rw)
        _accumulate(Rw, Phi, C, GL)
    # one normalised gradient step on the weighted command error (eq. 6)
    step = learning_rate / wsum
    for i in range(m):
        for k in range(p):
            M[i, k] -= step * vsum(vload(GL, i, k * LANES))


def _layout(V, T):
    """(Bv, VG): columns per variation (T + 1 rounded up to LANES), variations per group."""
    Bv = -(-(T + 1) // LANES) * LANES
    return Bv, max(1, min(V, _GROUP // Bv))


@njit(cache=True)
def _work(m, n, p, V, T, Bv, VG):
    """Work arrays of one epoch: N = V Bv columns, C = VG Bv per group."""
    N, C = V * Bv, VG * Bv
    f4 = np.float32
    return (np.empty((m, N), f4), np.empty((n, N), f4), np.empty(N, f4),
            np.empty((m, C), f4), np.empty((3, C), f4), np.empty((3, C), f4),
            np.empty((p, C), f4), np.empty((m, C), f4),
            np.empty((n, T), f4), np.empty((p, T), f4), np.empty((m, T), f4),
            np.empty((n, T), f4), np.empty(T, f4), np.empty((3, T), f4),
            np.empty((V, m, n), f4), np.empty((V, m), f4),
            np.empty((m, p), f4), np.empty((m, p * LANES), f4))


@njit(fastmath=_FLAGS, cache=True)
def _block(M, idx, raw, sizes, scales, chain, targets, home, parent, var, joints, radius, steps,
           learning_rate, Bv, VG):
    """Epochs e = 0 ... B-1 with sizes[e] and per-joint length factors scales[e]."""
    a, d, ca, sa, base, outputs = chain
    m, p = M.shape
    n = targets.shape[1]
    T = (idx.shape[1] - 1) * steps
    work = _work(m, n, p, raw.shape[1], T, Bv, VG)
    ae = np.empty(m, np.float32)
    de = np.empty(m, np.float32)
    for e in range(idx.shape[0]):
        for i in range(m):
            ae[i] = a[i] * scales[e, i]
            de[i] = d[i] * scales[e, i]
        body = (ae, de, ca, sa, base, outputs)
        _epoch(M, idx[e], raw[e], sizes[e], body, targets, home, parent, var, joints, radius,
               steps, learning_rate, work)


@njit(fastmath=_FLAGS, cache=True)
def _distances(M, scale, chain, xs, parent, var, joints, out):
    """out[t] = |f(g(xs_t)) - xs_t| (float64) with the chain's lengths times scale."""
    a, d, ca, sa, base, outputs = chain
    m, p = M.shape
    NT, n = xs.shape
    ae, de = np.empty(m, np.float32), np.empty(m, np.float32)
    for i in range(m):
        ae[i], de[i] = a[i] * scale[i], d[i] * scale[i]
    body = (ae, de, ca, sa, base, outputs)
    M32 = np.empty((m, p), np.float32)
    for i in range(m):
        for k in range(p):
            M32[i, k] = M[i, k]
    X, Phi = np.empty((n, NT), np.float32), np.empty((p, NT), np.float32)
    Q, theta = np.empty((m, NT), np.float32), np.empty((m, NT), np.float32)
    P0, P1 = np.empty((3, NT), np.float32), np.empty((3, NT), np.float32)
    for t in range(NT):
        for j in range(n):
            X[j, t] = xs[t, j]
    _features(X, 0, NT, parent, var, Phi)
    _matmul(M32, Phi, Q)
    _angles(Q, 0, NT, joints, theta)
    _forward(theta, NT, body, X, 0, P0, P1)
    for t in range(NT):
        d2 = 0.0
        for j in range(n):
            dx = float(X[j, t]) - xs[t, j]
            d2 += dx * dx
        out[t] = np.sqrt(d2)


def monomial_tree(exps: np.ndarray):
    """parent[k], var[k] with exps[k] = exps[parent[k]] + unit(var[k]) (parent[0] = var[0] = 0)."""
    rows = {tuple(e): k for k, e in enumerate(exps)}
    parent = np.zeros(len(exps), np.int64)
    var = np.zeros(len(exps), np.int64)
    for k, e in enumerate(exps[1:], start=1):
        j = int(np.flatnonzero(e)[0])
        lower = e.copy()
        lower[j] -= 1
        parent[k], var[k] = rows[tuple(lower)], j
    return parent, var


_ARRAYS: dict = {}  # (id(body), exps) -> (body, arrays); the body is kept so its id stays its own


def _arrays(body, exps):
    """The body as the kernels take it: float32 chain and joint map, plus the monomial tree.
    Built once per body object (bodies are frozen) and monomial table."""
    exps = np.asarray(exps)
    key = (id(body), exps.shape, exps.tobytes())
    hit = _ARRAYS.get(key)
    if hit is not None and hit[0] is body:
        return hit[1]
    f4 = lambda x: np.ascontiguousarray(x, np.float32)  # noqa: E731
    chain = body.chain(1.0)
    normalized = body.normalized
    joints = (normalized, body.saturates,
              f4(body.q_min if normalized else np.zeros(body.m)),
              f4(body.q_max - body.q_min if normalized else np.ones(body.m)),
              f4(body.theta_offset))
    parent, var = monomial_tree(exps)
    arr = dict(
        chain=(f4(chain["a"]), f4(chain["d"]), f4(chain["cos_alpha"]), f4(chain["sin_alpha"]),
               f4(body.base), np.array(body.outputs, np.int64)),
        targets=f4(body.targets), home=f4(body.saturate(body.home)), parent=parent, var=var,
        joints=joints,
    )
    if len(_ARRAYS) >= 32:
        _ARRAYS.clear()
    _ARRAYS[key] = (body, arr)
    return arr


def run_block(M, body, params, exps, sizes, scales, idx, raw):
    """Epochs with sizes `sizes`, per-joint length factors `scales` (B, m) and draws idx, raw.
    Returns the updated M (a new array)."""
    M = np.array(M, dtype=np.float64, order="C")
    idx = np.ascontiguousarray(idx, np.int64)
    raw = np.ascontiguousarray(raw, np.float64)
    Bv, VG = _layout(raw.shape[1], (idx.shape[1] - 1) * int(params.steps))
    _block(M, idx, raw, np.ascontiguousarray(sizes, np.float64),
           np.ascontiguousarray(scales, np.float32).reshape(len(sizes), body.m),
           radius=float(params.radius), steps=int(params.steps),
           learning_rate=float(params.learning_rate), Bv=Bv, VG=VG, **_arrays(body, exps))
    return M


def distances(M, body, exps, scale, xs):
    """|f(g(x*)) - x*| for every row of xs (N, n): the evaluation on the fast path."""
    arr = _arrays(body, exps)
    out = np.empty(len(xs))
    _distances(np.ascontiguousarray(M, np.float64), np.ascontiguousarray(scale, np.float32),
               arr["chain"], np.ascontiguousarray(xs, np.float64), arr["parent"], arr["var"],
               arr["joints"], out)
    return out


def epoch_samples(M, body, params, exps, size, scale, idx, raw):
    """One epoch on the fast path, for tests: returns (M after, Q, X, w) with the samples laid
    out as (V, T + 1, ...) like reference.epoch's."""
    M = np.array(M, dtype=np.float64, order="C")
    arr = _arrays(body, exps)
    a, d, ca, sa, base, outputs = arr["chain"]
    k = np.asarray(scale, np.float32)
    chain = (a * k, d * k, ca, sa, base, outputs)
    T = (len(idx) - 1) * params.steps
    V = raw.shape[0]
    Bv, VG = _layout(V, T)
    work = _work(body.m, body.n, len(exps), V, T, Bv, VG)
    _epoch(M, np.asarray(idx, np.int64), np.ascontiguousarray(raw, np.float64), float(size),
           chain, arr["targets"], arr["home"], arr["parent"], arr["var"], arr["joints"],
           float(params.radius), int(params.steps), float(params.learning_rate), work)
    Q, X, w = work[0], work[1], work[2]

    def samples(a):  # (rows, V * Bv) -> (V, T + 1, rows)
        return a.reshape(len(a), V, Bv)[:, :, :T + 1].transpose(1, 2, 0)
    return M, samples(Q), samples(X), w.reshape(V, Bv)[:, :T + 1]
