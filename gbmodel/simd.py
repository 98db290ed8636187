"""The compiled kernels' toolbox (numba), so that each kernel computes lane by lane what it
writes, on every x86-64 CPU: `F32x16` (LLVM <16 x float>: one zmm register, or two ymm halves
without AVX-512, the same result lane by lane) and `F64x8` (lanes round as the scalar loop does),
both made by _vector_set; single IEEE operations (vfma rounded once, vdiv and vsqrt correctly
rounded), vsum in a fixed tree; `sincos` (F32x16) and `sincos64` (float64), branch-free Cephes
polynomials after a Cody-Waite reduction; `chain_kinematics` (F32x16) and `chain_forward64`
(float64) through kinematics.chain_layout. No fastmath. tests/core/test_kernel_targets.py checks
the kernels bit for bit across CPU targets.
"""
from __future__ import annotations

import hashlib
import os
from pathlib import Path

import numpy as np
from llvmlite import ir
from numba import njit, types
from numba.core import cgutils
from numba.extending import intrinsic, models, register_model

F4 = np.float32


def fresh_cache(folder, files=()) -> bool:
    """Remove numba's cached kernels of `folder` when its *.py files, this file or `files`
    changed (numba checks a cache against its own file only, but a kernel's machine code holds
    its callees' from other files); returns whether they were removed. An unwritable folder
    (an installed package) is left alone."""
    folder = Path(folder)
    sources = sorted(folder.glob("*.py")) + [Path(__file__)] + [Path(f) for f in files]
    h = hashlib.sha256()
    for f in sources:
        h.update(f.read_bytes())
    stamp = h.hexdigest()[:16]
    cache = folder / "__pycache__"
    mark = cache / "kernels.stamp"
    try:
        if mark.read_text() == stamp:
            return False
    except OSError:
        pass
    try:
        for f in [*cache.glob("*.nbi"), *cache.glob("*.nbc")]:
            f.unlink(missing_ok=True)
        cache.mkdir(exist_ok=True)
        tmp = cache / f"kernels.stamp.{os.getpid()}"
        tmp.write_text(stamp)
        os.replace(tmp, mark)
    except OSError:
        return False
    return True


LANES, W8 = 16, 8  # the lanes of F32x16 and of F64x8
_VEC = ir.VectorType(ir.FloatType(), LANES)
_VEC8 = ir.VectorType(ir.DoubleType(), W8)
_LLVM = {"F32x16": _VEC, "F64x8": _VEC8}


class VectorType(types.Type):
    def __init__(self, name):
        super().__init__(name=name)


F32x16, F64x8 = VectorType("F32x16"), VectorType("F64x8")


@register_model(VectorType)
class _VectorModel(models.PrimitiveModel):
    def __init__(self, dmm, fe_type):
        super().__init__(dmm, fe_type, _LLVM[fe_type.name])


def _vector_pointer(context, builder, sig, args, n, vec=_VEC):
    aryty = sig.args[0]
    inds = [context.cast(builder, v, t, types.intp) for v, t in zip(args[1:1 + n],
                                                                    sig.args[1:1 + n])]
    ptr = cgutils.get_item_pointer(context, builder, aryty,
                                   context.make_array(aryty)(context, builder, args[0]), inds)
    return builder.bitcast(ptr, vec.as_pointer())


def _llvm(builder, name, args, vec=_VEC):
    kind = "f32" if vec is _VEC else "f64"
    fn = cgutils.get_or_insert_function(
        builder.module, ir.FunctionType(vec, [vec] * len(args)), f"{name}.v{vec.count}{kind}")
    return builder.call(fn, args)


def _vector_set(vt, scalar, suffix):
    """The operations on `vt`, named v<op><suffix>: load a[k, i:i + lanes] (load1: a[i:...] of
    1-d; no bounds check), store, store1, splat, add ... div, neg, sqrt, fma (rounded once: one
    instruction, or a correctly rounded libm call without FMA), where (x if a > b else y; a NaN
    compares false)."""
    vec, align = _LLVM[vt.name], 4 if scalar is types.float32 else 8

    def pointer(context, builder, sig, args, n):
        return _vector_pointer(context, builder, sig, args, n, vec)

    def load(typingctx, a, k, i):
        return vt(a, k, i), lambda context, builder, sig, args: builder.load(
            pointer(context, builder, sig, args, 2), align=align)

    def load1(typingctx, a, i):
        return vt(a, i), lambda context, builder, sig, args: builder.load(
            pointer(context, builder, sig, args, 1), align=align)

    def stored(n):
        def codegen(context, builder, sig, args):
            builder.store(args[n + 1], pointer(context, builder, sig, args, n), align=align)
            return context.get_dummy_value()
        return codegen

    def store(typingctx, a, k, i, v):
        return types.none(a, k, i, v), stored(2)

    def store1(typingctx, a, i, v):
        return types.none(a, i, v), stored(1)

    def splat(typingctx, x):
        def codegen(context, builder, sig, args):
            x = context.cast(builder, args[0], sig.args[0], scalar)
            v = builder.insert_element(ir.Constant(vec, ir.Undefined), x,
                                       ir.Constant(ir.IntType(32), 0))
            return builder.shuffle_vector(v, v, ir.Constant(
                ir.VectorType(ir.IntType(32), vec.count), [0] * vec.count))
        return vt(x), codegen

    def binary(op):
        def typer(typingctx, a, b):
            return vt(a, b), lambda context, builder, sig, args: getattr(builder, op)(*args)
        return typer

    def neg(typingctx, a):
        return vt(a), lambda context, builder, sig, args: builder.fneg(args[0])

    def sqrt(typingctx, a):
        return vt(a), lambda context, builder, sig, args: _llvm(builder, "llvm.sqrt", args, vec)

    def fma(typingctx, a, b, c):
        return vt(a, b, c), lambda context, builder, sig, args: _llvm(builder, "llvm.fma",
                                                                      args, vec)

    def where(typingctx, a, b, x, y):
        def codegen(context, builder, sig, args):
            return builder.select(builder.fcmp_ordered(">", args[0], args[1]), args[2], args[3])
        return vt(a, b, x, y), codegen

    ops = dict(load=load, load1=load1, store=store, store1=store1, splat=splat,
               add=binary("fadd"), sub=binary("fsub"), mul=binary("fmul"), div=binary("fdiv"),
               neg=neg, sqrt=sqrt, fma=fma, where=where)
    for name, fn in ops.items():
        fn.__name__ = fn.__qualname__ = f"v{name}{suffix}"
    return tuple(intrinsic(fn) for fn in ops.values())


(vload, vload1, vstore, vstore1, vsplat, vadd, vsub, vmul, vdiv, vneg, vsqrt, vfma,
 vwhere) = _vector_set(F32x16, types.float32, "")
(vload8, vload18, vstore8, vstore18, vsplat8, vadd8, vsub8, vmul8, vdiv8, vneg8, vsqrt8, vfma8,
 vwhere8) = _vector_set(F64x8, types.float64, "8")


_ONE_REGISTER: dict = {}  # codegen.magic_tuple() -> whether an F32x16 lives in one register

_PROBE = """
define void @probe(<16 x float>* %p) {
  %v = load <16 x float>, <16 x float>* %p
  %w = fadd <16 x float> %v, %v
  store <16 x float> %w, <16 x float>* %p
  ret void
}
"""


def _one_register(codegen) -> bool:
    """Whether LLVM's target holds an F32x16 in one zmm register (compiles an add of two to
    see; False where it cannot tell)."""
    key = codegen.magic_tuple()
    if key not in _ONE_REGISTER:
        try:
            import llvmlite.binding as ll
            asm = codegen._tm.emit_assembly(ll.parse_assembly(_PROBE))
            _ONE_REGISTER[key] = "zmm" in asm
        except Exception:  # noqa: BLE001 (a numba without _tm: the narrow choice, same bits)
            _ONE_REGISTER[key] = False
    return _ONE_REGISTER[key]


@intrinsic
def wide_vectors(typingctx):
    """Compile-time: an F32x16 is one of 32 registers (AVX-512). Only for choices that move no
    bit (a register tile's shape)."""
    def codegen(context, builder, sig, args):
        return context.get_constant(types.boolean, _one_register(context.codegen()))
    return types.boolean(), codegen


@intrinsic
def vsum(typingctx, v):
    """The lanes' sum in float64, in a fixed tree (l + l + 8 first, then l + l + 4, ...)."""
    def codegen(context, builder, sig, args):
        x = builder.fpext(args[0], ir.VectorType(ir.DoubleType(), LANES))
        width = LANES
        while width > 1:
            width //= 2
            lo, hi = (ir.Constant(ir.VectorType(ir.IntType(32), width),
                                  list(range(start, start + width))) for start in (0, width))
            x = builder.fadd(builder.shuffle_vector(x, x, lo), builder.shuffle_vector(x, x, hi))
        return builder.extract_element(x, ir.Constant(ir.IntType(32), 0))
    return types.float64(v), codegen


# ---- sin and cos ---------------------------------------------------------------------------------
_HALF, _1 = F4(0.5), F4(1.0)
# Cephes' single-precision minimax kernels for sin and cos on [-pi/4, pi/4] (error ~3e-8)
_S0, _S1, _S2 = F4(-1.9515295891e-4), F4(8.3321608736e-3), F4(-1.6666654611e-1)
_C0, _C1, _C2 = F4(2.443315711809948e-5), F4(-1.388731625493765e-3), F4(4.166664568298827e-2)
_TWO_OVER_PI = F4(6.36619772367581382433e-01)
_PIO2_HI, _PIO2_LO = F4(1.5707963705062866), F4(-4.371139000186243e-08)  # pi/2 = HI + LO
_ROUND = F4(1.5 * 2 ** 23)  # y + _ROUND - _ROUND rounds |y| < 2^22 to an integer (to even)


@intrinsic
def _quadrant(typingctx, kf, s, c):
    """(sin x, cos x) from sin r, cos r, x = k pi/2 + r, k in kf's low bits: odd k swaps, bit 1
    of k (of k + 1) is the sine's (cosine's) sign. Exact."""
    def codegen(context, builder, sig, args):
        i32 = ir.VectorType(ir.IntType(32), LANES)

        def const(x):
            return ir.Constant(i32, [x] * LANES)
        k = builder.bitcast(args[0], i32)
        odd = builder.icmp_unsigned("!=", builder.and_(k, const(1)), const(0))
        sn, cs = builder.select(odd, args[2], args[1]), builder.select(odd, args[1], args[2])
        sign_s = builder.shl(builder.and_(k, const(2)), const(30))
        sign_c = builder.shl(builder.and_(builder.add(k, const(1)), const(2)), const(30))
        sn = builder.bitcast(builder.xor(builder.bitcast(sn, i32), sign_s), _VEC)
        cs = builder.bitcast(builder.xor(builder.bitcast(cs, i32), sign_c), _VEC)
        return context.make_tuple(builder, sig.return_type, [sn, cs])
    return types.UniTuple(F32x16, 2)(kf, s, c), codegen


@njit(inline="always")
def sincos(x):
    """(sin x, cos x), within 1e-7 for |x| < 10: x = k pi/2 + r (Cody-Waite, pi/2 in two
    parts), the kernels on r, the quadrant k mod 4."""
    kf = vfma(x, vsplat(_TWO_OVER_PI), vsplat(_ROUND))
    k = vsub(kf, vsplat(_ROUND))
    r = vfma(k, vsplat(-_PIO2_HI), x)
    r = vfma(k, vsplat(-_PIO2_LO), r)
    z = vmul(r, r)
    s = vfma(vmul(r, z), vfma(vfma(vsplat(_S0), z, vsplat(_S1)), z, vsplat(_S2)), r)
    c = vfma(vfma(vfma(vfma(vsplat(_C0), z, vsplat(_C1)), z, vsplat(_C2)), z, vsplat(-_HALF)),
             z, vsplat(_1))
    return _quadrant(kf, s, c)


@njit(cache=True)
def sincos_array(x):
    n = len(x)
    pad = np.zeros(n + LANES, np.float32)
    pad[:n] = x
    s, c = np.empty_like(pad), np.empty_like(pad)
    for i in range(0, n, LANES):
        si, ci = sincos(vload1(pad, i))
        vstore1(s, i, si)
        vstore1(c, i, ci)
    return s[:n], c[:n]


# ---- the chain on F32x16: forward kinematics of LANES samples at a time ---------------------------
@njit(inline="always")
def vclip(q):
    one, minus_one = vsplat(_1), vsplat(-_1)
    return vwhere(minus_one, q, minus_one, vwhere(q, one, one, q))


_KB = 256  # columns per block of chain_kinematics: the block's hand points stay in L1


@njit(cache=True)
def aligned(rows, cols, dtype=np.float32):
    """np.zeros((rows, cols), dtype) on a 64-byte boundary: with rows of whole vectors (F32x16,
    F64x8) each vector lies in one cache line (numba's arrays start on 32 bytes: a 64-byte load
    or store of one spans two lines, which AVX-512 pays for twice, and a split store is not
    forwarded to the next load)."""
    n = rows * cols
    buf = np.zeros(n + 64, dtype)
    off = (-(buf.ctypes.data // buf.itemsize)) % (64 // buf.itemsize)
    return buf[off:off + n].reshape((rows, cols))


@njit(cache=True)
def chain_kinematics(Q, X, C, joints, body):
    """Hand positions X[:, :C] of commands Q[:, :C] (C a multiple of LANES) through
    kinematics.chain_layout in float32, saturating Q in place where the body does. The point
    goes from the last joint to the base, joint by joint over blocks of _KB columns (a joint's
    constants out of the column loop); twists of 0 and +-90 degrees skip the products by 0 and
    +-1 (the same values up to a zero's sign)."""
    normalized, saturates, q_lo, q_span, offset = joints
    a, d, ca, sa, base, outputs, ty, R, general = body
    m = Q.shape[0]
    P = aligned(3, min(C, _KB))
    for c0 in range(0, C, _KB):
        cb = min(_KB, C - c0)
        P[:, :cb] = 0
        for ii in range(m):
            i = m - 1 - ii
            half_span = _HALF * q_span[i]
            start = offset[i] + q_lo[i] + half_span
            ai, di, tyi, oi, cai, sai = a[i], d[i], ty[i], offset[i], ca[i], sa[i]
            # the kind of step: a general chain's (4), a DH row's twist of 0 (0), +90 (1), -90
            # degrees (2) or any (3)
            kind = 4 if general else (0 if sai == 0 and cai == 1 else (
                1 if cai == 0 and sai == 1 else (2 if cai == 0 and sai == -1 else 3)))
            for c in range(0, cb, LANES):
                q = vload(Q, i, c0 + c)
                if normalized:
                    if saturates:
                        q = vclip(q)
                        vstore(Q, i, c0 + c, q)
                    theta = vfma(q, vsplat(half_span), vsplat(start))
                else:
                    theta = vadd(q, vsplat(oi))
                s, co = sincos(theta)
                px, py, pz = vload(P, 0, c), vload(P, 1, c), vload(P, 2, c)
                if kind == 4:  # a URDF's chain: p <- Rz(theta) (R_i p + (a, ty, d)_i)
                    u = vfma(vsplat(R[i, 0, 0]), px, vfma(vsplat(R[i, 0, 1]), py, vfma(
                        vsplat(R[i, 0, 2]), pz, vsplat(ai))))
                    v = vfma(vsplat(R[i, 1, 0]), px, vfma(vsplat(R[i, 1, 1]), py, vfma(
                        vsplat(R[i, 1, 2]), pz, vsplat(tyi))))
                    pz = vfma(vsplat(R[i, 2, 0]), px, vfma(vsplat(R[i, 2, 1]), py, vfma(
                        vsplat(R[i, 2, 2]), pz, vsplat(di))))
                else:
                    u = vadd(px, vsplat(ai))
                    if kind == 0:
                        v = py
                        pz = vadd(pz, vsplat(di))
                    elif kind == 1:
                        v = vneg(pz)
                        pz = vadd(py, vsplat(di))
                    elif kind == 2:
                        v = pz
                        pz = vsub(vsplat(di), py)
                    else:
                        v = vfma(vsplat(cai), py, vmul(vsplat(-sai), pz))
                        pz = vadd(vfma(vsplat(sai), py, vmul(vsplat(cai), pz)), vsplat(di))
                vstore(P, 0, c, vfma(co, u, vmul(vneg(s), v)))
                vstore(P, 1, c, vfma(s, u, vmul(co, v)))
                vstore(P, 2, c, pz)
        for j in range(len(outputs)):
            o = outputs[j]
            for c in range(0, cb, LANES):
                x = vfma(vsplat(base[o, 0]), vload(P, 0, c), vsplat(base[o, 3]))
                x = vfma(vsplat(base[o, 1]), vload(P, 1, c), x)
                vstore(X, j, c0 + c, vfma(vsplat(base[o, 2]), vload(P, 2, c), x))


@njit(cache=True)
def box(targets):
    """The target box's centre and half-widths (n,) in float64."""
    n = targets.shape[1]
    centre, half = np.empty(n), np.empty(n)
    for j in range(n):
        lo, hi = float(targets[:, j].min()), float(targets[:, j].max())
        centre[j], half[j] = 0.5 * (lo + hi), 0.5 * (hi - lo)
    return centre, half


_MASK32 = np.uint64(0xFFFFFFFF)


@njit(cache=True)
def fsum(x):
    """(math.fsum of the float64 array x, True): the same correctly rounded sum without a list of
    Python floats; (nan, False) at a non-finite value or an intermediate overflow, math.fsum's to
    answer. x must be float64 (its bits are read as a float64's; evaluation.error converts).
    The values are added exactly, as integers in units of 2^-1074 in 32-bit limbs (each value's
    53-bit mantissa over three limbs of int64: 2^31 values before a limb could overflow), and the
    limbs, each an exact double, summed by `_msum`: the correctly rounded sum of the same exact
    total, so math.fsum's bits (5-10x faster than _msum over the values, whose branches depend on
    the data). A value of 2^1000 or more, or 2^23 values or more, go to _msum as they are, so
    that an intermediate overflow is math.fsum's to report."""
    n = x.size
    if n >= 1 << 23:
        return _msum(x)
    bits = np.ascontiguousarray(x).view(np.uint64)
    acc = np.zeros(67, np.int64)  # limb k: 2^(32 k - 1074); |x| < 2^1000: k <= 65, one for carries
    for k in range(n):
        b = bits[k]
        e = (b >> np.uint64(52)) & np.uint64(0x7FF)
        if e >= np.uint64(2023):  # |x| >= 2^1000, inf or nan
            return _msum(x)
        m = b & np.uint64((1 << 52) - 1)
        if e > np.uint64(0):  # normal: the hidden bit; a subnormal's unit is 2^-1074 as is
            m |= np.uint64(1 << 52)
            e -= np.uint64(1)
        q, s = e >> np.uint64(5), e & np.uint64(31)  # x = m 2^(e - 1074): limbs q ... q + 2
        lo = np.int64((m << s) & _MASK32)
        mid = np.int64((m >> (np.uint64(32) - s)) & _MASK32)
        hi = np.int64((m >> np.uint64(32)) >> (np.uint64(32) - s))
        i = np.int64(q)
        if b >> np.uint64(63):
            acc[i], acc[i + 1], acc[i + 2] = acc[i] - lo, acc[i + 1] - mid, acc[i + 2] - hi
        else:
            acc[i], acc[i + 1], acc[i + 2] = acc[i] + lo, acc[i + 1] + mid, acc[i + 2] + hi
    parts, c = np.empty(67), 0
    for k in range(66):  # carries up: limbs in [-2^31, 2^31) (a negative total stays short)
        carry = (acc[k] + (1 << 31)) >> 32
        acc[k] -= carry << 32
        acc[k + 1] += carry
    for k in range(67):
        if acc[k] != 0:
            parts[c] = np.ldexp(np.float64(acc[k]), 32 * k - 1074)
            c += 1
    return _msum(parts[:c])


@njit(cache=True)
def _msum(x):
    """math.fsum of x: Shewchuk's partials and CPython's half-even correction step for step;
    (nan, False) at a non-finite value or an intermediate overflow."""
    p = np.empty(64)  # nonoverlapping partials: at most 2098 / 53 + 1 of finite doubles
    n = 0
    for k in range(x.size):
        v = x[k]
        if not np.isfinite(v):
            return np.nan, False
        i = 0
        for j in range(n):
            y = p[j]
            if abs(v) < abs(y):
                v, y = y, v
            hi = v + y
            lo = y - (hi - v)
            if lo != 0.0:
                p[i] = lo
                i += 1
            v = hi
        n = i
        if v != 0.0:
            if not np.isfinite(v):
                return np.nan, False
            p[n] = v
            n += 1
    hi = lo = 0.0
    if n > 0:
        n -= 1
        hi = p[n]
        while n > 0:  # from the top, until the sum becomes inexact
            v, n = hi, n - 1
            y = p[n]
            hi = v + y
            lo = y - (hi - v)
            if lo != 0.0:
                break
        if n > 0 and ((lo < 0.0 and p[n - 1] < 0.0) or (lo > 0.0 and p[n - 1] > 0.0)):
            y = lo * 2.0  # half-even across partials
            v = hi + y
            if y == v - hi:
                hi = v
    return hi, True


@intrinsic
def vload8f(typingctx, a, k, i):
    """a[k, i:i + 8] of a float32 array as float64 lanes (exact)."""
    def codegen(context, builder, sig, args):
        ptr = _vector_pointer(context, builder, sig, args, 2, ir.VectorType(ir.FloatType(), W8))
        return builder.fpext(builder.load(ptr, align=4), _VEC8)
    return F64x8(a, k, i), codegen


@intrinsic
def transpose8(typingctx, r0, r1, r2, r3, r4, r5, r6, r7):
    """The 8 x 8 transpose of eight F64x8 rows (three stages of shuffles)."""
    def codegen(context, builder, sig, args):
        mask = ir.VectorType(ir.IntType(32), W8)

        def pair(a, b, lo, hi):
            return (builder.shuffle_vector(a, b, ir.Constant(mask, lo)),
                    builder.shuffle_vector(a, b, ir.Constant(mask, hi)))
        x = list(args)
        for step, lo, hi in ((1, [0, 8, 2, 10, 4, 12, 6, 14], [1, 9, 3, 11, 5, 13, 7, 15]),
                             (2, [0, 1, 8, 9, 4, 5, 12, 13], [2, 3, 10, 11, 6, 7, 14, 15]),
                             (4, [0, 1, 2, 3, 8, 9, 10, 11], [4, 5, 6, 7, 12, 13, 14, 15])):
            y = list(x)
            for k in range(W8):
                if k & step == 0:
                    y[k], y[k + step] = pair(x[k], x[k + step], lo, hi)
            x = y
        return context.make_tuple(builder, sig.return_type, x)
    return types.UniTuple(F64x8, W8)(r0, r1, r2, r3, r4, r5, r6, r7), codegen

# ---- float64 scalars ------------------------------------------------------------------------------
# Cephes' double kernels (|r| <= pi/4) after x = k pi/2 + r, pi/2 in three parts (the first two
# with trailing zero bits: k times them exact for |k| < 2^24); plain float64 in a fixed order,
# the same on every CPU and libm, within 2 ulp of the C library's (tests/core/test_learners.py).
_PIO2_64 = (1.57079625129699707031e0, 7.54978941586159635335e-8, 5.39030285815811905290e-15)
_ROUND64 = 6755399441055744.0  # 1.5 * 2^52: x + _ROUND64 - _ROUND64 rounds x to an integer
_SIN64 = (1.58962301576546568060e-10, -2.50507477628578072866e-8, 2.75573136213857245213e-6,
           -1.98412698295895385996e-4, 8.33333333332211858878e-3, -1.66666666666666307295e-1)
_COS64 = (-1.13585365213876817300e-11, 2.08757008419747316778e-9, -2.75573141792967388112e-7,
           2.48015872888517045348e-5, -1.38888888888730564116e-3, 4.16666666666665929218e-2)


@njit(cache=True)
def sincos64(x):
    """(sin x, cos x): the polynomials for |x| < 2^24, the C library beyond (a diverging
    command)."""
    if not abs(x) < 16777216.0:
        return np.sin(x), np.cos(x)
    k = (x * 0.63661977236758134308 + _ROUND64) - _ROUND64  # nearest integer to x / (pi/2)
    r = ((x - k * _PIO2_64[0]) - k * _PIO2_64[1]) - k * _PIO2_64[2]
    z = r * r
    ps = ((((_SIN64[0] * z + _SIN64[1]) * z + _SIN64[2]) * z + _SIN64[3]) * z
          + _SIN64[4]) * z + _SIN64[5]
    pc = ((((_COS64[0] * z + _COS64[1]) * z + _COS64[2]) * z + _COS64[3]) * z
          + _COS64[4]) * z + _COS64[5]
    s = r + r * z * ps
    c = (1.0 - 0.5 * z) + z * z * pc
    # quadrant 0: (s, c), 1: (c, -s), 2: (-s, -c), 3: (-c, s), branch-free: exact +-1 products
    quadrant = int(k) & 3
    swap = quadrant & 1
    a = c if swap else s
    b = s if swap else c
    return a * (1 - (quadrant & 2)), b * (1 - ((quadrant + 1) & 2))


@njit(cache=True)
def chain_forward64(q, scale, chain, joints, out):
    """body.forward(q, scale) into out (n,) in float64, operation by operation as
    kinematics.hand_position (DH rows) or chain_position."""
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
        s, c = sincos64(theta)
        px, py, pz = c * u - s * v, s * u + c * v, w
    for j in range(len(outputs)):
        o = outputs[j]
        out[j] = px * base[o, 0] + py * base[o, 1] + pz * base[o, 2] + base[o, 3]


