"""Safe arithmetic for ``${...}`` references: numbers, parameter names, + - * / // % **,
comparisons, and/or/not, ``a if c else b``, and min, max, abs, round, int, float."""
from __future__ import annotations

import ast
import math
import operator
from typing import Any, Callable, Mapping

_BINARY: dict[type, Callable[[Any, Any], Any]] = {
    ast.Add: operator.add, ast.Sub: operator.sub, ast.Mult: operator.mul,
    ast.Div: operator.truediv, ast.FloorDiv: operator.floordiv, ast.Mod: operator.mod,
    ast.Pow: operator.pow,
}
_UNARY: dict[type, Callable[[Any], Any]] = {ast.USub: operator.neg, ast.UAdd: operator.pos,
                                            ast.Not: operator.not_}
_COMPARE: dict[type, Callable[[Any, Any], Any]] = {
    ast.Eq: operator.eq, ast.NotEq: operator.ne, ast.Lt: operator.lt, ast.LtE: operator.le,
    ast.Gt: operator.gt, ast.GtE: operator.ge,
}
FUNCTIONS: dict[str, Callable[..., Any]] = {
    "min": min, "max": max, "abs": abs, "round": round, "int": int, "float": float,
}
CONSTANTS = {"pi": math.pi}


class ExprError(ValueError):
    """The expression uses something outside the safe subset, or names an unknown value."""


MAX_LENGTH = 400
MAX_INT_BITS = 1024  # results stay printable and cheap
MAX_TEXT = 10_000


def _check_cost(op: ast.operator, left: Any, right: Any) -> None:
    """Refuse operations whose result would be huge, before computing them."""
    if isinstance(op, ast.Pow) and isinstance(left, int) and isinstance(right, int):
        if right > 0 and abs(left) > 1 and left.bit_length() * right > MAX_INT_BITS:
            raise ExprError("result too large")
    if isinstance(op, ast.Pow) and isinstance(right, (int, float)) and abs(right) > 1024:
        raise ExprError("exponent too large")
    if isinstance(op, ast.Mult):
        for text, count in ((left, right), (right, left)):
            if isinstance(text, str) and isinstance(count, int) and len(text) * count > MAX_TEXT:
                raise ExprError("text too long")


def _bounded(value: Any) -> Any:
    if isinstance(value, int) and not isinstance(value, bool) and \
            value.bit_length() > MAX_INT_BITS:
        raise ExprError("result too large")
    if isinstance(value, str) and len(value) > MAX_TEXT:
        raise ExprError("text too long")
    return value


def evaluate(text: str, names: Mapping[str, Any]) -> Any:
    """Evaluate ``text`` with ``names`` as variables; raise ExprError if it is not allowed."""
    if len(text) > MAX_LENGTH:
        raise ExprError(f"expression longer than {MAX_LENGTH} characters; use a parameter")
    try:
        tree = ast.parse(text, mode="eval")
    except SyntaxError as exc:
        raise ExprError(f"cannot parse {text!r}: {exc.msg}") from None
    except (RecursionError, MemoryError, ValueError):
        raise ExprError("expression too deeply nested") from None
    try:
        return _eval(tree.body, names)
    except ExprError:
        raise
    except RecursionError:
        raise ExprError("expression too deeply nested") from None
    except (ArithmeticError, TypeError, ValueError, OverflowError) as exc:
        raise ExprError(f"{text!r} fails: {exc}") from None


def _eval(node: ast.AST, names: Mapping[str, Any]) -> Any:
    if isinstance(node, ast.Constant) and isinstance(node.value, (int, float, bool, str)):
        return node.value
    if isinstance(node, ast.Name):
        if node.id in names:
            return names[node.id]
        if node.id in CONSTANTS:
            return CONSTANTS[node.id]
        raise ExprError(f"unknown name '{node.id}'")
    if isinstance(node, ast.BinOp) and type(node.op) in _BINARY:
        left, right = _eval(node.left, names), _eval(node.right, names)
        _check_cost(node.op, left, right)
        return _bounded(_BINARY[type(node.op)](left, right))
    if isinstance(node, ast.UnaryOp) and type(node.op) in _UNARY:
        return _UNARY[type(node.op)](_eval(node.operand, names))
    if isinstance(node, ast.BoolOp):
        values = [_eval(v, names) for v in node.values]
        return all(values) if isinstance(node.op, ast.And) else any(values)
    if isinstance(node, ast.Compare) and all(type(op) in _COMPARE for op in node.ops):
        left = _eval(node.left, names)
        for op, comp in zip(node.ops, node.comparators):
            right = _eval(comp, names)
            if not _COMPARE[type(op)](left, right):
                return False
            left = right
        return True
    if isinstance(node, ast.IfExp):
        return _eval(node.body if _eval(node.test, names) else node.orelse, names)
    if (isinstance(node, ast.Call) and isinstance(node.func, ast.Name)
            and node.func.id in FUNCTIONS and not node.keywords):
        return FUNCTIONS[node.func.id](*[_eval(a, names) for a in node.args])
    raise ExprError(f"'{ast.unparse(node)}' is not allowed in a ${{...}} expression")
