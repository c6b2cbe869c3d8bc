"""Whole-block vector operations written directly in LLVM IR (numba intrinsics).

numba's auto-vectoriser turns "OR the 64 per-lane carry bits into one word"
into a chain of masked loads and a horizontal OR; LLVM's own idiom for it is a
single ``bitcast <64 x i1> to i64``, which x86 lowers to vector compares into
mask registers (AVX-512) or ``movmsk`` (AVX2/SSE) and other targets lower
correctly too.  These helpers express a 64-lane block step that way, and the
noise-free ones a whole run of readouts with the accumulator kept in vector
registers (a step per call keeps it in memory, which measured about half as
fast).  Lane ``k`` maps to bit ``k`` of the result, the little-bit-order
packed layout of docs/architecture.md, Conventions.  Everything here is plain,
portable LLVM IR: a few helpers choose between two forms of the same
operation by the target's instruction set (:func:`_target_features`, read
from numba's public configuration or llvmlite's host query), and every form
gives the same bits.
"""

from __future__ import annotations

import functools
import platform

from llvmlite import ir
from numba import types
from numba.core import cgutils
from numba.extending import intrinsic

LANES = 64
_X86 = platform.machine().lower() in ("x86_64", "amd64", "i686", "x86")


@functools.cache
def _target_features() -> frozenset[str]:
    """The CPU features numba compiles for: ``NUMBA_CPU_FEATURES`` when set
    (numba's public configuration), else the host's (llvmlite's
    ``get_host_cpu_features``), as numba itself chooses them."""
    from llvmlite import binding
    from numba.core import config

    features = config.CPU_FEATURES
    if features is None:
        features = binding.get_host_cpu_features().flatten()
    return frozenset(str(features).split(","))


def _avx512(context) -> bool:
    """Whether numba compiles for an x86 CPU with AVX-512 (``context`` unused:
    the same answer for every function of a process)."""
    return _X86 and "+avx512f" in _target_features()


def _avx2_only(context) -> bool:
    """Whether numba compiles for an x86 CPU with AVX2 but not AVX-512: the
    target of :class:`_RunLanes`' pack path."""
    return _X86 and not _avx512(context) and "+avx2" in _target_features()


def _pack_order(width=64) -> list[int]:
    """Where the pack sequence of :meth:`_RunLanes.word` (``width`` 64) or
    :func:`countdown_run32` (``width`` 32) puts each lane: bit ``i`` of its
    word is register lane ``order[i]`` (lane ``r`` is lane ``r % (256 /
    width)`` of 256-bit part ``r // (256 / width)``).  Follows the lanes
    through the instructions' documented lane rules: ``vpblendd`` (even dwords
    from the first source; 64-bit lanes only), ``vpackssdw`` and
    ``vpacksswb`` (each 128-bit half packs its half of the first source, then
    of the second)."""
    per = 256 // width
    parts = [list(range(per * k, per * k + per)) for k in range(LANES // per)]

    def pack(x, y):  # one 256-bit pack: per 128-bit half, x's half then y's
        h = len(x) // 2
        return x[:h] + y[:h] + x[h:] + y[h:]

    if width == 64:
        parts = [[a if i % 2 == 0 else b for a, b in zip(p, q, strict=True) for i in (0, 1)]
                 for p, q in zip(parts[::2], parts[1::2], strict=True)]
    words = [pack(x, y) for x, y in zip(parts[::2], parts[1::2], strict=True)]
    bytes_ = [pack(x, y) for x, y in zip(words[::2], words[1::2], strict=True)]
    return [lane for b in bytes_ for lane in b]


_PACK_ORDER = _pack_order()
_PACK_SLOT = [_PACK_ORDER.index(lane) for lane in range(LANES)]  # register lane → its bit
_PACK_ORDER32 = _pack_order(32)
_PACK_SLOT32 = [_PACK_ORDER32.index(lane) for lane in range(LANES)]


def _part(builder, vec, k):
    """Lanes ``[8k, 8k + 8)`` of a 64-lane vector (one 512-bit register of 64-bit lanes)."""
    lanes = ir.Constant(ir.VectorType(ir.IntType(32), 8), [8 * k + j for j in range(8)])
    return builder.shuffle_vector(vec, ir.Constant(vec.type, ir.Undefined), lanes)


def _quarter(builder, vec, k):
    """Lanes ``[4k, 4k + 4)`` of a 64-lane vector (one 256-bit register of 64-bit lanes)."""
    lanes = ir.Constant(ir.VectorType(ir.IntType(32), 4), [4 * k + j for j in range(4)])
    return builder.shuffle_vector(vec, ir.Constant(vec.type, ir.Undefined), lanes)


def _join(builder, parts):
    """The 64-lane vector of its ``parts`` in order (eight of 8 lanes or sixteen
    of 4: the inverse of :func:`_part` or :func:`_quarter`)."""
    while len(parts) > 1:
        n = 2 * parts[0].type.count
        lanes = ir.Constant(ir.VectorType(ir.IntType(32), n), list(range(n)))
        pairs = zip(parts[::2], parts[1::2], strict=True)
        parts = [builder.shuffle_vector(a, b, lanes) for a, b in pairs]
    return parts[0]


def _byte_of(builder, mask8, k):
    """The 8 bits of an <8 x i1> as bits ``8k`` to ``8k + 7`` of an i64."""
    i64 = ir.IntType(64)
    b = builder.bitcast(mask8, ir.IntType(8))
    return builder.shl(builder.zext(b, i64), i64(8 * k))


def _mask_word(context, builder, mask):
    """The 64 bits of a <64 x i1> (lane ``k`` → bit ``k``) as one i64: the
    plain bit cast, which LLVM lowers to vector compares into mask registers
    (AVX-512) or ``movmsk`` (AVX2/SSE)."""
    return builder.bitcast(mask, ir.IntType(LANES))


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
        ir.Constant(ir.VectorType(ir.IntType(32), vec.count), None))


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


def _out_bytes(context, builder, sig, args, k):
    """The data pointer of the C-contiguous uint8 array argument ``k`` (any
    rank) and the next three arguments: the byte index ``first`` of the first
    word, the ``stride`` in bytes from one readout's word to the next, and the
    ``nbytes`` (1 to 8) of each word that lie in the row."""
    data = context.make_array(sig.args[k])(context, builder, args[k]).data
    first, stride, nbytes = (context.cast(builder, args[k + j], sig.args[k + j], types.intp)
                             for j in (1, 2, 3))
    return data, first, stride, nbytes


def _store_word(builder, data, index, word, nbytes, width=8):
    """Store the low ``nbytes`` (up to ``width``, 8 or 4; none when ≤ 0) bytes
    of the i64 ``word`` at byte ``index`` of ``data``, lowest byte first (the
    little-endian layout): one unaligned ``width``-byte store, or byte by byte
    for the last, partial word of a row (whose other bytes belong to the next
    row)."""
    i8, i64, full_int = ir.IntType(8), ir.IntType(64), ir.IntType(8 * width)
    ptr = builder.gep(data, [index])
    with builder.if_else(builder.icmp_signed("==", nbytes, i64(width)),
                         likely=True) as (full, part):
        with full:
            value = word if width == 8 else builder.trunc(word, full_int)
            builder.store(value, builder.bitcast(ptr, full_int.as_pointer()), align=1)
        with part:
            with cgutils.for_range(builder, nbytes) as loop:
                byte = builder.trunc(builder.lshr(word, builder.mul(loop.index, i64(8))), i8)
                builder.store(byte, builder.gep(ptr, [loop.index]), align=1)


class _RunLanes:
    """The lane layout of a noise-free run loop (:func:`_run_loop`).

    On AVX2 without AVX-512 a compare yields a 64-bit mask per lane and
    ``bitcast <64 x i1> to i64`` costs 14 packs, 7 cross-lane permutes and 2
    ``vpmovmskb`` per readout.  Held in the order the packs leave the lanes in
    (:func:`_pack_order`), the word needs 8 blends, 6 packs and 2
    ``vpmovmskb`` and no permute: the block's rows are put in that order once
    per call (:meth:`load`) and the accumulator back in lane order at the end
    (:meth:`store_acc`).  The accumulator is also held biased by 2⁶³ there, so the
    carry ``new < old`` (unsigned) is one signed compare (AVX2 has no unsigned
    one: each side otherwise needs an exclusive or).  Measured on an AVX2
    host (AMD EPYC), a 64-lane block's readout in a cache-resident loop:
    5.9 ns against 11.9 before.  Elsewhere lanes stay in order and the word is
    :func:`_mask_word`'s."""

    def __init__(self, context, builder):
        self.builder = builder
        self.context = context
        self.packs = _avx2_only(context)
        self.bias = _splat(builder, ir.VectorType(ir.IntType(64), LANES),
                           ir.IntType(64)(1 << 63))

    def _shuffle(self, vec, order):
        return self.builder.shuffle_vector(
            vec, ir.Constant(vec.type, ir.Undefined),
            ir.Constant(ir.VectorType(ir.IntType(32), LANES), order))

    def load(self, ptr):
        """The 64 lanes at ``ptr``, in the loop's order."""
        vec = self.builder.load(ptr, align=8)
        return self._shuffle(vec, _PACK_SLOT) if self.packs else vec

    def load_acc(self, ptr):
        """The accumulator at ``ptr`` (uint64 lanes), in the loop's order and form."""
        acc = self.load(ptr)
        return self.builder.xor(acc, self.bias) if self.packs else acc

    def store_acc(self, ptr, acc):
        """The inverse of :meth:`load_acc`."""
        if self.packs:
            acc = self._shuffle(self.builder.xor(acc, self.bias), _PACK_ORDER)
        self.builder.store(acc, ptr, align=8)

    def carry(self, old, new):
        """The lanes whose add ``old + inc = new`` carried (unsigned wrap)."""
        if self.packs:
            return self.builder.icmp_signed("<", new, old)
        return self.builder.icmp_unsigned("<", new, old)

    def zero(self):
        """A cleared accumulator lane, in the loop's form."""
        return self.bias if self.packs else ir.Constant(self.bias.type, None)

    def word(self, mask):
        """The 64 bits of ``mask`` (<64 x i1>, the loop's order) as an i64,
        lane ``k`` of the block at bit ``k``."""
        if not self.packs:
            return _mask_word(self.context, self.builder, mask)
        full = self.builder.sext(mask, ir.VectorType(ir.IntType(64), LANES))
        return self.word_of_parts([_quarter(self.builder, full, k) for k in range(LANES // 4)])

    def word_of_parts(self, parts):
        """The word of sixteen (or eight) 4-lane masks (<4 x i64>, all ones or
        zero, in the loop's order): blends, packs and two ``vpmovmskb`` (one)."""
        b = self.builder
        v8 = ir.VectorType(ir.IntType(32), 8)
        parts = [b.bitcast(x, v8) for x in parts]
        # one dword per lane (both halves of a 64-bit mask are equal): vpblendd
        odd = ir.Constant(v8, [0, 9, 2, 11, 4, 13, 6, 15])
        return self.word_of_dwords([b.shuffle_vector(x, y, odd)
                                    for x, y in zip(parts[::2], parts[1::2], strict=True)])

    def word_of_dwords(self, dwords):
        """The word of the sign bits of eight (or four) <8 x i32> (in the order
        of :func:`_pack_order` of width 32): four ``vpackssdw`` and two
        ``vpacksswb`` (half as many for four), which saturate and so keep each
        sign, and two ``vpmovmskb`` (one)."""
        b = self.builder
        i16, i32, i64 = ir.IntType(16), ir.IntType(32), ir.IntType(64)
        words = [self._x86("llvm.x86.avx2.packssdw", ir.VectorType(i16, 16), x, y)
                 for x, y in zip(dwords[::2], dwords[1::2], strict=True)]
        bytes_ = [self._x86("llvm.x86.avx2.packsswb", ir.VectorType(ir.IntType(8), 32), x, y)
                  for x, y in zip(words[::2], words[1::2], strict=True)]
        halves = [b.zext(self._x86("llvm.x86.avx2.pmovmskb", i32, x), i64) for x in bytes_]
        if len(halves) == 1:  # four vectors: a 32-bit word
            return halves[0]
        return b.or_(halves[0], b.shl(halves[1], i64(32)))

    def fixed(self, q):
        """``fptoui(q)`` of 64 lanes of float64 in [0, 2⁶⁴) (the truncated
        integer), exactly.  AVX2 has no vector conversion of float64 to a
        64-bit integer, and LLVM's fallback converts lane by lane in scalar
        code; the pack path builds the integer from the bits instead: the
        53-bit significand with its implicit bit, shifted left by
        ``exponent − 52`` (at most 11 below 2⁶⁴) and right by ``52 − exponent``
        with ``vpsllvq`` and ``vpsrlvq``, which give 0 for any count above 63
        (a negative count included), so one of the two is 0 and values below
        1 (0 included) give 0: 8 vector instructions for 4 lanes, no compare."""
        b = self.builder
        uvec = ir.VectorType(ir.IntType(64), LANES)
        if not self.packs:
            return b.fptoui(q, uvec)

        def splat(v):
            return _splat(b, uvec, ir.IntType(64)(v))

        bits = b.bitcast(q, uvec)
        significand = b.or_(b.and_(bits, splat((1 << 52) - 1)), splat(1 << 52))
        up = b.sub(b.lshr(bits, splat(52)), splat(1075))  # exponent − 52 (the sign bit is 0)
        down = b.sub(splat(0), up)
        v4 = ir.VectorType(ir.IntType(64), 4)
        parts = []
        for k in range(LANES // 4):
            s, u, d = (_quarter(b, x, k) for x in (significand, up, down))
            parts.append(b.or_(self._x86("llvm.x86.avx2.psllv.q.256", v4, s, u),
                               self._x86("llvm.x86.avx2.psrlv.q.256", v4, s, d)))
        return _join(b, parts)

    def _x86(self, name, ret, *args):
        fn = self.builder.module.declare_intrinsic(
            name, [], ir.FunctionType(ret, [a.type for a in args]))
        return self.builder.call(fn, list(args))


def _run_loop(context, builder, lanes, acc_ptr, count, out, charge_at, zero_reset):
    """``count`` readouts of a 64-lane block with the accumulator held in
    registers (``lanes``: a :class:`_RunLanes`): readout ``k`` adds
    ``charge_at(k)`` (a <64 x i64> increment in ``lanes``' order), and its
    carry bits go to the word at byte ``first + k·stride`` of ``out``
    (:meth:`_RunLanes.word`; zero reset: :func:`_zero_reset_step`)."""
    data, first, stride, nbytes = out
    slot = cgutils.alloca_once(builder, acc_ptr.type.pointee)
    builder.store(lanes.load_acc(acc_ptr), slot)
    with cgutils.for_range(builder, count) as loop:
        old = builder.load(slot)
        inc = charge_at(loop.index)
        if zero_reset:
            new, word = _zero_reset_step(context, builder, lanes, old, inc)
        else:
            new = builder.add(old, inc)
            word = lanes.word(lanes.carry(old, new))
        builder.store(new, slot)
        _store_word(builder, data, builder.add(first, builder.mul(loop.index, stride)), word,
                    nbytes)
    lanes.store_acc(acc_ptr, builder.load(slot))


def _zero_halves_loop(context, builder, lanes, acc_ptr, count, out, inc):
    """``count`` zero-reset readouts of a constant increment ``inc`` (in
    ``lanes``' order) on the pack path, 32 lanes at a time: the first half's
    run, then the second's, each storing its 4 bytes of every readout's word
    (fewer at a row's end).  On 16 vector registers the 64-lane loop held
    the accumulator, the increment and the masks that both clear the lanes
    and make the word, and spilled half the accumulator to the stack each
    readout (56 stack moves against modulo's 25); a half fits.  Zero reset's
    static stream then ran at 0.73–0.76× modulo's throughput, against
    0.59–0.67× (AMD EPYC host, 2048 readouts, two processes each)."""
    data, first, stride, nbytes = out
    i32, i64 = ir.IntType(32), ir.IntType(64)
    acc = lanes.load_acc(acc_ptr)
    halves = []
    for h in (0, 1):
        sel = ir.Constant(ir.VectorType(i32, 32), list(range(32 * h, 32 * h + 32)))
        acc_h = builder.shuffle_vector(acc, ir.Constant(acc.type, ir.Undefined), sel)
        inc_h = builder.shuffle_vector(inc, ir.Constant(inc.type, ir.Undefined), sel)
        bias_h = builder.shuffle_vector(lanes.bias, ir.Constant(acc.type, ir.Undefined), sel)
        slot = cgutils.alloca_once(builder, acc_h.type)
        builder.store(acc_h, slot)
        n = builder.sub(nbytes, i64(4 * h))
        n = builder.select(builder.icmp_signed(">", n, i64(4)), i64(4), n)
        with cgutils.for_range(builder, count) as loop:
            old = builder.load(slot)
            total = builder.add(old, inc_h)
            carry = lanes.carry(old, total)
            builder.store(builder.select(carry, bias_h, total), slot)
            full = builder.sext(carry, ir.VectorType(i64, 32))
            word = lanes.word_of_parts([_quarter(builder, full, k) for k in range(8)])
            index = builder.add(builder.add(first, builder.mul(loop.index, stride)), i64(4 * h))
            _store_word(builder, data, index, word, n, width=4)
        halves.append(builder.load(slot))
    joined = builder.shuffle_vector(halves[0], halves[1],
                                    ir.Constant(ir.VectorType(i32, 64), list(range(64))))
    lanes.store_acc(acc_ptr, joined)


def _zero_reset_step(context, builder, lanes, old, inc):
    """``(new accumulator, carry word)`` of one zero-reset readout: ``old + inc``
    (wrapping), cleared where it carried.

    The lanes that keep their sum are decided before the add, ``old ≤ ~inc``
    (no carry), so the clearing is the add itself with zero-masking, in
    eight 8-lane parts whose masks go straight to their byte of the word
    (:func:`_byte_of`; AVX-512).  Without AVX-512 the carry is found as
    modulo's (``old + inc < old``, :meth:`_RunLanes.carry`) and the sum then
    cleared: on an AVX2 host (no unsigned compare, no masked add) 0.82×
    [0.66–0.83] and 0.82× [0.74–1.04] of modulo's throughput against 0.74×
    [0.73–0.80] and 0.73× [0.68–0.73] with the compare before the add
    (static, 4096 readouts in 512-readout chunks, 5 alternating rounds, two
    processes per build)."""
    if not _avx512(context):  # the carry as modulo's, then cleared
        total = builder.add(old, inc)
        carry = lanes.carry(old, total)
        return builder.select(carry, lanes.zero(), total), lanes.word(carry)
    limit = builder.not_(inc)  # the largest accumulator that does not carry
    parts = []
    word = None
    for k in range(LANES // 8):
        o = _part(builder, old, k)
        keep_k = builder.icmp_unsigned("<=", o, _part(builder, limit, k))
        parts.append(builder.select(keep_k, builder.add(o, _part(builder, inc, k)),
                                    ir.Constant(o.type, None)))
        byte = _byte_of(builder, keep_k, k)
        word = byte if word is None else builder.or_(word, byte)
    return _join(builder, parts), builder.not_(word)


def _is_bytes(t) -> bool:
    return isinstance(t, types.Array) and t.dtype == types.uint8 and t.layout == "C"


def _all_int(*ts) -> bool:
    return all(isinstance(t, types.Integer) for t in ts)


@intrinsic
def store_word(typingctx, out, index, word, nbytes):
    """``out.flat[index : index + nbytes] = `` the low ``nbytes`` (1 to 8)
    bytes of the uint64 ``word``, lowest first (``out`` a C-contiguous uint8
    array): a readout's 64 spike bits of one block, in the packed layout."""
    if not (_is_bytes(out) and _all_int(index, nbytes) and word == types.uint64):
        return None

    def codegen(context, builder, sig, args):
        data = context.make_array(sig.args[0])(context, builder, args[0]).data
        index_, nbytes_ = (context.cast(builder, args[j], sig.args[j], types.intp) for j in (1, 3))
        _store_word(builder, data, index_, args[2], nbytes_)
        return context.get_dummy_value()

    return types.void(out, index, word, nbytes), codegen


def _carry_run(zero_reset):
    @intrinsic
    def carry_run(typingctx, acc, inc, out, first, stride, nbytes, count):
        if not (_is_u64_array(acc) and (_is_u64_array(inc) or _is_f64_array(inc))
                and _is_bytes(out) and _all_int(first, stride, nbytes, count)):
            return None

        def codegen(context, builder, sig, args):
            vec = ir.VectorType(ir.IntType(64), LANES)
            zero = ir.IntType(64)(0)
            lanes = _RunLanes(context, builder)
            if _is_f64_array(sig.args[1]):  # charges: fptoui(charge·2⁶⁴)
                fvec = ir.VectorType(ir.DoubleType(), LANES)
                charge = lanes.load(_lanes_ptr(context, builder, sig, args, 1, zero, fvec))
                inc_v = lanes.fixed(builder.fmul(charge, ir.Constant(fvec, [2.0**64] * LANES)))
            else:
                inc_v = lanes.load(_lanes_ptr(context, builder, sig, args, 1, zero, vec))
            count_ = context.cast(builder, args[6], sig.args[6], types.intp)
            if zero_reset and lanes.packs:
                _zero_halves_loop(context, builder, lanes,
                                  _lanes_ptr(context, builder, sig, args, 0, zero, vec), count_,
                                  _out_bytes(context, builder, sig, args, 2), inc_v)
                return context.get_dummy_value()
            _run_loop(context, builder, lanes,
                      _lanes_ptr(context, builder, sig, args, 0, zero, vec),
                      count_, _out_bytes(context, builder, sig, args, 2),
                      lambda k: inc_v, zero_reset)
            return context.get_dummy_value()

        return types.void(acc, inc, out, first, stride, nbytes, count), codegen

    return carry_run


def _linear_carry_run(zero_reset):
    @intrinsic
    def linear_carry_run(typingctx, acc, level, slope, gain, offset, n0, t_a, inv,
                         out, first, stride, nbytes, count):
        arrays = (level, slope, gain, offset)
        if not (_is_u64_array(acc) and all(_is_f64_array(a) for a in arrays)
                and isinstance(n0, types.Integer) and isinstance(t_a, types.Float)
                and isinstance(inv, types.Float) and _is_bytes(out)
                and _all_int(first, stride, nbytes, count)):
            return None

        def codegen(context, builder, sig, args):
            uvec = ir.VectorType(ir.IntType(64), LANES)
            fvec = ir.VectorType(ir.DoubleType(), LANES)
            zero = ir.IntType(64)(0)
            lanes = _RunLanes(context, builder)
            a, d, g, o = (lanes.load(_lanes_ptr(context, builder, sig, args, k, zero, fvec))
                          for k in (1, 2, 3, 4))
            n_first = context.cast(builder, args[5], sig.args[5], types.int64)
            t_a_ = context.cast(builder, args[6], sig.args[6], types.float64)
            inv_ = context.cast(builder, args[7], sig.args[7], types.float64)
            scale = ir.Constant(fvec, [2.0**64] * LANES)
            half = ir.Constant(ir.DoubleType(), 0.5)

            def charge_at(k):
                # phi = (float(n) + 0.5 - t_a) * inv, then (g·(a + d·phi) + o)·2⁶⁴:
                # the scalar kernel's operations in its order (no contraction)
                n = builder.sitofp(builder.add(n_first, k), ir.DoubleType())
                phi = builder.fmul(builder.fsub(builder.fadd(n, half), t_a_), inv_)
                level_now = builder.fadd(a, builder.fmul(d, _splat(builder, fvec, phi)))
                q = builder.fadd(builder.fmul(g, level_now), o)
                return lanes.fixed(builder.fmul(q, scale))

            count_ = context.cast(builder, args[12], sig.args[12], types.intp)
            _run_loop(context, builder, lanes,
                      _lanes_ptr(context, builder, sig, args, 0, zero, uvec),
                      count_, _out_bytes(context, builder, sig, args, 8), charge_at, zero_reset)
            return context.get_dummy_value()

        return (types.void(acc, level, slope, gain, offset, n0, t_a, inv, out, first, stride,
                           nbytes, count), codegen)

    return linear_carry_run


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


carry_run64 = _carry_run(False)
carry_run64.__doc__ = """``count`` readouts of a constant charge for a 64-lane block:
    ``acc[:64] += inc[:64]`` (uint64, wrapping; a float64 ``inc`` holds charges
    in [0, 1) threshold, added as ``fptoui(charge·2⁶⁴)``) per readout, the accumulator
    held in registers throughout, and readout ``k``'s 64 carry-out bits
    (lane ``j`` → bit ``j``) stored as :func:`store_word` does, at byte
    ``first + k·stride`` of the C-contiguous uint8 ``out`` (flat index), its
    low ``nbytes`` bytes (8, or fewer for a row's last block).  With the
    accumulator fraction in units of 2⁻⁶⁴ θ, a carry is a threshold crossing.
    ``acc`` and ``inc`` must hold 64 contiguous lanes; no bounds check."""
linear_carry_run64 = _linear_carry_run(False)
linear_carry_run64.__doc__ = """``count`` readouts of a linear-radiance segment for a 64-lane block.

    Readout ``k`` (clock index ``n = n0 + k``, ``phi = (n + ½ − t_a)·inv``)
    gives lane ``j`` the charge ``q = (gain·(level + slope·phi) + offset)·2⁶⁴``
    (float64, evaluated in exactly this order, truncated to uint64: the same
    value as the scalar kernel and the NumPy reference), ``acc += q``
    (wrapping); its carry bits are stored as in :func:`carry_run64`.  Every
    charge must lie in [0, 1) threshold (the caller checks), else the
    conversion is undefined."""
paper_carry_add64 = _paper_carry_add(False)
paper_carry_add64.__doc__ = """One readout of paper-mode noise (docs/model.md) for a 64-lane block.

    Lane ``k`` (index ``start + k``) gets the noisy level
    ``x = max(level + sd·z, 0)``, the charge ``q = (gain·x + offset)·2⁶⁴``
    (float64, in exactly this order: the scalar kernel's and the NumPy
    reference's value), ``acc += q`` (wrapping) and its carry bits, returned
    as one uint64 (lane ``k`` → bit ``k``; a carry is a threshold crossing).
    Every charge must lie in [0, 1) threshold (the caller bounds it with the
    largest normal deviate), else the conversion is undefined."""
#: The same for zero reset: a lane that carried is cleared to 0 (for charges
#: < 1 θ a carry is exactly a firing, and zero reset drops the residual).
carry_run64_zero = _carry_run(True)
linear_carry_run64_zero = _linear_carry_run(True)
paper_carry_add64_zero = _paper_carry_add(True)


@intrinsic
def counting_down_pays(typingctx):
    """Whether static zero-reset runs should be counted down
    (:func:`countdown_run32`, ``spikesim._zero_period``) rather than added and
    cleared per readout: a compile-time constant, true on AVX2 without
    AVX-512, where it was measured (3.8 against 7.6 ns a block-readout at
    512 readouts, AMD EPYC host); the AVX-512 add-and-clear loop runs at
    modulo's speed already."""
    def codegen(context, builder, sig, args):
        return ir.IntType(1)(int(_avx2_only(context)))

    return types.boolean(), codegen


@intrinsic
def countdown_run32(typingctx, count_down, period, out, first, stride, nbytes, count):
    """``count`` readouts of zero reset's periodic firing for a 64-lane block:
    per readout ``c −= 1`` and, where ``c`` went below 0, a spike and
    ``c = period`` (each lane fires every ``period + 1`` readouts once it has
    fired), the counters held as int32 in registers throughout; the spike
    words are stored as :func:`carry_run64` stores its carry words.
    ``count_down`` and ``period`` (uint64, 64 contiguous lanes, values below
    2³¹) are the readouts before each lane's next and each later firing,
    less one; ``count_down`` is updated.

    Eight 32-bit lanes per 256-bit register against four of the 64-bit
    accumulator, and no compare: on AVX2 the spike bits are the counters' sign
    bits, packed (``vpackssdw``, ``vpacksswb`` saturate, keeping the sign) and
    moved out with ``vpmovmskb``, the lanes held in the packs' order
    (:func:`_pack_order` of width 32); the reset is a ``vblendvps`` on the same
    sign bits."""
    if not (_is_u64_array(count_down) and _is_u64_array(period) and _is_bytes(out)
            and _all_int(first, stride, nbytes, count)):
        return None

    def codegen(context, builder, sig, args):
        v64 = ir.VectorType(ir.IntType(64), LANES)
        v32 = ir.VectorType(ir.IntType(32), LANES)
        lanes = _RunLanes(context, builder)
        c_ptr, period_ptr = (_lanes_ptr(context, builder, sig, args, k, ir.IntType(64)(0), v64)
                             for k in (0, 1))

        def load(ptr):
            vec = builder.trunc(builder.load(ptr, align=8), v32)
            return lanes._shuffle(vec, _PACK_SLOT32) if lanes.packs else vec

        period_v = load(period_ptr)
        data, first_, stride_, nbytes_ = _out_bytes(context, builder, sig, args, 2)
        count_ = context.cast(builder, args[6], sig.args[6], types.intp)
        slot = cgutils.alloca_once(builder, v32)
        builder.store(load(c_ptr), slot)
        with cgutils.for_range(builder, count_) as loop:
            c = builder.sub(builder.load(slot), ir.Constant(v32, [1] * LANES))
            fired = builder.icmp_signed("<", c, ir.Constant(v32, None))
            builder.store(builder.select(fired, period_v, c), slot)
            if lanes.packs:
                word = lanes.word_of_dwords([_part(builder, c, k) for k in range(LANES // 8)])
            else:
                word = _mask_word(context, builder, fired)
            _store_word(builder, data, builder.add(first_, builder.mul(loop.index, stride_)),
                        word, nbytes_)
        c = builder.load(slot)
        if lanes.packs:
            c = lanes._shuffle(c, _PACK_ORDER32)
        builder.store(builder.zext(c, v64), c_ptr, align=8)
        return context.get_dummy_value()

    return types.void(count_down, period, out, first, stride, nbytes, count), codegen


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


def _bit_count(name, flag):
    """An intrinsic calling LLVM's ``name`` on a uint64 (with a constant i1
    ``flag`` argument where the intrinsic takes one)."""

    @intrinsic
    def bit_count(typingctx, mask):
        if mask != types.uint64:
            return None

        def codegen(context, builder, sig, args):
            i64, i1 = ir.IntType(64), ir.IntType(1)
            params = [i64] if flag is None else [i64, i1]
            fn = builder.module.declare_intrinsic(name, [i64], ir.FunctionType(i64, params))
            return builder.call(fn, [args[0]] if flag is None else [args[0], i1(flag)])

        return types.uint64(mask), codegen

    return bit_count


lowest_bit_index = _bit_count("llvm.cttz", 1)
lowest_bit_index.__doc__ = """Index of the lowest set bit of a non-zero uint64 (``cttz``)."""
popcount64 = _bit_count("llvm.ctpop", None)
popcount64.__doc__ = """Number of set bits of a uint64 (``ctpop``)."""



@intrinsic
def prefer_wide_vectors(typingctx):
    """Ask LLVM to vectorise the calling function's loops with the widest
    vectors the CPU has (the function attribute ``"prefer-vector-width"="512"``).

    LLVM's x86 default for AVX-512 CPUs prefers 256-bit vectors, to avoid the
    clock drop some older parts showed, and with it the cost model left loops
    of hashes and table gathers scalar: on this project's host the block's
    normal deviates (:func:`spikesim.rng.normals_into`) took 158 ns per 64
    lanes instead of 79.  The attribute is ignored where the CPU
    has no wider vectors.  The function is also marked ``noinline``: an
    inlined copy would be optimised under its caller's attributes.  llvmlite
    only lets a fixed list of attribute names be added, so the string
    attribute is put into the set directly; it is printed verbatim into the
    function's definition."""

    def codegen(context, builder, sig, args):
        set.add(builder.function.attributes, '"prefer-vector-width"="512"')
        builder.function.attributes.add("noinline")  # an inlined copy would lose the attribute
        return context.get_dummy_value()

    return types.void(), codegen


def _event_cached_run(zero_reset, static):
    @intrinsic
    def event_cached_run(typingctx, wait, lam, dlam, electrons, gnext, wmin, m0, lam_max,
                         backlog, out, first, stride, nbytes, count):
        arrays = (wait, lam, dlam, electrons, gnext, wmin)
        if not (all(_is_f64_array(a) for a in arrays) and isinstance(m0, types.Integer)
                and all(isinstance(x, types.Float) for x in (lam_max, backlog))
                and _is_bytes(out) and _all_int(first, stride, nbytes, count)):
            return None
        result = types.UniTuple(types.uint64, 3)

        def codegen(context, builder, sig, args):
            i64 = ir.IntType(64)
            fvec = ir.VectorType(ir.DoubleType(), LANES)
            part = ir.VectorType(ir.DoubleType(), 8)
            zero = i64(0)
            wait_ptr = _lanes_ptr(context, builder, sig, args, 0, zero, fvec)
            lo_ptr = _lanes_ptr(context, builder, sig, args, 5, zero, fvec)
            # static: λ itself, loaded once; moving: λ and its change read in the
            # loop, part by part (loaded once before it, LLVM copied them to the
            # stack at every call, the loop then reading the copies)
            e, gn = ([_part(builder, builder.load(
                _lanes_ptr(context, builder, sig, args, k, zero, fvec), align=8), j)
                for j in range(LANES // 8)] for k in (3, 4))
            rows = {k: builder.bitcast(_lanes_ptr(context, builder, sig, args, k, zero, fvec),
                                       part.as_pointer()) for k in (1, 2)}

            def row_part(k, j):
                return builder.load(builder.gep(rows[k], [i64(j)]), align=8)
            lam_static = [row_part(1, j) for j in range(LANES // 8)] if static else None
            m_first = context.cast(builder, args[6], sig.args[6], types.int64)
            lam_max_, backlog_ = (
                context.cast(builder, args[k], sig.args[k], types.float64) for k in (7, 8))
            data, first_, stride_, nbytes_ = _out_bytes(context, builder, sig, args, 9)
            count_ = context.cast(builder, args[13], sig.args[13], types.int64)
            cap = _splat(builder, part, lam_max_)
            backlog_v = _splat(builder, part, backlog_)
            floor = [builder.fmul(backlog_v, ej) for ej in e]  # −BACKLOG_MAX·E
            fzero = ir.Constant(part, [0.0] * 8)
            spent = ir.Constant(part, [float("inf")] * 8)

            def electrons_at(m, j):
                # λ = min(lam + m·dlam, cap): spikesim._event.charge_at's operations
                x = builder.fadd(row_part(1, j), builder.fmul(m, row_part(2, j)))
                return builder.select(builder.fcmp_ordered("<", cap, x), cap, x)

            k_slot = cgutils.alloca_once_value(builder, zero)
            bad_slot = cgutils.alloca_once_value(builder, zero)
            used_slot = cgutils.alloca_once_value(builder, zero)
            w_old, lo_old = builder.load(wait_ptr, align=8), builder.load(lo_ptr, align=8)
            w_slots = [cgutils.alloca_once_value(builder, _part(builder, w_old, j))
                       for j in range(LANES // 8)]
            lo_slots = [cgutils.alloca_once_value(builder, _part(builder, lo_old, j))
                        for j in range(LANES // 8)]
            loop = builder.append_basic_block("event_run.loop")
            body = builder.append_basic_block("event_run.body")
            done = builder.append_basic_block("event_run.done")
            builder.branch(loop)
            builder.position_at_end(loop)
            k = builder.load(k_slot)
            builder.cbranch(builder.icmp_signed("<", k, count_), body, done)
            builder.position_at_end(body)
            word = taken = None
            m = None if static else _splat(builder, part, builder.sitofp(
                builder.add(m_first, k), ir.DoubleType()))
            for j in range(LANES // 8):  # 8 lanes at a time, in order (see the docstring)
                lam = lam_static[j] if static else electrons_at(m, j)
                w_in = builder.load(w_slots[j])
                w = builder.fsub(w_in, lam)
                fired = builder.fcmp_ordered("<=", w, fzero)
                lo = builder.load(lo_slots[j])
                take = builder.and_(fired, builder.fcmp_ordered(">=", w, lo))  # lo = +∞: not ready
                lo = builder.select(take, spent, lo)
                builder.store(lo, lo_slots[j])
                if zero_reset:
                    new_w = gn[j]
                else:
                    new_w = builder.fadd(w, gn[j])
                    new_w = builder.select(builder.fcmp_ordered("<", new_w, floor[j]), floor[j],
                                           new_w)
                w = builder.select(take, new_w, w)
                builder.store(w, w_slots[j])
                fired_byte, take_byte = (_byte_of(builder, m, j) for m in (fired, take))
                word = fired_byte if word is None else builder.or_(word, fired_byte)
                taken = take_byte if taken is None else builder.or_(taken, take_byte)
            builder.store(builder.or_(builder.load(used_slot), taken), used_slot)
            _store_word(builder, data, builder.add(first_, builder.mul(k, stride_)), word,
                        nbytes_)
            builder.store(builder.add(k, i64(1)), k_slot)
            bad = builder.xor(word, taken)  # fired, not taken
            builder.store(bad, bad_slot)
            builder.cbranch(builder.icmp_unsigned("!=", bad, zero), done, loop)
            builder.position_at_end(done)
            builder.store(_join(builder, [builder.load(x) for x in w_slots]), wait_ptr, align=8)
            builder.store(_join(builder, [builder.load(x) for x in lo_slots]), lo_ptr, align=8)
            return context.make_tuple(builder, result, [
                builder.load(k_slot), builder.load(bad_slot), builder.load(used_slot)])

        return (result(wait, lam, dlam, electrons, gnext, wmin, m0, lam_max, backlog, out,
                       first, stride, nbytes, count), codegen)

    return event_cached_run


event_cached_run64 = _event_cached_run(False, False)
event_cached_run64.__doc__ = """Up to ``count`` readouts of the event-driven shot-noise model
    (:mod:`spikesim._event`) for a 64-lane block, without charge loss, the
    waits held in registers, its firings taken from the block's cache of drawn
    cycles while it can (modulo or subtract reset).

    Readout ``k`` takes lane ``j``'s ``λ = min(lam + m·dlam, lam_max)``
    electrons (``m = m0 + k`` readouts after its segment's reference, as a
    float64; :func:`spikesim._event.charge_at`, in exactly this order) off its
    ``wait``; a lane fires where the wait is ≤ 0, and every readout's firing
    bits are stored as :func:`store_word` does (at byte ``first + k·stride``
    of ``out``).  A lane that fires at a wait ≥ its ``wmin`` (+∞: no draw
    cached) takes its cached draw, ``max(wait + gnext, backlog·E)``
    (``backlog`` = −2⁶²; the operations of
    :func:`spikesim._event.apply_cached`), and its ``wmin`` becomes +∞.

    The call ends after the first readout with a firing lane that could not
    take its draw, or after ``count`` readouts.  Returns ``(k, bad, used)``:
    the number of readouts done, the lanes of the last one still to settle
    (their waits are those at the firing; 0 when none), and the lanes that
    took their draw (once each at most), whose need and cycle the caller then
    advances (:func:`spikesim._event.event_sync`).

    Each readout works through the block 8 lanes at a time (on 64-lane
    vectors LLVM made all sixteen masks of a readout first and spilled most of
    them: 17.4 against 11.1 ns a block-readout, static, cache-resident)."""
#: The same for zero reset (a lane takes ``gnext`` itself), and for runs of
#: constant radiance (``dlam`` all zero, the caller checks), which subtract
#: ``lam`` itself (``dlam``, ``m0`` and ``lam_max`` unread).
event_cached_run64_zero = _event_cached_run(True, False)
event_cached_run64_static = _event_cached_run(False, True)
event_cached_run64_zero_static = _event_cached_run(True, True)


@intrinsic
def expands_natively(typingctx):
    """Whether :func:`expand_lanes64` is one instruction per 8 lanes
    (``vexpandpd``, AVX-512): a compile-time constant.  Elsewhere LLVM
    splits an expanding load into a branch per lane, on the unpredictable
    bits of the mask: on an AMD EPYC host (AVX2) three such put-backs of a
    refill took 630 ns at 28 of 64 lanes, a loop over the set bits 53."""
    def codegen(context, builder, sig, args):
        return ir.IntType(1)(int(_avx512(context)))

    return types.boolean(), codegen


@intrinsic
def expand_lanes64(typingctx, mask, src, dst):
    """``dst[k] = src[j]`` for each lane ``k`` of ``mask`` (lane ``k`` ↔ bit
    ``k``), ``j`` its rank among them (the inverse of packing the lanes of
    ``mask`` into contiguous rows in lane order; ``src`` holds at least that
    many values, and no more are read); the other lanes keep their value.
    ``dst``: 64 contiguous float64 lanes, written as eight whole 8-lane
    stores (AVX-512: an expanding load, ``vexpandpd``, merged into the old
    part), where a refill would otherwise store lane by lane.  Without
    AVX-512 LLVM makes it a branch per lane (:func:`expands_natively`)."""
    if not (mask == types.uint64 and _is_f64_array(src) and _is_f64_array(dst)):
        return None

    def codegen(context, builder, sig, args):
        i64 = ir.IntType(64)
        part = ir.VectorType(ir.DoubleType(), 8)
        fn = builder.module.declare_intrinsic(
            "llvm.masked.expandload.v8f64", [],
            ir.FunctionType(part, [ir.DoubleType().as_pointer(), ir.VectorType(ir.IntType(1), 8),
                                   part]))
        src_data = context.make_array(sig.args[1])(context, builder, args[1]).data
        dst_base = builder.bitcast(context.make_array(sig.args[2])(context, builder, args[2]).data,
                                   part.as_pointer())
        ctpop = builder.module.declare_intrinsic("llvm.ctpop", [i64])
        offset = i64(0)
        for k in range(LANES // 8):
            byte = builder.trunc(builder.lshr(args[0], i64(8 * k)), ir.IntType(8))
            p = builder.gep(dst_base, [i64(k)])
            new = builder.call(fn, [builder.gep(src_data, [offset]),
                                    builder.bitcast(byte, ir.VectorType(ir.IntType(1), 8)),
                                    builder.load(p, align=8)])
            builder.store(new, p, align=8)
            offset = builder.add(offset, builder.call(ctpop, [builder.zext(byte, i64)]))
        return context.get_dummy_value()

    return types.void(mask, src, dst), codegen
