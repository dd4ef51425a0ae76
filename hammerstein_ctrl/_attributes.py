"""LLVM function attributes a compiled function asks for from inside its own body.

numba gives no way to set the attributes of the machine function it makes
from a Python function; a call of one of these, compiled into the function,
sets one on the function being compiled.  The call itself compiles to
nothing (and run as Python it does nothing); the attribute's own cost is
a few instructions of prologue or a real call, as each says.  These two
change how fast code runs, not what it computes, in the functions that use
them (none reassociates floating point across a call), so the caches of
those functions are not keyed on this file (the generated kernels' are, with
the rest of their sources).

* :func:`align_stack`: the stack frame aligned to a cache line, so vectors
  kept in it never straddle two (the generated vector, lanes and array passes);
* :func:`never_inline`: the function stays one function in its callers'
  code instead of a copy at each call (small helpers called many times in one
  caller: the copies, each unrolled and vectorised by LLVM, made most of the
  code compiled on a first use).

Examples
--------
>>> from hammerstein_ctrl._jit import cached_njit
>>> @cached_njit(cache=False)
... def aligned(x):
...     align_stack()
...     return 2.0 * x
>>> aligned(1.5), "alignstack=64" in aligned.inspect_llvm(aligned.signatures[0])
(3.0, True)
>>> @cached_njit(cache=False)
... def apart(x):
...     never_inline()
...     return x + 1.0
>>> @cached_njit(cache=False)
... def twice(x):
...     return apart(x) + apart(2.0 * x)
>>> twice(1.0)
5.0
>>> code = twice.inspect_llvm(twice.signatures[0]).splitlines()
>>> sum("call" in line and "5apart" in line for line in code)       # two calls, not two inlined copies
2
"""

from __future__ import annotations

from numba import types
from numba.extending import intrinsic, overload

__all__ = ["align_stack", "never_inline", "STACK_ALIGNMENT"]

#: Stack alignment (bytes) :func:`align_stack` gives a compiled function: a cache line.
STACK_ALIGNMENT = 64


def _attribute_call(name: str, doc: str, apply):
    """A function of no arguments that, compiled into a function, applies ``apply`` to that function's LLVM
    attributes (and does nothing when run as Python, e.g. under ``NUMBA_DISABLE_JIT``)."""
    def typing(typingctx):
        def codegen(context, builder, signature, args):
            apply(builder.function.attributes)
            return context.get_dummy_value()
        return types.none(), codegen
    typing.__name__ = typing.__qualname__ = f"_{name}_intrinsic"
    attribute = intrinsic(typing)

    def call():
        return None
    call.__name__ = call.__qualname__ = name
    call.__doc__ = doc

    @overload(call, inline="always")        # inlined, so the intrinsic's function is the caller's
    def _compiled():
        def impl():
            attribute()
        return impl
    return call


def _align(attributes):
    attributes.alignstack = STACK_ALIGNMENT
    # llvmlite writes no attribute at all while its set of named ones is empty; numba's compiled functions
    # return their errors as status codes, so they never unwind (the function loses its unwind table: debuggers
    # and profilers that unwind by DWARF do not see its frame, those that follow frame pointers do)
    attributes.add("nounwind")


align_stack = _attribute_call("align_stack", """Align the calling compiled function's stack frame to
:data:`STACK_ALIGNMENT` bytes (LLVM's ``alignstack``, with ``nounwind``).

A function whose vectors do not all fit in registers keeps the rest in its
stack frame.  The calling convention aligns the stack to 16 bytes only, so
without this a 32-byte vector slot straddles two cache lines in half the
processes and call depths, and the same loop ran 1.2-1.6x slower there.
Scalar code gains nothing (its 8- and 16-byte slots never straddle a line).
Only where the function is called through its own code (from Python or by
address): a compiled caller into which LLVM inlines it drops the alignment.
""", _align)

never_inline = _attribute_call("never_inline", """Keep the calling compiled function out of line in the code
of its callers (LLVM's ``noinline``).

For small helpers that a caller calls several times: LLVM otherwise copies
the helper into each call site, unrolled and vectorised for every trip
count, and compiles all the copies again in every caller that links it.
Each call then costs a real call.
""", lambda attributes: attributes.add("noinline"))
