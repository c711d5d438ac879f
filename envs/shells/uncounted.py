"""Arrays a compiled kernel hands its stage functions without reference counts.

numba counts the references to every array it moves: each time an array (alone or in a tuple)
is bound to a stage function's argument, assigned, or goes out of use, an atomic increment or
decrement of its memory record is made, and LLVM's pruning removes only the pairs it can match
within simple control flow. A kernel whose row loop calls a dozen stages with a few arrays each
pays hundreds of atomic operations a row: on a virtual machine each costs as much as a dozen
floating-point operations, a large share of a row of a couple of microseconds.

:func:`uncounted` returns the same arrays (same data, shape, strides and type) without their
memory record: numba's increments and decrements of such an array find no record and return
at once. It is safe only for arrays that something else keeps alive for as long as the views
are used: the caller's arguments (held by the Python caller until the kernel returns), or a
scratch buffer the kernel itself keeps (used again after the last use of its views). The views
must not be returned from the kernel or stored in a longer-lived container.
"""

from __future__ import annotations

from numba.core import cgutils, types
from numba.extending import intrinsic

__all__ = ["uncounted"]


def _strip(context, builder, ty, value):
    """``value`` of numba type ``ty`` with every array's memory record and parent set to null
    (through tuples, nested or not); other values as they are (a new reference, as numba
    expects of a returned value)."""
    if isinstance(ty, types.Array):
        ary = context.make_array(ty)(context, builder, value=value)
        ary.meminfo = cgutils.get_null_value(ary.meminfo.type)
        ary.parent = cgutils.get_null_value(ary.parent.type)
        return ary._getvalue()
    if isinstance(ty, types.BaseTuple):
        items = [
            _strip(context, builder, t, builder.extract_value(value, j)) for j, t in enumerate(ty)
        ]
        return context.make_tuple(builder, ty, items)
    context.nrt.incref(builder, ty, value)
    return value


@intrinsic
def uncounted(typingctx, arrays):
    """``arrays`` (an array or a tuple of arrays, nested tuples too) as views without a
    reference count (module docstring: only for arrays kept alive elsewhere)."""

    def codegen(context, builder, signature, args):
        return _strip(context, builder, signature.args[0], args[0])

    return arrays(arrays), codegen
