"""Arithmetic expressions for numbers in run files and stop conditions (``"9*pi^2/4"``)."""

from __future__ import annotations

import ast
import math
import operator

_FUNCS = {"sqrt": math.sqrt, "sin": math.sin, "cos": math.cos, "tan": math.tan,
          "exp": math.exp, "log": math.log, "abs": abs}
_CONSTS = {"pi": math.pi, "e": math.e}
_BINOPS = {ast.Add: operator.add, ast.Sub: operator.sub, ast.Mult: operator.mul,
           ast.Div: operator.truediv, ast.Pow: operator.pow}
_UNOPS = {ast.USub: operator.neg, ast.UAdd: operator.pos}


def evaluate(text: str) -> float:
    """Evaluate an arithmetic expression such as ``"9*pi^2/4"`` (``^`` means power).

    Only numbers, the constants pi, e, the functions sqrt, sin, cos, tan, exp, log, abs and
    + - * / ** are allowed, and the value must be a finite real number; anything else raises
    ValueError.
    """
    def ev(node):
        if isinstance(node, ast.Expression):
            return ev(node.body)
        if isinstance(node, ast.Constant) and isinstance(node.value, (int, float)) \
                and not isinstance(node.value, bool):
            return float(node.value)
        if isinstance(node, ast.Name) and node.id in _CONSTS:
            return _CONSTS[node.id]
        if isinstance(node, ast.BinOp) and type(node.op) in _BINOPS:
            return _BINOPS[type(node.op)](ev(node.left), ev(node.right))
        if isinstance(node, ast.UnaryOp) and type(node.op) in _UNOPS:
            return _UNOPS[type(node.op)](ev(node.operand))
        if (isinstance(node, ast.Call) and isinstance(node.func, ast.Name)
                and node.func.id in _FUNCS and len(node.args) == 1 and not node.keywords):
            return float(_FUNCS[node.func.id](ev(node.args[0])))
        raise ValueError(_not_allowed(node))

    try:
        value = ev(ast.parse(str(text).replace("^", "**"), mode="eval"))
    except SyntaxError as exc:  # its own text names the parser's "<unknown>" file and line
        raise ValueError(f"cannot evaluate {text!r}: {exc.msg}") from exc
    except (ValueError, ZeroDivisionError, OverflowError, TypeError) as exc:
        raise ValueError(f"cannot evaluate {text!r}: {exc}") from exc
    except (RecursionError, MemoryError) as exc:  # the parser's or ev's stack, nested too deep
        raise ValueError(f"cannot evaluate {str(text)[:20]!r}...: nested too deeply") from exc
    if isinstance(value, complex) or not math.isfinite(value):
        raise ValueError(f"{text!r} is not a finite real number")
    return float(value)


def _not_allowed(node: ast.AST) -> str:
    """What is wrong with a node `evaluate` does not take, in the terms of its docstring."""
    if isinstance(node, ast.Name):
        return f"unknown name {node.id!r} (the constants are {', '.join(_CONSTS)})"
    if isinstance(node, ast.Call):
        return f"not one of the functions {', '.join(_FUNCS)} of one argument"
    if isinstance(node, ast.Constant):
        return f"{node.value!r} is not a real number"
    return f"{type(node).__name__.lower()} not allowed (numbers, pi, e, + - * / ^ and " \
           "functions only)"
