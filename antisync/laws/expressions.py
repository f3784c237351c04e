"""The math language of a user's law: an expression read into sympy without ``eval``.

A law's expressions (``w * sin(theta_j - theta_i)``) are parsed by Python's :mod:`ast` and
walked node by node: numbers, the names the law declares, ``+ - * / **``, unary minus and the
functions of :data:`FUNCTIONS`. Anything else (an attribute, a subscript, a comparison, a
string, a keyword argument, ``^``, a name the law does not declare, a function not in the list)
is refused by name with a :class:`~antisync.errors.ConfigError` naming the key and the
expression. Nothing the user writes is ever executed: the walk builds sympy objects itself.
"""

from __future__ import annotations

import ast
import math

from antisync.errors import ConfigError

__all__ = ["CONSTANTS", "FUNCTIONS", "parse_expression"]

#: the functions of the language and how many arguments each takes
FUNCTIONS: dict[str, int] = {
    "sin": 1,
    "cos": 1,
    "tan": 1,
    "exp": 1,
    "log": 1,
    "sqrt": 1,
    "tanh": 1,
    "abs": 1,
    "atan2": 2,
}
#: the named constants every expression may use
CONSTANTS: dict[str, float] = {"pi": math.pi}

_OPERATORS = {ast.Add: "+", ast.Sub: "-", ast.Mult: "*", ast.Div: "/", ast.Pow: "**"}


def _sympy_function(name: str):
    import sympy

    return {
        "sin": sympy.sin,
        "cos": sympy.cos,
        "tan": sympy.tan,
        "exp": sympy.exp,
        "log": sympy.log,
        "sqrt": sympy.sqrt,
        "tanh": sympy.tanh,
        "abs": sympy.Abs,
        "atan2": sympy.atan2,
    }[name]


def parse_expression(key: str, text, names: dict):
    """``text`` as a sympy expression over ``names`` (``{name: sympy object}``: the symbols and
    numbers the context allows), or a one-line :class:`ConfigError` naming ``key``, the
    expression and what is wrong."""
    import sympy

    if isinstance(text, bool) or not isinstance(text, str | int | float):
        raise ConfigError(
            f"{key} must be an expression (a string such as 'w * sin(theta_j - theta_i)'), got {text!r}"
        )
    source = str(text).strip()
    if not source:
        raise ConfigError(f"{key} is empty; write an expression")

    def fail(why: str):
        raise ConfigError(f"{key}: {why} in {source!r}")

    try:
        tree = ast.parse(source, mode="eval")
    except SyntaxError as exc:
        fail(f"not an expression ({exc.msg})")

    def walk(node):
        if isinstance(node, ast.Constant):
            value = node.value
            if isinstance(value, bool) or not isinstance(value, int | float):
                fail(f"{value!r} is not a number")
            return sympy.Integer(value) if isinstance(value, int) else sympy.Float(value)
        if isinstance(node, ast.Name):
            if node.id in names:
                return names[node.id]
            if node.id in CONSTANTS:
                return sympy.Float(CONSTANTS[node.id]) if node.id != "pi" else sympy.pi
            if node.id in FUNCTIONS:
                fail(f"the function {node.id} needs its arguments: {node.id}(...)")
            fail(f"unknown name {node.id!r} (known here: {', '.join(sorted(names)) or 'none'}, and pi)")
        if isinstance(node, ast.BinOp):
            if isinstance(node.op, ast.BitXor):
                fail("'^' is not a power; write ** (x**2)")
            op = _OPERATORS.get(type(node.op))
            if op is None:
                fail(f"the operator {type(node.op).__name__} is not in the language (+ - * / **)")
            a, b = walk(node.left), walk(node.right)
            if op == "+":
                return a + b
            if op == "-":
                return a - b
            if op == "*":
                return a * b
            if op == "/":
                return a / b
            return a**b
        if isinstance(node, ast.UnaryOp):
            if isinstance(node.op, ast.USub):
                return -walk(node.operand)
            if isinstance(node.op, ast.UAdd):
                return walk(node.operand)
            fail(f"the operator {type(node.op).__name__} is not in the language")
        if isinstance(node, ast.Call):
            if not isinstance(node.func, ast.Name):
                fail("only the functions " + ", ".join(FUNCTIONS) + " may be called")
            name = node.func.id
            if name not in FUNCTIONS:
                fail(f"unknown function {name!r} (the language has {', '.join(FUNCTIONS)})")
            if node.keywords:
                fail(f"{name} takes no keyword arguments")
            if len(node.args) != FUNCTIONS[name]:
                fail(
                    f"{name} takes {FUNCTIONS[name]} argument{'s' if FUNCTIONS[name] > 1 else ''}, "
                    f"got {len(node.args)}"
                )
            return _sympy_function(name)(*(walk(a) for a in node.args))
        fail(f"{type(node).__name__.lower()} is not in the language (numbers, names, + - * / **, functions)")

    return walk(tree.body)
