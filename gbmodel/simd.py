"""Explicit float32 vectors of LANES lanes for the compiled kernels (numba), and sin/cos on them.

Every kernel (the Goal Babbling kernel, the online learner's, the chains' kinematics) shares this
one set, so that each computes lane by lane what it writes, on every x86-64 CPU: `F32x16` is LLVM
<16 x float> (one zmm register, or two ymm halves without AVX-512, with the same result lane by
lane); vadd ... vfma are single IEEE operations (vfma: llvm.fma, rounded once; vdiv, vsqrt
correctly rounded); vsum adds the lanes in a fixed tree; sincos is a branch-free polynomial
(Cephes' kernels after a Cody-Waite reduction). Nothing is compiled with fastmath.
(Moved from gbmodel/learners/goal_babbling/fast.py; tests/test_kernel_targets.py checks the
kernels bit for bit across CPU targets.)
"""
from __future__ import annotations

import numpy as np
from llvmlite import ir
from numba import njit, types
from numba.core import cgutils
from numba.extending import intrinsic, models, register_model

F4 = np.float32
LANES = 16  # width of the explicit vectors (F32x16)

# ---- explicit float32 vectors of LANES lanes -----------------------------------------------------
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


def _vector_pointer(context, builder, sig, args, n):
    """Address of element args[1:1 + n] of the array args[0], as a pointer to a vector."""
    aryty = sig.args[0]
    inds = [context.cast(builder, v, t, types.intp) for v, t in zip(args[1:1 + n],
                                                                    sig.args[1:1 + n])]
    ptr = cgutils.get_item_pointer(context, builder, aryty,
                                   context.make_array(aryty)(context, builder, args[0]), inds)
    return builder.bitcast(ptr, _VEC.as_pointer())


@intrinsic
def vload(typingctx, a, k, i):
    """a[k, i:i + LANES] of a 2-d float32 array with contiguous rows (no bounds check)."""
    def codegen(context, builder, sig, args):
        return builder.load(_vector_pointer(context, builder, sig, args, 2), align=4)
    return F32x16(a, k, i), codegen


@intrinsic
def vload1(typingctx, a, i):
    """a[i:i + LANES] of a contiguous 1-d float32 array (no bounds check)."""
    def codegen(context, builder, sig, args):
        return builder.load(_vector_pointer(context, builder, sig, args, 1), align=4)
    return F32x16(a, i), codegen


@intrinsic
def vstore(typingctx, a, k, i, v):
    """a[k, i:i + LANES] = v."""
    def codegen(context, builder, sig, args):
        builder.store(args[3], _vector_pointer(context, builder, sig, args, 2), align=4)
        return context.get_dummy_value()
    return types.none(a, k, i, v), codegen


@intrinsic
def vstore1(typingctx, a, i, v):
    """a[i:i + LANES] = v."""
    def codegen(context, builder, sig, args):
        builder.store(args[2], _vector_pointer(context, builder, sig, args, 1), align=4)
        return context.get_dummy_value()
    return types.none(a, i, v), codegen


@intrinsic
def vsplat(typingctx, x):
    """Every lane x (cast to float32)."""
    def codegen(context, builder, sig, args):
        x = context.cast(builder, args[0], sig.args[0], types.float32)
        v = builder.insert_element(ir.Constant(_VEC, ir.Undefined), x,
                                   ir.Constant(ir.IntType(32), 0))
        return builder.shuffle_vector(v, v, ir.Constant(ir.VectorType(ir.IntType(32), LANES),
                                                         [0] * LANES))
    return F32x16(x), codegen


def _llvm(builder, name, args):
    """A call of the LLVM intrinsic `name` on vectors."""
    fn = cgutils.get_or_insert_function(
        builder.module, ir.FunctionType(_VEC, [_VEC] * len(args)), f"{name}.v{LANES}f32")
    return builder.call(fn, args)


@intrinsic
def vadd(typingctx, a, b):
    return F32x16(a, b), lambda context, builder, sig, args: builder.fadd(*args)


@intrinsic
def vsub(typingctx, a, b):
    return F32x16(a, b), lambda context, builder, sig, args: builder.fsub(*args)


@intrinsic
def vmul(typingctx, a, b):
    return F32x16(a, b), lambda context, builder, sig, args: builder.fmul(*args)


@intrinsic
def vdiv(typingctx, a, b):
    """a / b, correctly rounded (IEEE)."""
    return F32x16(a, b), lambda context, builder, sig, args: builder.fdiv(*args)


@intrinsic
def vneg(typingctx, a):
    return F32x16(a), lambda context, builder, sig, args: builder.fneg(args[0])


@intrinsic
def vsqrt(typingctx, a):
    """sqrt(a), correctly rounded (IEEE)."""
    return F32x16(a), lambda context, builder, sig, args: _llvm(builder, "llvm.sqrt", args)


@intrinsic
def vfma(typingctx, a, b, c):
    """a * b + c, rounded once."""
    return F32x16(a, b, c), lambda context, builder, sig, args: _llvm(builder, "llvm.fma", args)


@intrinsic
def vwhere(typingctx, a, b, x, y):
    """x where a > b, else y, lane by lane (a NaN compares false)."""
    def codegen(context, builder, sig, args):
        return builder.select(builder.fcmp_ordered(">", args[0], args[1]), args[2], args[3])
    return F32x16(a, b, x, y), codegen


@intrinsic
def vsum(typingctx, v):
    """The lanes' sum in float64, in a fixed tree: lanes l and l + 8 first, then l and l + 4,
    and so on."""
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
    """(sin x, cos x) from s = sin r, c = cos r for x = k pi/2 + r, with k in the low bits of
    kf = k + _ROUND: odd k swaps s and c, then bit 1 of k (of k + 1) is the sign of the sine
    (of the cosine). Exact: a select and a flip of the sign bit."""
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
    """(sin x, cos x) lane by lane, within 1e-7 for |x| < 10 (joint angles), branch-free:
    x = k pi/2 + r with |r| <= pi/4 (Cody-Waite, two parts of pi/2), the kernels on r, then the
    quadrant k mod 4 swaps and negates them."""
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
    """sincos of a float32 array (for tests)."""
    n = len(x)
    pad = np.zeros(n + LANES, np.float32)
    pad[:n] = x
    s, c = np.empty_like(pad), np.empty_like(pad)
    for i in range(0, n, LANES):
        si, ci = sincos(vload1(pad, i))
        vstore1(s, i, si)
        vstore1(c, i, ci)
    return s[:n], c[:n]
