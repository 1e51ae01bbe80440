"""Source blocks: values that come from parameters, the clock or an RNG."""
from __future__ import annotations

from typing import Any

import numpy as np

from ..core import Block, Param, Port, block
from ..core.schema import schema_of_value


def as_value(value: Any) -> Any:
    """Lists become numpy arrays so that they flow as typed arrays."""
    return np.asarray(value) if isinstance(value, (list, tuple)) else value


@block("constant", category="sources")
class Constant(Block):
    """Outputs the same value every tick; its type follows the value."""

    outputs = {"value": Port(doc="the constant")}
    params = {
        "value": Param(object, doc="the value: a number, bool, list (becomes an array) or mapping"),
        "unit": Param(str, "", "SI unit of the value, for type checking"),
        "frame": Param(str, "", "coordinate frame of the value, for type checking"),
    }

    @classmethod
    def resolve_ports(cls, params):
        port = schema_of_value(params["value"]).with_fields(
            unit=params.get("unit") or None, frame=params.get("frame") or None,
            doc="the constant")
        return {}, {"value": port}

    def setup(self) -> None:
        self._value = as_value(self.p.value)

    def step(self) -> dict[str, Any]:
        return {"value": self._value}


@block("counter", category="sources")
class Counter(Block):
    """Counts its own runs: start, start + increment, ..."""

    outputs = {"count": Port.scalar("int64", doc="the count")}
    params = {"start": Param(int, 0, "first value"),
              "increment": Param(int, 1, "added on every run")}

    def reset(self) -> None:
        self._next = self.p.start

    def step(self) -> dict[str, Any]:
        value = self._next
        self._next += self.p.increment
        return {"count": value}


@block("clock", category="sources")
class Clock(Block):
    """Simulated time in seconds at this tick."""

    outputs = {"time": Port.scalar("float64", unit="s", doc="tick * dt")}

    def step(self) -> dict[str, Any]:
        return {"time": self.ctx.tick * self.ctx.dt}


@block("noise", category="sources")
class Noise(Block):
    """Seeded random values: normal or uniform, scalar or array."""

    outputs = {"value": Port(doc="a fresh sample every run")}
    params = {
        "distribution": Param(str, "normal", "sampling law", choices=("normal", "uniform")),
        "mean": Param(float, 0.0, "normal: mean"),
        "std": Param(float, 1.0, "normal: standard deviation", min=0.0),
        "low": Param(float, 0.0, "uniform: lower bound"),
        "high": Param(float, 1.0, "uniform: upper bound"),
        "shape": Param(list, [], "array shape; [] gives a scalar"),
        "unit": Param(str, "", "SI unit of the value"),
    }

    @classmethod
    def resolve_ports(cls, params):
        shape = params["shape"]
        if not all(isinstance(d, int) and not isinstance(d, bool) and d > 0 for d in shape):
            raise ValueError(f"shape must list positive whole numbers, got {shape!r}")
        unit = params.get("unit") or None
        port = (Port.array("float64", tuple(shape), unit) if shape
                else Port.scalar("float64", unit))
        return {}, {"value": port.with_fields(doc="a fresh sample every run")}

    def step(self) -> dict[str, Any]:
        size = tuple(self.p.shape) or None
        if self.p.distribution == "normal":
            sample = self.rng.normal(self.p.mean, self.p.std, size)
        else:
            sample = self.rng.uniform(self.p.low, self.p.high, size)
        return {"value": sample if size else float(sample)}
