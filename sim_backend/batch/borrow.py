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

from numba.core import cgutils, types
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
