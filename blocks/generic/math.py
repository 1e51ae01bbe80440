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


REDUCERS: dict[str, Callable[[np.ndarray], Any]] = {
    "min": np.min, "max": np.max, "mean": np.mean, "sum": np.sum,
}


@block("select", category="math")
class Select(Block):
    """Picks elements of a 1-D array by index, optionally reduced to one number (min, max, ...)."""

    inputs = {"x": Port.array(None, doc="the array")}
    outputs = {"y": Port(doc="the selected elements, or their reduction")}
    params = {"indices": Param(list, doc="indices to pick, e.g. [0, 1]"),
              "reduce": Param(str, "none", "combine the picked elements",
                              choices=("none", *REDUCERS))}

    @classmethod
    def resolve_ports(cls, params):
        indices = params["indices"]
        if not indices or not all(isinstance(i, int) and not isinstance(i, bool)
                                  for i in indices):
            raise ValueError(f"indices must be a non-empty list of whole numbers, got {indices!r}")
        if params["reduce"] == "none":
            out = Port.array(None, (len(indices),), doc="the selected elements")
        else:
            out = Port.scalar(None, doc=f"{params['reduce']} of the selected elements")
        return cls.inputs, {"y": out}

    def setup(self) -> None:
        self._index = np.asarray(self.p.indices)
        self._reduce = REDUCERS.get(self.p.reduce)

    def step(self, x: Any) -> dict[str, Any]:
        try:
            picked = np.asarray(x)[self._index]
        except IndexError:
            from ..core import BlockError
            raise BlockError(f"index out of range for an input of shape {np.shape(x)}",
                             node=self.name, field="param 'indices'") from None
        return {"y": picked if self._reduce is None else _plain(self._reduce(picked))}


@block("switch", category="math")
class Switch(Block):
    """Outputs ``a`` when the condition is true, else ``b``."""

    inputs = {"when": Port.scalar("bool", doc="the condition"),
              "a": Port(doc="value when true"),
              "b": Port(like="a", doc="value when false")}
    outputs = {"y": Port(like="a", doc="a or b")}

    def step(self, when: Any, a: Any, b: Any) -> dict[str, Any]:
        return {"y": a if when else b}
