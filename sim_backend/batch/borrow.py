"""Borrowed arrays: the same array with no owner, so numba does no reference
counting on it.

numba counts references to every array it holds, with an atomic increment and
decrement (`lock incq`/`lock decq` in NRT_incref/NRT_decref) around each view
it makes and each call it passes one to. The struct-of-arrays step makes
dozens of row views per robot-tick (every `grids[OBJ]` handed to a kernel
function), and perf showed a third of a 10,000-robot tick in those two
instructions. NRT skips a null owner (its meminfo pointer), so an entry
function borrows each array argument once, and every view made from it
inherits the null owner: no atomic operation is left in the step. This is
safe because the caller (Python) holds every array for the whole call and
the step allocates nothing.
"""

from typing import Any

from llvmlite import ir
from numba import njit
from numba.core import cgutils, types
from numba.core.compiler import Compiler
from numba.extending import intrinsic

from sim_backend.batch.transform import TABLE_HI, TABLE_LO


@intrinsic
def borrow(typingctx, value):
    """`value` unchanged; an array comes back without its owner."""
    if not isinstance(value, types.Array):
        def passthrough(context, builder, sig, args):
            return args[0]
        return value(value), passthrough

    def codegen(context, builder, sig, args):
        ary = context.make_array(sig.args[0])(context, builder, value=args[0])
        out = context.make_array(sig.return_type)(context, builder)
        for name in ("nitems", "itemsize", "data", "shape", "strides"):
            setattr(out, name, getattr(ary, name))
        out.meminfo = cgutils.get_null_value(out.meminfo.type)
        out.parent = cgutils.get_null_value(out.parent.type)
        return out._getvalue()
    return value(value), codegen


class NoAlias(Compiler):
    """numba's pipeline with every pointer argument `noalias`: an entry
    function's arrays are apart (transform.state_arrays checks it), so LLVM
    may keep a value it loaded from one array in a register across stores
    to the others. Without it every store to any table (a robot's
    heading, its random stream) made the step load again the robot's index,
    its run and the run's fields (w, n, base, rules, ...) behind every HAL
    call (docs/performance.md)."""

    def __init__(self, typingctx: Any, targetctx: Any, library: Any, args: Any,
                 return_type: Any, flags: Any, locals: Any) -> None:
        flags = flags.copy()
        flags.noalias = True
        super().__init__(typingctx, targetctx, library, args, return_type, flags, locals)


@intrinsic
def prefetch(typingctx, ary, index):
    """kernel.prefetch compiled: a cache prefetch of `ary[index]` (of every
    line of row `index` when `ary` is 2-D, an object table's row), which
    unlike a read never waits for its line (a random order's reads ahead
    would stall the core as long as the misses they spare)."""
    if not isinstance(ary, types.Array) or ary.ndim not in (1, 2) or \
            not isinstance(index, types.Integer):
        return None

    def codegen(context, builder, sig, args):
        aryty = sig.args[0]
        a = context.make_array(aryty)(context, builder, value=args[0])
        # an index read from a narrower table (int32) is widened as numba's own indexing does
        at = context.cast(builder, args[1], sig.args[1], types.intp)
        i64 = ir.IntType(64)
        i8p = ir.IntType(8).as_pointer()
        fnty = ir.FunctionType(ir.VoidType(), [i8p, ir.IntType(32), ir.IntType(32),
                                               ir.IntType(32)])
        fetch = cgutils.get_or_insert_function(builder.module, fnty, "llvm.prefetch.p0i8")
        flags = [ir.Constant(ir.IntType(32), v) for v in (0, 3, 1)]   # read, keep, data
        if aryty.ndim == 1:
            ptr = cgutils.get_item_pointer(context, builder, aryty, a, [at],
                                           wraparound=False)
            builder.call(fetch, [builder.bitcast(ptr, i8p)] + flags)
            return context.get_dummy_value()
        zero = context.get_constant(types.intp, 0)
        ptr = cgutils.get_item_pointer(context, builder, aryty, a, [at, zero],
                                       wraparound=False)
        start = builder.ptrtoint(ptr, i64)
        shape = cgutils.unpack_tuple(builder, a.shape, 2)
        size = builder.mul(builder.sext(shape[1], i64), builder.sext(a.itemsize, i64))
        first = builder.and_(start, ir.Constant(i64, -64))
        end = builder.add(builder.add(start, size), ir.Constant(i64, 63))
        lines = builder.udiv(builder.sub(end, first), ir.Constant(i64, 64))
        with cgutils.for_range(builder, lines) as loop:
            at = builder.add(first, builder.mul(loop.index, ir.Constant(i64, 64)))
            builder.call(fetch, [builder.inttoptr(at, i8p)] + flags)
        return context.get_dummy_value()
    return types.none(ary, index), codegen


@intrinsic
def clear(typingctx, ary, lo, hi):
    """kernel.clear compiled: `ary[lo:hi] = 0` as one memset of a contiguous
    1-D array (the caller's range lies inside it, as the loop it replaces
    would index)."""
    if not isinstance(ary, types.Array) or ary.ndim != 1 or ary.layout != "C" or \
            not isinstance(lo, types.Integer) or not isinstance(hi, types.Integer):
        return None

    def codegen(context, builder, sig, args):
        aryty = sig.args[0]
        a = context.make_array(aryty)(context, builder, value=args[0])
        start = context.cast(builder, args[1], sig.args[1], types.intp)
        stop = context.cast(builder, args[2], sig.args[2], types.intp)
        with builder.if_then(builder.icmp_signed(">", stop, start)):
            ptr = cgutils.get_item_pointer(context, builder, aryty, a, [start],
                                           wraparound=False)
            size = builder.mul(builder.sub(stop, start),
                               context.get_constant(types.intp, context.get_abi_sizeof(
                                   context.get_data_type(aryty.dtype))))
            cgutils.memset(builder, ptr, size, 0)
        return context.get_dummy_value()
    return types.none(ary, lo, hi), codegen


@njit(cache=True, forceinline=True)
def fits(v: int) -> int:
    """`v`, a value stored into an int32 table cell that the transform did
    not prove to fit (transform.TABLE, FunctionTransform.proven), checked:
    outside int32 it is an OverflowError, never a value wrapped round."""
    if v < TABLE_LO or v > TABLE_HI:
        raise OverflowError("a value outside int32 stored into an int field "
                            "(the batch engine's tables: sim_backend/batch/transform.py, TABLE)")
    return v
