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
from numba.core import cgutils, types
from numba.core.compiler import Compiler
from numba.extending import intrinsic


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
    to the others. Without it every store to any int64 table (a robot's
    heading, its random stream) made the step load again the robot's index,
    its run and the run's fields (w, n, base, rules, ...) behind every HAL
    call (docs/performance.md)."""

    def __init__(self, typingctx: Any, targetctx: Any, library: Any, args: Any,
                 return_type: Any, flags: Any, locals: Any) -> None:
        flags = flags.copy()
        flags.noalias = True
        super().__init__(typingctx, targetctx, library, args, return_type, flags, locals)


@intrinsic
def prefetch(typingctx, array, index):
    """Ask the cache for array[index] ahead of its read (`llvm.prefetch`:
    never faults, so an index off the array is harmless); the compiled form
    of body.prefetch."""
    if not isinstance(array, types.Array) or not isinstance(index, types.Integer):
        return None

    def codegen(context, builder, sig, args):
        ary = context.make_array(sig.args[0])(context, builder, value=args[0])
        ptr = builder.gep(ary.data, [builder.sext(args[1], ir.IntType(64))
                                     if args[1].type.width < 64 else args[1]])
        i8p = ir.IntType(8).as_pointer()
        i32 = ir.IntType(32)
        fn = cgutils.get_or_insert_function(
            builder.module, ir.FunctionType(ir.VoidType(), [i8p, i32, i32, i32]),
            "llvm.prefetch.p0")
        # read, the strongest locality (all cache levels), the data cache
        builder.call(fn, [builder.bitcast(ptr, i8p), i32(0), i32(3), i32(1)])
        return context.get_dummy_value()
    return types.none(array, index), codegen
