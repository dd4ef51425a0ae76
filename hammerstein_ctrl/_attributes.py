"""LLVM function attributes a compiled function asks for from inside its own body.

numba gives no way to set the attributes of the machine function it makes
from a Python function; a call of one of these intrinsics, compiled into the
function, sets one on the function being compiled (and costs nothing at run
time).  An attribute changes how fast the code runs, never what it computes,
so the caches of functions that use these are not keyed on this file (the
generated kernels' are, with the rest of their sources).

* :func:`align_stack`: the stack frame aligned to a cache line, so vectors
  kept in it never straddle two (the generated kernels);
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
>>> aligned(1.5), "alignstack(64)" in aligned.inspect_llvm(aligned.signatures[0])
(3.0, True)
>>> @cached_njit(cache=False)
... def apart(x):
...     never_inline()
...     return x + 1.0
>>> apart(1.0), "noinline" in apart.inspect_llvm(apart.signatures[0])
(2.0, True)
"""

from __future__ import annotations

from numba import types
from numba.extending import intrinsic

__all__ = ["align_stack", "never_inline", "STACK_ALIGNMENT"]

#: Stack alignment (bytes) :func:`align_stack` gives a compiled function: a cache line.
STACK_ALIGNMENT = 64


def _attribute_intrinsic(name: str, doc: str, apply):
    """An intrinsic of no arguments whose code applies ``apply`` to the attributes of the function compiling it."""
    def typing(typingctx):
        def codegen(context, builder, signature, args):
            attributes = builder.function.attributes
            apply(attributes)
            # llvmlite writes no attribute at all while its set of named ones is empty; numba's compiled
            # functions return their errors as status codes, so they never unwind
            attributes.add("nounwind")
            return context.get_dummy_value()
        return types.none(), codegen
    typing.__name__ = typing.__qualname__ = name
    typing.__doc__ = doc
    return intrinsic(typing)


def _align(attributes):
    attributes.alignstack = STACK_ALIGNMENT


align_stack = _attribute_intrinsic("align_stack", """Align the calling compiled function's stack frame to
:data:`STACK_ALIGNMENT` bytes.

A function whose vectors do not all fit in registers keeps the rest in its
stack frame.  The calling convention aligns the stack to 16 bytes only, so
without this a 32-byte vector slot straddles two cache lines in half the
processes and call depths, and the same loop ran up to 1.4x slower there.
""", _align)

never_inline = _attribute_intrinsic("never_inline", """Keep the calling compiled function out of line in the code
of its callers (LLVM's ``noinline``).

For small helpers that a caller calls several times: LLVM otherwise copies
the helper into each call site, unrolled and vectorised for every trip
count, and compiles all the copies again in every caller that links it.
""", lambda attributes: attributes.add("noinline"))
