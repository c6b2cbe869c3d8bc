"""Whole-block vector operations written directly in LLVM IR (numba intrinsics).

numba's auto-vectoriser turns "OR the 64 per-lane carry bits into one word"
into a chain of masked loads and a horizontal OR; LLVM's own idiom for it is a
single ``bitcast <64 x i1> to i64``, which x86 lowers to vector compares into
mask registers (AVX-512) or ``movmsk`` (AVX2/SSE) and other targets lower
correctly too.  These helpers express one 64-lane block step that way.  Lane
``k`` maps to bit ``k`` of the result, the little-bit-order packed layout of
docs/architecture.md, Conventions.
"""

from __future__ import annotations

from llvmlite import ir
from numba import types
from numba.extending import intrinsic

LANES = 64


def _is_u64_array(t) -> bool:
    return isinstance(t, types.Array) and t.dtype == types.uint64


def _is_f64_array(t) -> bool:
    return isinstance(t, types.Array) and t.dtype == types.float64


def _lanes_ptr(context, builder, sig, args, k, off, vec):
    """Pointer to the ``vec``-typed lanes of array argument ``k``, from index ``off``."""
    data = context.make_array(sig.args[k])(context, builder, args[k]).data
    return builder.bitcast(builder.gep(data, [off]), vec.as_pointer())


def _splat(builder, vec, value):
    """``value`` broadcast to every lane of vector type ``vec``."""
    return builder.shuffle_vector(
        builder.insert_element(ir.Constant(vec, ir.Undefined), value, ir.IntType(64)(0)),
        ir.Constant(vec, ir.Undefined),
        ir.Constant(ir.VectorType(ir.IntType(32), LANES), None))


def _store_step(builder, acc_ptr, old, new, zero_reset):
    """Store the new accumulator (cleared where it carried, for zero reset) and
    return the 64 carry bits as one i64."""
    carry = builder.icmp_unsigned("<", new, old)
    if zero_reset:
        new = builder.select(carry, ir.Constant(new.type, None), new)
    builder.store(new, acc_ptr, align=8)
    return builder.bitcast(carry, ir.IntType(LANES))


def _add_charge(builder, acc_ptr, charge, zero_reset):
    """``acc += fptoui(charge·2⁶⁴)`` on 64 lanes; returns the carry bits."""
    uvec = ir.VectorType(ir.IntType(64), LANES)
    q = builder.fmul(charge, ir.Constant(charge.type, [2.0**64] * LANES))
    old = builder.load(acc_ptr, align=8)
    return _store_step(builder, acc_ptr, old, builder.add(old, builder.fptoui(q, uvec)),
                       zero_reset)


def _carry_add(zero_reset):
    @intrinsic
    def carry_add(typingctx, acc, inc, start):
        if not (_is_u64_array(acc) and _is_u64_array(inc) and isinstance(start, types.Integer)):
            return None

        def codegen(context, builder, sig, args):
            vec = ir.VectorType(ir.IntType(64), LANES)
            off = context.cast(builder, args[2], sig.args[2], types.intp)
            pa = _lanes_ptr(context, builder, sig, args, 0, off, vec)
            pb = _lanes_ptr(context, builder, sig, args, 1, off, vec)
            old = builder.load(pa, align=8)
            new = builder.add(old, builder.load(pb, align=8))
            return _store_step(builder, pa, old, new, zero_reset)

        return types.uint64(acc, inc, start), codegen

    return carry_add


def _linear_carry_add(zero_reset):
    @intrinsic
    def linear_carry_add(typingctx, acc, level, slope, gain, offset, phi, start):
        arrays = (level, slope, gain, offset)
        if not (_is_u64_array(acc) and all(_is_f64_array(a) for a in arrays)
                and isinstance(phi, types.Float) and isinstance(start, types.Integer)):
            return None

        def codegen(context, builder, sig, args):
            uvec = ir.VectorType(ir.IntType(64), LANES)
            fvec = ir.VectorType(ir.DoubleType(), LANES)
            off = context.cast(builder, args[6], sig.args[6], types.intp)
            a, d, g, o = (builder.load(_lanes_ptr(context, builder, sig, args, k, off, fvec),
                                       align=8) for k in (1, 2, 3, 4))
            phi_v = _splat(builder, fvec,
                           context.cast(builder, args[5], sig.args[5], types.float64))
            level_now = builder.fadd(a, builder.fmul(d, phi_v))
            q = builder.fadd(builder.fmul(g, level_now), o)
            return _add_charge(builder, _lanes_ptr(context, builder, sig, args, 0, off, uvec), q,
                               zero_reset)

        return types.uint64(acc, level, slope, gain, offset, phi, start), codegen

    return linear_carry_add


def _paper_carry_add(zero_reset):
    @intrinsic
    def paper_carry_add(typingctx, acc, level, z, sd, gain, offset, start):
        arrays = (level, z, sd, gain, offset)
        if not (_is_u64_array(acc) and all(_is_f64_array(a) for a in arrays)
                and isinstance(start, types.Integer)):
            return None

        def codegen(context, builder, sig, args):
            uvec = ir.VectorType(ir.IntType(64), LANES)
            fvec = ir.VectorType(ir.DoubleType(), LANES)
            off = context.cast(builder, args[6], sig.args[6], types.intp)
            lv, zv, sv, g, o = (builder.load(_lanes_ptr(context, builder, sig, args, k, off, fvec),
                                             align=8) for k in (1, 2, 3, 4, 5))
            x = builder.fadd(lv, builder.fmul(sv, zv))
            zero = ir.Constant(fvec, [0.0] * LANES)
            x = builder.select(builder.fcmp_ordered(">", x, zero), x, zero)
            q = builder.fadd(builder.fmul(g, x), o)
            return _add_charge(builder, _lanes_ptr(context, builder, sig, args, 0, off, uvec), q,
                               zero_reset)

        return types.uint64(acc, level, z, sd, gain, offset, start), codegen

    return paper_carry_add


carry_add64 = _carry_add(False)
carry_add64.__doc__ = """``acc[start:start+64] += inc[start:start+64]`` (uint64, wrapping).

    Returns the 64 carry-out bits as one uint64 (lane ``k`` → bit ``k``): with
    the accumulator fraction in units of 2⁻⁶⁴ θ, a carry is a threshold
    crossing.  Both arrays must be C-contiguous; no bounds check."""
linear_carry_add64 = _linear_carry_add(False)
linear_carry_add64.__doc__ = """One readout of a linear-radiance segment for a 64-lane block.

    Lane ``k`` (index ``start + k``) gets the charge
    ``q = (gain·(level + slope·phi) + offset)·2⁶⁴`` (float64, evaluated in
    exactly this order, truncated to uint64: the same value as the scalar
    kernel and the NumPy reference), ``acc += q`` (wrapping), and the carry
    bits are returned as in :func:`carry_add64`.  Every charge must lie in
    [0, 1) threshold (the caller checks), else the conversion is undefined."""
paper_carry_add64 = _paper_carry_add(False)
paper_carry_add64.__doc__ = """One readout of paper-mode noise (docs/model.md) for a 64-lane block.

    Lane ``k`` (index ``start + k``) gets the noisy level
    ``x = max(level + sd·z, 0)``, the charge ``q = (gain·x + offset)·2⁶⁴``
    (float64, in exactly this order: the scalar kernel's and the NumPy
    reference's value), ``acc += q`` (wrapping) and its carry bit, returned as
    in :func:`carry_add64`.  Every charge must lie in [0, 1) threshold (the
    caller bounds it with the largest normal deviate), else the conversion is
    undefined."""
#: The same three steps for zero reset: a lane that carried is cleared to 0
#: (for charges < 1 θ a carry is exactly a firing, and zero reset drops the residual).
carry_add64_zero = _carry_add(True)
linear_carry_add64_zero = _linear_carry_add(True)
paper_carry_add64_zero = _paper_carry_add(True)


@intrinsic
def high_bits_at_least64(typingctx, values, shift, low, span):
    """Mask of the 64 lanes of ``values`` (uint64, C-contiguous) whose
    ``(v >> shift) − low`` is ``>= span`` (unsigned, wrapping): lane ``k`` →
    bit ``k``.  With ``low``/``span`` the central bins of a table indexed by
    the top bits, these are the lanes outside it."""
    if not (_is_u64_array(values) and all(isinstance(t, types.Integer)
                                          for t in (shift, low, span))):
        return None

    def codegen(context, builder, sig, args):
        uvec = ir.VectorType(ir.IntType(64), LANES)
        v = builder.load(_lanes_ptr(context, builder, sig, args, 0, ir.IntType(64)(0), uvec),
                         align=8)

        def splat(k):
            return _splat(builder, uvec, context.cast(builder, args[k], sig.args[k], types.uint64))

        rel = builder.sub(builder.lshr(v, splat(1)), splat(2))
        return builder.bitcast(builder.icmp_unsigned(">=", rel, splat(3)), ir.IntType(LANES))

    return types.uint64(values, shift, low, span), codegen


@intrinsic
def lowest_bit_index(typingctx, mask):
    """Index of the lowest set bit of a non-zero uint64 (``cttz``)."""
    if mask != types.uint64:
        return None

    def codegen(context, builder, sig, args):
        i64 = ir.IntType(64)
        fnty = ir.FunctionType(i64, [i64, ir.IntType(1)])
        fn = builder.module.declare_intrinsic("llvm.cttz", [i64], fnty)
        return builder.call(fn, [args[0], ir.Constant(ir.IntType(1), 1)])

    return types.uint64(mask), codegen

