"""Arithmetic on scalars and arrays (numpy broadcasting rules)."""
from __future__ import annotations

import operator
from typing import Any, Callable

import numpy as np

from ..core import Block, Param, Port, block

# operator.* handles Python numbers and numpy arrays alike, and is ~5x faster
# than the numpy ufuncs on plain floats; min/max need numpy for elementwise arrays.
OPERATIONS: dict[str, Callable[[Any, Any], Any]] = {
    "add": operator.add, "sub": operator.sub, "mul": operator.mul, "div": operator.truediv,
    "min": np.minimum, "max": np.maximum,
}


def _plain(value: Any) -> Any:
    """numpy scalars back to Python numbers, so scalar ports stay scalars."""
    return value.item() if isinstance(value, np.generic) else value


@block("arith", category="math")
class Arith(Block):
    """Combines two values with +, -, *, /, min or max."""

    inputs = {"a": Port(doc="left operand"),
              "b": Port(like="a", doc="right operand, same type as a")}
    outputs = {"y": Port(like="a", doc="a OP b")}
    params = {"op": Param(str, "add", "the operation", choices=tuple(OPERATIONS))}

    def setup(self) -> None:
        self._op = OPERATIONS[self.p.op]

    def step(self, a: Any, b: Any) -> dict[str, Any]:
        try:
            return {"y": _plain(self._op(a, b))}
        except ZeroDivisionError:  # follow numpy: x / 0 is +-inf or nan, not a crash
            with np.errstate(divide="ignore", invalid="ignore"):
                return {"y": _plain(np.divide(np.float64(a), b))}


@block("scale", category="math")
class Scale(Block):
    """Affine map y = gain * x + offset."""

    inputs = {"x": Port(doc="input value")}
    outputs = {"y": Port(like="x", doc="gain * x + offset")}
    params = {"gain": Param(float, 1.0, "multiplier"),
              "offset": Param(float, 0.0, "added after the gain")}

    def step(self, x: Any) -> dict[str, Any]:
        return {"y": self.p.gain * x + self.p.offset}


@block("pack", category="math")
class Pack(Block):
    """Packs two to four scalars into one float array (unconnected optional inputs are left out)."""

    inputs = {"a": Port.scalar(None, doc="first element"),
              "b": Port.scalar(None, doc="second element"),
              "c": Port.scalar(None, required=False, doc="optional third element"),
              "d": Port.scalar(None, required=False, doc="optional fourth element")}
    outputs = {"y": Port.array("float64", ("N",), doc="[a, b, (c), (d)]")}

    def step(self, a: Any, b: Any, c: Any = None, d: Any = None) -> dict[str, Any]:
        values = [a, b] + [v for v in (c, d) if v is not None]
        return {"y": np.array([np.nan if v is None else v for v in values], dtype=np.float64)}
