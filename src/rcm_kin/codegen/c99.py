"""A CasADi SX function written out as one plain C99 function: no CasADi runtime, only ``<math.h>``.

The function's instruction list (what CasADi's own virtual machine runs) is emitted statement
by statement into a local work array, in the same order and with the same operations, so the
C code rounds like the interpreted function. Inputs must be dense vectors; each output is
written in full, row-major (``out[r * cols + c]``), its structural zeros as ``0.0``. The code
compiles with ``-std=c99 -Wall -Wextra -pedantic -Werror`` and allocates nothing.
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass

import casadi as ca
import numpy as np

from rcm_kin.errors import RcmKinError

_UNARY = {"OP_ASSIGN": "{0}", "OP_NEG": "-{0}", "OP_SQ": "{0} * {0}", "OP_TWICE": "2.0 * {0}",
          "OP_INV": "1.0 / {0}", "OP_SQRT": "sqrt({0})", "OP_SIN": "sin({0})", "OP_COS": "cos({0})",
          "OP_TAN": "tan({0})", "OP_ASIN": "asin({0})", "OP_ACOS": "acos({0})", "OP_ATAN": "atan({0})",
          "OP_EXP": "exp({0})", "OP_LOG": "log({0})", "OP_FABS": "fabs({0})", "OP_TANH": "tanh({0})",
          "OP_SINH": "sinh({0})", "OP_COSH": "cosh({0})"}
_BINARY = {"OP_ADD": "{0} + {1}", "OP_SUB": "{0} - {1}", "OP_MUL": "{0} * {1}", "OP_DIV": "{0} / {1}",
           "OP_POW": "pow({0}, {1})", "OP_CONSTPOW": "pow({0}, {1})", "OP_ATAN2": "atan2({0}, {1})",
           "OP_FMIN": "fmin({0}, {1})", "OP_FMAX": "fmax({0}, {1})", "OP_HYPOT": "hypot({0}, {1})"}
_CODE = {getattr(ca, name): name for name in (*_UNARY, *_BINARY, "OP_INPUT", "OP_OUTPUT", "OP_CONST")}


@dataclass(frozen=True)
class CFunction:
    """One generated C function."""

    name: str
    prototype: str                 # the declaration, without the trailing semicolon
    body: str                      # the definition (prototype and braces included)
    operations: int                # arithmetic and math-library operations per call
    operation_counts: dict         # {"mul": 469, "sin": 3, ...}


def _literal(value: float) -> str:
    if not np.isfinite(value):
        raise RcmKinError(f"cannot write the constant {value} as C99")
    text = repr(float(value))
    return text if any(ch in text for ch in ".e") else text + ".0"


def c_function(fn: ca.Function, name: str, inputs: list[str], outputs: list[str]) -> CFunction:
    """The SX function ``fn`` as C99 ``void name(const double in[n], ..., double out[m], ...)``.

    ``inputs``/``outputs``: the C parameter names, one per input/output of ``fn``."""
    if not fn.is_a("SXFunction"):
        raise RcmKinError(f"{fn.name()}: only SX functions can be written as plain C")
    if len(inputs) != fn.n_in() or len(outputs) != fn.n_out():
        raise RcmKinError(f"{fn.name()}: {fn.n_in()} input and {fn.n_out()} output names needed")
    for i in range(fn.n_in()):
        if not fn.sparsity_in(i).is_dense() or fn.size2_in(i) != 1:
            raise RcmKinError(f"{fn.name()}: input {i} must be a dense column vector")
    params = [f"const double {n}[{fn.nnz_in(i)}]" for i, n in enumerate(inputs)]
    params += [f"double {n}[{fn.numel_out(i)}]" for i, n in enumerate(outputs)]
    prototype = f"void {name}({', '.join(params)})"

    # row-major position of every output nonzero, and the structural zeros to clear
    position, zeros = [], []
    for i, n in enumerate(outputs):
        sp = fn.sparsity_out(i)
        r, c = (np.array(x, dtype=int) for x in sp.get_triplet())
        flat = r * sp.size2() + c
        position.append(flat)
        zeros += [f"    {n}[{k}] = 0.0;" for k in sorted(set(range(sp.numel())) - set(flat.tolist()))]

    lines, counts, used = [], Counter(), [0]
    for k in range(fn.n_instructions()):
        op = _CODE.get(fn.instruction_id(k))
        if op is None:
            raise RcmKinError(f"{fn.name()}: CasADi operation {fn.instruction_id(k)} has no C99 translation here")
        arg, res = fn.instruction_input(k), fn.instruction_output(k)
        used += res if op != "OP_OUTPUT" else arg
        if op == "OP_INPUT":
            lines.append(f"    w[{res[0]}] = {inputs[arg[0]]}[{arg[1]}];")
        elif op == "OP_OUTPUT":
            lines.append(f"    {outputs[res[0]]}[{position[res[0]][res[1]]}] = w[{arg[0]}];")
        elif op == "OP_CONST":
            lines.append(f"    w[{res[0]}] = {_literal(fn.instruction_constant(k))};")
        else:
            table = _UNARY if op in _UNARY else _BINARY
            operands = [f"w[{a}]" for a in arg[:2 if op in _BINARY else 1]]
            lines.append(f"    w[{res[0]}] = {table[op].format(*operands)};")
            if op != "OP_ASSIGN":
                counts[op[3:].lower()] += 1
    body = "\n".join([f"{prototype}", "{", f"    double w[{max(used) + 1}];", *zeros, *lines, "}"])
    return CFunction(name, prototype, body, sum(counts.values()), dict(sorted(counts.items())))
