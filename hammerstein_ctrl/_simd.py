"""Four float64 lanes as one value of compiled code: an LLVM ``<4 x double>`` that stays in registers.

numba vectorises a loop over the columns of a small array, but keeps that
array in memory, so a recursion carried from one sample to the next goes
through a store and a load every step; tuples of scalars are not
vectorised at all.  The type here is a numba value whose machine form is one
256-bit vector: a loop-carried ``Lanes4`` is a register, and ``+``, ``-``,
``*`` on two of them are single vector instructions, each rounded as IEEE
arithmetic rounds it (no fused multiply-add, as in the scalar code of the
kernels, so that a lane gives the bits of the same steps in scalars).  Four
lanes is the width a 256-bit unit (AVX2, or AVX-512 run on two 256-bit
halves) executes at full rate.

The generated normal-equation pass (:func:`hammerstein_ctrl.kernels.get_normal_kernel`)
keeps its forward-difference neighbours in these.  The package builds that
pass in C (:mod:`~hammerstein_ctrl._kernel_c` writes each operation on
GCC's four-lane vectors); numba's compile of the same source, with this
type, gives the same bits and serves the tests as its oracle.

Examples
--------
>>> from hammerstein_ctrl._jit import cached_njit
>>> @cached_njit(cache=False)
... def demo(a, b):
...     v = pack(a, b, 3.0, 4.0) * splat(2.0) + splat(1.0)
...     return lane(v, 0), lane(rotate(v, 1), 0), lane(v, 3)
>>> demo(1.0, 2.0)
(3.0, 5.0, 9.0)
>>> @cached_njit(cache=False)
... def updated(a, b):
...     v = pack(a, b, 3.0, 4.0)
...     v -= splat(1.0)
...     v += v * splat(0.5)
...     v *= splat(2.0)
...     return lane(v, 0), lane(v, 3)
>>> updated(1.0, 2.0)
(0.0, 9.0)
>>> @cached_njit(cache=False)
... def moved(a, out):
...     store(load(a, 1) * splat(2.0), out, 0)
>>> import numpy as np
>>> out = np.zeros(4); moved(np.arange(6.0), out); out
array([2., 4., 6., 8.])
"""

from __future__ import annotations

import operator

from llvmlite import ir
from numba import types
from numba.extending import intrinsic, lower_builtin, models, register_model, type_callable

__all__ = ["Lanes4", "lanes4", "WIDTH", "pack", "splat", "lane", "rotate", "load", "store"]

#: Lanes of one vector.
WIDTH = 4
#: Floating-point flags of the vector arithmetic: none (IEEE arithmetic, no contraction into FMAs).
_FLAGS = ()
_VECTOR = ir.VectorType(ir.DoubleType(), WIDTH)
_I32 = ir.IntType(32)


class Lanes4(types.Type):
    """numba type of four float64 lanes (machine form ``<4 x double>``)."""

    def __init__(self):
        super().__init__(name="Lanes4")


#: The one instance of :class:`Lanes4`.
lanes4 = Lanes4()


@register_model(Lanes4)
class _Lanes4Model(models.PrimitiveModel):
    def __init__(self, dmm, fe_type):
        super().__init__(dmm, fe_type, _VECTOR)


def _shuffle(builder, v, order):
    return builder.shuffle_vector(v, v, ir.Constant(ir.VectorType(_I32, WIDTH), list(order)))


@intrinsic
def pack(typingctx, a, b, c, d):
    """The vector of four floats, lane 0 first."""
    def codegen(context, builder, signature, args):
        v = ir.Constant(_VECTOR, ir.Undefined)
        for i, (value, ty) in enumerate(zip(args, signature.args)):
            v = builder.insert_element(v, context.cast(builder, value, ty, types.float64), ir.Constant(_I32, i))
        return v
    return lanes4(a, b, c, d), codegen


@intrinsic
def splat(typingctx, a):
    """The vector with ``a`` in every lane."""
    def codegen(context, builder, signature, args):
        value = context.cast(builder, args[0], signature.args[0], types.float64)
        v = builder.insert_element(ir.Constant(_VECTOR, ir.Undefined), value, ir.Constant(_I32, 0))
        return _shuffle(builder, v, [0] * WIDTH)
    return lanes4(a), codegen


@intrinsic
def lane(typingctx, v, k):
    """Lane ``k`` (a literal integer) of ``v``."""
    if not isinstance(v, Lanes4) or not isinstance(k, types.IntegerLiteral):
        return None
    index = k.literal_value

    def codegen(context, builder, signature, args):
        return builder.extract_element(args[0], ir.Constant(_I32, index))
    return types.float64(v, k), codegen


@intrinsic
def rotate(typingctx, v, k):
    """``v`` with its lanes moved down by ``k`` (a literal integer): lane ``i`` holds lane ``(i + k) % 4``."""
    if not isinstance(v, Lanes4) or not isinstance(k, types.IntegerLiteral):
        return None
    shift = k.literal_value

    def codegen(context, builder, signature, args):
        return _shuffle(builder, args[0], [(i + shift) % WIDTH for i in range(WIDTH)])
    return lanes4(v, k), codegen


def _flat_float_array(a) -> bool:
    return isinstance(a, types.Array) and a.dtype == types.float64 and a.ndim == 1 and a.layout == "C" and a.aligned


def _lanes_pointer(context, builder, array_type, array, index_type, index):
    """Pointer to ``array[index]`` as a pointer to a vector (elements' alignment)."""
    data = context.make_array(array_type)(context, builder, array).data
    offset = context.cast(builder, index, index_type, types.intp)
    return builder.bitcast(builder.gep(data, [offset]), _VECTOR.as_pointer())


@intrinsic
def load(typingctx, a, i):
    """The vector of ``a[i], ..., a[i + 3]`` (``a`` a C-contiguous float64 array of one dimension; no index is
    checked): one load, where :func:`pack` would take four statements of indexing to compile."""
    if not (_flat_float_array(a) and isinstance(i, types.Integer)):
        return None

    def codegen(context, builder, signature, args):
        pointer = _lanes_pointer(context, builder, signature.args[0], args[0], signature.args[1], args[1])
        return builder.load(pointer, align=8)
    return lanes4(a, i), codegen


@intrinsic
def store(typingctx, v, a, i):
    """Write the lanes of ``v`` to ``a[i], ..., a[i + 3]`` (``a`` as :func:`load` takes it)."""
    if not (isinstance(v, Lanes4) and _flat_float_array(a) and a.mutable and isinstance(i, types.Integer)):
        return None

    def codegen(context, builder, signature, args):
        pointer = _lanes_pointer(context, builder, signature.args[1], args[1], signature.args[2], args[2])
        builder.store(args[0], pointer, align=8)
        return context.get_dummy_value()
    return types.none(v, a, i), codegen


def _register_operator(target, instruction: str):
    """``target(a, b)`` (``+``, ``-``, ``*`` or an in-place form) on two vectors, typed and lowered the way numba
    types and lowers its own arithmetic: one instruction emitted where it is used.

    An ``overload`` made each use a call of a compiled function, resolved
    again through numba's overload machinery and inlined later by LLVM.
    Measured when the change was made (one fresh process each on a 2-core
    machine, numba's registries loaded first): the order-4 pass with 6 to 9
    lanes compiled in 2.9-3.0 s against 3.8-4.3 s; four vector passes and
    four lanes kernels gave the overloads' sums bit for bit on random inputs.
    """
    @type_callable(target)
    def _typer(context):
        def typer(a, b):
            if isinstance(a, Lanes4) and isinstance(b, Lanes4):
                return lanes4
            return None
        return typer

    @lower_builtin(target, Lanes4, Lanes4)
    def _lower(context, builder, signature, args):
        return getattr(builder, instruction)(args[0], args[1], flags=_FLAGS)


for _op, _instruction in ((operator.add, "fadd"), (operator.sub, "fsub"), (operator.mul, "fmul")):
    _register_operator(_op, _instruction)
    _register_operator(getattr(operator, f"i{_op.__name__}"), _instruction)
