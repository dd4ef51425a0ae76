"""The C text of a generated kernel, translated from its Python source (:mod:`~hammerstein_ctrl._kernel_source`).

The kernels are written once, as Python source (numba compiles it where C
cannot take a kernel's output map, and in the tests as this translation's
oracle); the same source is the input of this translator, which writes the C
function a C compiler builds in a fraction of numba's time.  It takes the
small subset of Python the generators write: assignments of scalars, of
array entries and of an array's row, ``for ... in range`` (a literal step),
``while``, ``if``, ``break``, ``raise``, ``return`` (an output map's
formula), arithmetic and comparisons, ``x if c else y``, ``np.isfinite``,
``np.tanh``, ``np.exp``, ``np.abs``, ``np.sign``, ``np.minimum``,
``np.maximum`` (numba's scalar semantics), ``len``/``.size`` of a vector,
``np.inf``/``np.nan``, ``min``, local arrays (``np.empty``/``np.zeros`` of
literal size) and the four-lane vectors of :mod:`~hammerstein_ctrl._simd`
(``splat``, ``load``, ``store``, ``lane``, ``rotate``).  Where C would mean
something else it is refused: ``and``/``or`` of values that are not truth
values, ``min`` of floats, ``/``, ``//`` and ``%`` but by a positive literal
(integers only; they round as Python's), negative or float indices, tuple
assignments whose values read their targets, loops whose body assigns their
variable or bounds, a map that does not end by returning.  A loop's
variable is not read after its loop by the generators (C leaves it past
the last value).  Anything else is a
``NotImplementedError`` naming it (indices are not checked against the
arrays' sizes: the kernel's caller checks those).

Every operation is translated one for one, in the source's order and
grouping, and the C is compiled without contraction or fast-math
(``-ffp-contract=off``), so a kernel's results are the IEEE results of its
source's arithmetic, the same bits on every machine and at every
optimisation level.

The function takes one argument, an array of :data:`ARG_STRUCT` (``data``:
an array's first element, ``shape``: its dimensions; an integer argument is
``shape[0]``), and returns 0, or ``k`` if it stopped at the ``k``-th
``raise`` of its source (:attr:`CKernel.messages`).

Examples
--------
>>> src = '''
... @cached_njit(signatures=(kernel_signature("r1 w1"),))
... def kernel(x, out):
...     for i in range(x.shape[0]):
...         out[i] = 2.0 * x[i] if np.isfinite(x[i]) else 0.0
... '''
>>> print(translate(src).text.split("kernel(const hc_arg *args)\\n{")[1].strip())   # doctest: +NORMALIZE_WHITESPACE
const double *x = (const double *)args[0].data;
const int64_t x_0 = args[0].shape[0];
double *out = (double *)args[1].data;
const int64_t out_0 = args[1].shape[0];
int64_t i;
for (i = 0; i < x_0; i += 1) {
    out[i] = (isfinite(x[i]) ? (2.0 * x[i]) : 0.0);
}
return 0;
}
"""

from __future__ import annotations

import ast
import re
import textwrap
from dataclasses import dataclass
from pathlib import Path

__all__ = ["translate", "CSource", "ARG_STRUCT", "HEADER"]

#: The C declaration of one argument of a translated kernel (the package's C library reads the same header).
ARG_STRUCT = (Path(__file__).resolve().parent / "_native_kernel.h").read_text()
#: What every translated kernel's C starts with.
HEADER = f"""#include <math.h>
#include <stdint.h>
#include <string.h>

{ARG_STRUCT}
typedef double hc_v4 __attribute__((vector_size(32)));
typedef int64_t hc_i4 __attribute__((vector_size(32)));

static inline hc_v4 hc_load(const double *a) {{ hc_v4 v; memcpy(&v, a, sizeof v); return v; }}
static inline void hc_store(hc_v4 v, double *a) {{ memcpy(a, &v, sizeof v); }}
static inline hc_v4 hc_splat(double x) {{ return (hc_v4){{x, x, x, x}}; }}
static inline double hc_sign(double x) {{ return x > 0 ? 1.0 : (x < 0 ? -1.0 : x); }}
static inline double hc_minimum(double a, double b) {{ return isnan(a) ? a : (isnan(b) ? b : (b < a ? b : a)); }}
static inline double hc_maximum(double a, double b) {{ return isnan(a) ? a : (isnan(b) ? b : (b > a ? b : a)); }}
static inline int64_t hc_floordiv(int64_t a, int64_t b)
{{
    return a / b - ((a % b != 0) && ((a < 0) != (b < 0)));
}}
static inline int64_t hc_mod(int64_t a, int64_t b)
{{
    int64_t r = a % b;
    return r + ((r != 0 && ((r < 0) != (b < 0))) ? b : 0);
}}
#if defined(__clang__)
#define HC_ROTATE(v, k) __builtin_shufflevector(v, v, (k) % 4, (1 + (k)) % 4, (2 + (k)) % 4, (3 + (k)) % 4)
#else
#define HC_ROTATE(v, k) __builtin_shuffle(v, (hc_i4){{(k) % 4, (1 + (k)) % 4, (2 + (k)) % 4, (3 + (k)) % 4}})
#endif
"""

_INT, _FLOAT, _VECTOR = "int64_t", "double", "hc_v4"
#: A row of a two-dimensional array (an output map's parameters), held as a pointer.
_ROW = "const double *"
#: numpy's scalar functions an output map's formula calls, as C (numba's semantics: NaN propagates through
#: ``minimum``/``maximum``, which return their first argument between equals; ``sign`` of a zero or NaN is itself).
_FLOAT_FUNCTIONS = {"np.tanh": "tanh", "np.exp": "exp", "np.abs": "fabs", "np.sign": "hc_sign",
                    "np.minimum": "hc_minimum", "np.maximum": "hc_maximum", "h": "h"}
_OPERATORS = {ast.Add: "+", ast.Sub: "-", ast.Mult: "*", ast.BitAnd: "&"}
#: Integer operators with Python's rounding (towards minus infinity), as C functions.
_INTEGER_FUNCTIONS = {ast.FloorDiv: "hc_floordiv", ast.Mod: "hc_mod"}
_COMPARISONS = {ast.Lt: "<", ast.LtE: "<=", ast.Gt: ">", ast.GtE: ">=", ast.Eq: "==", ast.NotEq: "!="}
_SIGNATURE = re.compile(r'kernel_signature\("([^"]*)"\)')


@dataclass(frozen=True)
class CSource:
    """A translated kernel: its C ``text`` (a function named ``kernel``), its arguments' ``names`` and
    :func:`~hammerstein_ctrl._jit.kernel_signature` ``codes``, and the ``messages`` of its ``raise`` statements."""

    text: str
    names: tuple
    codes: tuple
    messages: tuple
    #: The fewest parameters the output map reads (its largest literal index into them, plus one; one at least
    #: where it computes an index; 0: no map or none read).
    map_params: int = 0


class _Arrays:
    """The arrays a kernel indexes: its arguments (dimensions read at run time) and its local arrays (literal)."""

    def __init__(self):
        self.dims: dict = {}

    def index(self, name: str, indices: list) -> str:
        dims = self.dims[name]
        if len(indices) != len(dims):
            raise NotImplementedError(f"{name} has {len(dims)} dimensions, indexed with {len(indices)}")
        flat = indices[0]
        for dim, i in zip(dims[1:], indices[1:]):
            flat = f"({flat}) * {dim} + ({i})"
        return f"{name}[{flat}]"


class _Translator:
    def __init__(self, function: ast.FunctionDef, codes: list):
        self.arrays = _Arrays()
        self.types: dict = {}
        self.locals: dict = {}
        self.messages: list = []
        self.names = [a.arg for a in function.args.args]
        self.codes = codes
        if len(codes) != len(self.names):
            raise NotImplementedError("the kernel's signature does not name every argument")
        for name, code in zip(self.names, codes):
            if code in ("i", "f"):
                self.types[name] = _INT if code == "i" else _FLOAT
            elif code[0] in "rw" and code[1:].isdigit():
                self.arrays.dims[name] = [f"{name}_{k}" for k in range(int(code[1:]))]
            else:
                raise NotImplementedError(f"argument code {code!r}")
        self.function = function
        self.returns = False            # True for an output map's formula (a function of one sample)
        self.map_source = None          # the C of the output map h, if the kernel calls one
        self.rows: dict = {}            # names holding a row of a two-dimensional array, and that array
        self.assigned: dict = {}        # each name's assigned values (plain assignments, in order)
        for node in ast.walk(function):
            if isinstance(node, ast.Assign):
                for target in {t.id for t in node.targets if isinstance(t, ast.Name)}:
                    self.assigned.setdefault(target, []).append(node.value)
        self._infer(function.body)

    # -- types ---------------------------------------------------------------------------------------------------
    def _infer(self, body):
        """Type every assigned name: an integer unless some assignment gives it a float (or a vector)."""
        for _ in range(8):
            before = dict(self.types)
            for node in ast.walk(ast.Module(body=body, type_ignores=[])):
                if isinstance(node, ast.Assign):
                    for target in node.targets:
                        self._assign_type(target, node.value)
                elif isinstance(node, ast.AugAssign) and isinstance(node.target, ast.Name):
                    self._widen(node.target.id, self._type(node.value))
                elif isinstance(node, ast.For):
                    self._widen(node.target.id, _INT)
            if self.types == before:
                return
        raise NotImplementedError("the kernel's types do not settle")

    def _assign_type(self, target, value):
        if isinstance(target, ast.Name) and self._row_of(value) is not None:
            self.types[target.id] = _ROW
            self.rows[target.id] = self._row_of(value)
            return
        if isinstance(target, ast.Name):
            if _call_name(value) in ("np.empty", "np.zeros"):
                shape = value.args[0].elts if isinstance(value.args[0], ast.Tuple) else [value.args[0]]
                dims = [ast.unparse(d) for d in shape]
                if self.arrays.dims.setdefault(target.id, dims) != dims:
                    raise NotImplementedError(f"local array {target.id} made with shapes {self.arrays.dims[target.id]} "
                                              f"and {dims}")
                size = 1
                for d in shape:
                    size *= self._largest(d)
                self.locals[target.id] = max(size, self.locals.get(target.id, 0))
            else:
                self._widen(target.id, self._type(value))
        elif isinstance(target, ast.Tuple):
            values = value.elts if isinstance(value, ast.Tuple) else [None] * len(target.elts)
            for t, v in zip(target.elts, values):
                self._widen(t.id, _INT if v is None else self._type(v))

    def _largest(self, node) -> int:
        """The largest value the literal size ``node`` takes: a literal, or a name only ever set to literals."""
        if isinstance(node, ast.Constant) and isinstance(node.value, int):
            return node.value
        values = self.assigned.get(getattr(node, "id", None), [])
        if not values or not all(isinstance(v, ast.Constant) for v in values):
            raise NotImplementedError(f"local array of size {ast.unparse(node)}, not a literal")
        return max(v.value for v in values)

    def _row_of(self, node) -> str | None:
        """The array ``A`` of a row ``A[i]`` of a two-dimensional array; else None."""
        if (isinstance(node, ast.Subscript) and isinstance(node.value, ast.Name)
                and not isinstance(node.slice, ast.Tuple) and len(self.arrays.dims.get(node.value.id, ())) == 2):
            return node.value.id
        return None

    def _truth(self, node) -> bool:
        """Whether ``node`` is a truth value (so that C's ``&&``/``||``, which give 0 or 1, give Python's value)."""
        if isinstance(node, (ast.Compare, ast.BoolOp)) or _call_name(node) == "np.isfinite":
            return True
        if isinstance(node, ast.UnaryOp) and isinstance(node.op, ast.Not):
            return True
        if isinstance(node, ast.Constant):
            return isinstance(node.value, bool)
        if isinstance(node, ast.Name):
            values = self.assigned.get(node.id, [])
            return bool(values) and all(self._truth(v) for v in values if v is not node)
        return False

    def _widen(self, name: str, kind: str):
        order = (_INT, _FLOAT, _VECTOR)
        current = self.types.get(name, _INT)
        if _ROW in (current, kind):
            raise NotImplementedError(f"{name}: a row of an array and a value at once")
        self.types[name] = max(current, kind, key=order.index)

    def _type(self, node) -> str:
        if isinstance(node, ast.Constant):
            return _FLOAT if isinstance(node.value, float) else _INT
        if isinstance(node, ast.Name):
            return self.types.get(node.id, _INT)
        if isinstance(node, ast.Subscript):
            return _INT if _is_shape(node) else _FLOAT
        if isinstance(node, ast.Attribute):
            return _INT if self._size(node) is not None else _FLOAT
        if isinstance(node, ast.BinOp):
            kinds = {self._type(node.left), self._type(node.right)}
            return _VECTOR if _VECTOR in kinds else _FLOAT if _FLOAT in kinds else _INT
        if isinstance(node, ast.UnaryOp):
            return _INT if isinstance(node.op, ast.Not) else self._type(node.operand)
        if isinstance(node, ast.IfExp):
            kinds = {self._type(node.body), self._type(node.orelse)}
            return _FLOAT if _FLOAT in kinds else _INT
        if isinstance(node, ast.Call):
            name = _call_name(node)
            if name in ("splat", "load", "rotate"):
                return _VECTOR
            if name == "lane" or name in _FLOAT_FUNCTIONS:
                return _FLOAT
            if name == "min":
                kinds = {self._type(a) for a in node.args}
                return _FLOAT if _FLOAT in kinds else _INT
            return _INT
        return _INT

    # -- statements ----------------------------------------------------------------------------------------------
    def _declarations(self) -> list:
        """The local arrays and scalars, declared at the top of the function."""
        head = [f"    double {name}[{size}] __attribute__((aligned(64)));" for name, size in self.locals.items()]
        for kind in (_INT, _FLOAT, _VECTOR, _ROW):
            names = sorted(n for n, t in self.types.items() if t == kind and n not in self.names)
            if kind == _ROW:
                names = [f"*{n}" for n in names]
                kind = "const double"
            for start in range(0, len(names), 12):
                head.append(f"    {kind} {', '.join(names[start:start + 12])};")
        return head

    def map_text(self) -> str:
        """An output map's formula ``formula(z, p, extra)`` as ``static inline double h(z, p, p_0, extra,
        extra_0)``."""
        z, p, extra = self.names
        head = [f"static inline double h(double {z}, const double *{p}, int64_t {p}_0, const double *{extra}, "
                f"int64_t {extra}_0)", "{"]
        return "\n".join(head + self._declarations() + self._block(self.function.body, 1) + ["}", ""])

    def text(self) -> str:
        if "f" in self.codes:
            raise NotImplementedError("a kernel's float argument (the library's call passes floats to its own entries)")
        head = ["int64_t kernel(const hc_arg *args)", "{"]
        for k, (name, code) in enumerate(zip(self.names, self.codes)):
            if code == "i":
                head.append(f"    const int64_t {name} = args[{k}].shape[0];")
                continue
            const = "const " if code[0] == "r" else ""
            head.append(f"    {const}double *{name} = ({const}double *)args[{k}].data;")
            dims = ", ".join(f"{name}_{d} = args[{k}].shape[{d}]" for d in range(int(code[1:])))
            head.append(f"    const int64_t {dims};")
        head += self._declarations()
        body = self._block(self.function.body, 1)
        return "\n".join(head + body + ["    return 0;", "}", ""])

    def _block(self, statements, depth: int) -> list:
        lines = []
        for node in statements:
            lines += self._statement(node, depth)
        return lines

    def _statement(self, node, depth: int) -> list:
        pad = "    " * depth
        if isinstance(node, ast.Expr):
            name = _call_name(node.value)
            if isinstance(node.value, ast.Constant) or name == "align_stack":
                return []
            if name == "store":
                v, a, i = node.value.args
                return [f"{pad}hc_store({self._expr(v)}, &{a.id}[{self._expr(i)}]);"]
            raise NotImplementedError(f"statement {ast.unparse(node)}")
        if isinstance(node, ast.Assign):
            return self._assign(node, pad)
        if isinstance(node, ast.AugAssign):
            target = self._target(node.target)
            value = ast.BinOp(left=node.target, op=node.op, right=node.value)
            return [f"{pad}{target} = {self._expr(value)};"]
        if isinstance(node, ast.For):
            return self._for(node, depth)
        if isinstance(node, ast.While):
            return ([f"{pad}while ({self._expr(node.test)}) {{"] + self._block(node.body, depth + 1) + [f"{pad}}}"])
        if isinstance(node, ast.If):
            lines = [f"{pad}if ({self._expr(node.test)}) {{"] + self._block(node.body, depth + 1)
            if node.orelse:
                lines += [f"{pad}}} else {{"] + self._block(node.orelse, depth + 1)
            return lines + [f"{pad}}}"]
        if isinstance(node, ast.Break):
            return [f"{pad}break;"]
        if isinstance(node, ast.Return) and self.returns and node.value is not None:
            return [f"{pad}return {self._expr(node.value)};"]
        if isinstance(node, ast.Raise):
            self.messages.append(ast.literal_eval(node.exc.args[0]) if node.exc.args else "")
            return [f"{pad}return {len(self.messages)};"]
        raise NotImplementedError(f"statement {ast.unparse(node)}")

    def _assign(self, node, pad: str) -> list:
        value = node.value
        if _call_name(value) in ("np.empty", "np.zeros"):
            name = node.targets[0].id
            return [f"{pad}memset({name}, 0, sizeof {name});"] if _call_name(value) == "np.zeros" else []
        target = node.targets[0]
        if isinstance(target, ast.Tuple):
            return self._unpack(target, value, pad)
        if len(node.targets) == 1 and isinstance(target, ast.Name) and target.id in self.rows:
            return [f"{pad}{target.id} = {_map_row(self, value)[0]};"]
        if len(node.targets) == 1:
            return [f"{pad}{self._target(target)} = {self._expr(value)};"]
        temp = [f"{pad}{{", f"{pad}    const {self._type(value)} hc_value = {self._expr(value)};"]
        return temp + [f"{pad}    {self._target(t)} = hc_value;" for t in node.targets] + [f"{pad}}}"]

    def _unpack(self, target, value, pad: str) -> list:
        """``a, b = <shape>`` or ``a, b = x, y`` where no value reads a target (C assigns one after the other)."""
        names = {t.id for t in target.elts if isinstance(t, ast.Name)}
        if len(names) != len(target.elts):
            raise NotImplementedError(f"assignment to {ast.unparse(target)}")
        if isinstance(value, ast.Tuple) and len(value.elts) == len(target.elts):
            if any(isinstance(n, ast.Name) and n.id in names for v in value.elts for n in ast.walk(v)):
                raise NotImplementedError(f"assignment {ast.unparse(target)} = {ast.unparse(value)} (values read "
                                          "the targets)")
            values = value.elts
        elif isinstance(value, ast.Attribute) and value.attr == "shape":
            values = [ast.Subscript(value=value, slice=ast.Constant(k)) for k in range(len(target.elts))]
        else:
            raise NotImplementedError(f"assignment {ast.unparse(target)} = {ast.unparse(value)}")
        return [f"{pad}{t.id} = {self._expr(v)};" for t, v in zip(target.elts, values)]

    def _for(self, node, depth: int) -> list:
        pad, var = "    " * depth, node.target.id
        if _call_name(node.iter) != "range" or node.orelse:
            raise NotImplementedError(f"loop {ast.unparse(node.iter)}")
        if len(node.iter.args) not in (1, 2, 3) or any(self._type(a) != _INT for a in node.iter.args):
            raise NotImplementedError(f"loop over {ast.unparse(node.iter)}")
        step = 1
        if len(node.iter.args) == 3:
            try:
                step = int(ast.literal_eval(node.iter.args[2]))
            except ValueError:
                raise NotImplementedError(f"loop over {ast.unparse(node.iter)} (a literal step)") from None
            if step == 0:
                raise NotImplementedError(f"loop over {ast.unparse(node.iter)}")
        assigned = {t.id for n in ast.walk(ast.Module(body=node.body, type_ignores=[]))
                    for target in (n.targets if isinstance(n, ast.Assign) else [getattr(n, "target", None)])
                    for t in (target.elts if isinstance(target, ast.Tuple) else [target])
                    if isinstance(t, ast.Name)}
        if var in assigned or {n.id for n in ast.walk(node.iter) if isinstance(n, ast.Name)} & assigned:
            raise NotImplementedError(f"loop {ast.unparse(node.target)} in {ast.unparse(node.iter)} whose variable "
                                      "or bounds its body assigns")
        bounds = [self._expr(a) for a in node.iter.args[:2]]
        start, stop = ("0", bounds[0]) if len(bounds) == 1 else bounds
        head = f"{pad}for ({var} = {start}; {var} {'<' if step > 0 else '>'} {stop}; {var} += {step}) {{"
        return [head] + self._block(node.body, depth + 1) + [f"{pad}}}"]

    def _target(self, node) -> str:
        if isinstance(node, ast.Name):
            return node.id
        return self._expr(node)

    # -- expressions ---------------------------------------------------------------------------------------------
    def _wrap(self, node) -> str:
        text = self._expr(node)
        return text if isinstance(node, (ast.Name, ast.Constant, ast.Subscript, ast.Call)) else f"({text})"

    def _expr(self, node) -> str:
        if isinstance(node, ast.Constant):
            if isinstance(node.value, bool):
                return str(int(node.value))
            return repr(node.value)
        if isinstance(node, ast.Name):
            return node.id
        if isinstance(node, ast.Attribute) and self._size(node) is not None:
            return self._size(node)
        if isinstance(node, ast.Attribute):
            constants = {"np.inf": "INFINITY", "np.nan": "NAN"}
            name = ast.unparse(node)
            if name not in constants:
                raise NotImplementedError(f"name {name}")
            return constants[name]
        if isinstance(node, ast.Subscript):
            return self._subscript(node)
        if isinstance(node, ast.BinOp):
            function = _INTEGER_FUNCTIONS.get(type(node.op))
            if function is not None and self._type(node) == _INT:
                if not (isinstance(node.right, ast.Constant) and isinstance(node.right.value, int)
                        and node.right.value > 0):
                    raise NotImplementedError(f"{ast.unparse(node)} (by a positive literal only)")
                return f"{function}({self._expr(node.left)}, {self._expr(node.right)})"
            op = _OPERATORS.get(type(node.op))
            if op is None:
                raise NotImplementedError(f"operator {ast.unparse(node)}")
            return f"{self._wrap(node.left)} {op} {self._wrap(node.right)}"
        if isinstance(node, ast.UnaryOp):
            op = {ast.Not: "!", ast.USub: "-"}.get(type(node.op))
            if op is None:
                raise NotImplementedError(f"operator {ast.unparse(node)}")
            return f"{op}{self._wrap(node.operand)}"
        if isinstance(node, ast.BoolOp):
            if not all(self._truth(v) for v in node.values):
                raise NotImplementedError(f"{ast.unparse(node)} (and/or of values that are not truth values)")
            op = " && " if isinstance(node.op, ast.And) else " || "
            return "(" + op.join(self._wrap(v) for v in node.values) + ")"
        if isinstance(node, ast.Compare):
            parts, left = [], node.left
            for op, right in zip(node.ops, node.comparators):
                if type(op) not in _COMPARISONS:
                    raise NotImplementedError(f"comparison {ast.unparse(node)}")
                parts.append(f"{self._wrap(left)} {_COMPARISONS[type(op)]} {self._wrap(right)}")
                left = right
            return "(" + " && ".join(parts) + ")"
        if isinstance(node, ast.IfExp):
            return f"({self._expr(node.test)} ? {self._wrap(node.body)} : {self._wrap(node.orelse)})"
        if isinstance(node, ast.Call):
            return self._call(node)
        raise NotImplementedError(f"expression {ast.unparse(node)}")

    def _map_call(self, node) -> str:
        """``h(z, HP[row], HX)``: the output map (:func:`translate`'s ``output_map``) of one sample."""
        if len(node.args) != 3 or not isinstance(node.args[2], ast.Name) or self.map_source is None:
            raise NotImplementedError(f"call {ast.unparse(node)} (no output map given)")
        given = node.args[1]
        if isinstance(given, ast.Name) and given.id in self.rows:
            row, width = given.id, self.arrays.dims[self.rows[given.id]][1]
        else:
            row, width = _map_row(self, given)
        extra = node.args[2].id
        return f"h({self._expr(node.args[0])}, {row}, {width}, {extra}, {self.arrays.dims[extra][0]})"

    def _size(self, node) -> str | None:
        """``len(a)`` or ``a.size`` of a one-dimensional array, as its dimension; else None."""
        target = node.args[0] if _call_name(node) == "len" and len(node.args) == 1 else (
            node.value if isinstance(node, ast.Attribute) and node.attr == "size" else None)
        if isinstance(target, ast.Name) and len(self.arrays.dims.get(target.id, ())) == 1:
            return self.arrays.dims[target.id][0]
        return None

    def _subscript(self, node) -> str:
        if _is_shape(node):
            return f"{node.value.value.id}_{node.slice.value}"
        if not isinstance(node.value, ast.Name) or node.value.id not in self.arrays.dims:
            raise NotImplementedError(f"indexing {ast.unparse(node)}")
        indices = node.slice.elts if isinstance(node.slice, ast.Tuple) else [node.slice]
        for i in indices:      # Python counts a negative index from the end; C would read before the array
            if self._type(i) != _INT or isinstance(i, ast.UnaryOp) or (isinstance(i, ast.Constant) and i.value < 0):
                raise NotImplementedError(f"indexing {ast.unparse(node)} (indices are non-negative integers)")
        return self.arrays.index(node.value.id, [self._expr(i) for i in indices])

    def _call(self, node) -> str:
        name, args = _call_name(node), node.args
        if name == "len" and self._size(node) is not None:
            return self._size(node)
        if name == "h":
            return self._map_call(node)
        if name in _FLOAT_FUNCTIONS:
            if any(self._type(a) == _VECTOR for a in args):
                raise NotImplementedError(f"call {ast.unparse(node)} on vectors")
            return f"{_FLOAT_FUNCTIONS[name]}({', '.join(self._expr(a) for a in args)})"
        if name == "np.isfinite":
            return f"isfinite({self._expr(args[0])})"
        if name == "min":
            if len(args) != 2 or any(self._type(x) != _INT for x in args):
                raise NotImplementedError(f"call {ast.unparse(node)} (min of two integers only)")
            a, b = (self._wrap(x) for x in args)
            return f"({a} < {b} ? {a} : {b})"
        if name == "splat":
            return f"hc_splat({self._expr(args[0])})"
        if name == "load":
            return f"hc_load(&{args[0].id}[{self._expr(args[1])}])"
        if name == "lane":
            return f"{self._wrap(args[0])}[{args[1].value}]"
        if name == "rotate":
            return f"HC_ROTATE({self._expr(args[0])}, {args[1].value})"
        raise NotImplementedError(f"call {ast.unparse(node)}")


def _map_row(translator, node) -> tuple:
    """``(pointer, length)`` of the row ``A[i]`` of a two-dimensional array (an output map's parameters)."""
    if not (isinstance(node, ast.Subscript) and isinstance(node.value, ast.Name)
            and len(translator.arrays.dims.get(node.value.id, ())) == 2 and not isinstance(node.slice, ast.Tuple)):
        raise NotImplementedError(f"map parameters {ast.unparse(node)} (a row of a two-dimensional array)")
    name, index = node.value.id, node.slice
    if translator._type(index) != _INT or isinstance(index, ast.UnaryOp) or (
            isinstance(index, ast.Constant) and index.value < 0):
        raise NotImplementedError(f"map parameters {ast.unparse(node)} (a non-negative integer row)")
    width = translator.arrays.dims[name][1]
    return f"&{name}[({translator._expr(index)}) * {width}]", width


def _call_name(node) -> str | None:
    return ast.unparse(node.func) if isinstance(node, ast.Call) else None


def _is_shape(node) -> bool:
    """Whether ``node`` is ``A.shape[k]``."""
    return (isinstance(node, ast.Subscript) and isinstance(node.value, ast.Attribute) and node.value.attr == "shape"
            and isinstance(node.slice, ast.Constant))


def translate(source: str, output_map: str | None = None) -> CSource:
    """The C of the generated kernel ``source`` (Python source defining ``kernel``, its argument types in the
    decorator's ``kernel_signature("...")``); :data:`HEADER` comes before it in the file.

    ``output_map`` is the Python source of the formula ``formula(z, p, extra)``
    of the output map the kernel calls as ``h(z, HP[row], HX)``
    (:attr:`~hammerstein_ctrl.nonlinearities.Nonlinearity.formula`): it is
    translated too, into a function ``h`` of one sample.  A formula that reads
    ``extra`` (fixed data whose size the map relates to its parameters') is
    refused: the kernel's door could not check that relation.

    Raises
    ------
    NotImplementedError
        For Python the translator does not take.
    """
    tree = ast.parse(source)
    function = next(node for node in tree.body if isinstance(node, ast.FunctionDef) and node.name == "kernel")
    found = _SIGNATURE.search(source)
    if found is None:
        raise NotImplementedError("the kernel has no kernel_signature")
    translator = _Translator(function, found.group(1).split())
    map_text, map_params = ("", 0) if output_map is None else _map(output_map)
    translator.map_source = map_text or None
    text = translator.text()
    return CSource(HEADER + "\n" + map_text + "\n" + text, tuple(translator.names), tuple(translator.codes),
                   tuple(translator.messages), map_params)


def _map(source: str) -> tuple:
    """``(C, fewest parameters)`` of an output map's formula (the Python source of ``formula(z, p, extra)``)."""
    function = next((node for node in ast.parse(textwrap.dedent(source)).body if isinstance(node, ast.FunctionDef)),
                    None)
    if function is None or len(function.args.args) != 3:
        raise NotImplementedError("an output map is a function formula(z, p, extra)")
    translator = _Translator(function, ["f", "r1", "r1"])
    translator.returns = True
    z, p, extra = translator.names
    if any(isinstance(n, ast.Name) and n.id == extra for n in ast.walk(function)):
        raise NotImplementedError(f"an output map that reads {extra} (its size relates to the parameters')")
    if not isinstance(function.body[-1], ast.Return) or function.body[-1].value is None:
        raise NotImplementedError("an output map that does not end by returning its value")
    reads = [n.slice for n in ast.walk(function) if isinstance(n, ast.Subscript)
             and isinstance(n.value, ast.Name) and n.value.id == p]
    literal = [i.value for i in reads if isinstance(i, ast.Constant)]
    # a computed index (polynomial: p[len(p) - 1], p[i]) is bounded by len(p) and needs one parameter at least
    fewest = max(max(literal, default=-1) + 1, 1 if len(literal) < len(reads) else 0)
    return translator.map_text(), fewest
