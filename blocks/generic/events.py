"""Events: booleans that fire triggers, and a block that ends the run."""
from __future__ import annotations

from typing import Any

from ..core import Block, Param, Port, block


def crossed(value: float, level: float, hysteresis: float, above: bool, was_on: bool) -> bool:
    """Schmitt-trigger state: on past ``level``, off only once back past the hysteresis band."""
    if above:
        return value > level or (was_on and value > level - hysteresis)
    return value < level or (was_on and value < level + hysteresis)


@block("threshold", category="events")
class Threshold(Block):
    """Fires while (or when) a scalar crosses a level, with hysteresis."""

    inputs = {"x": Port.scalar(None, doc="the watched value")}
    outputs = {"fired": Port.event(doc="true on the ticks the condition holds (or starts)"),
               "on": Port.scalar("bool", doc="the condition's current state")}
    params = {
        "level": Param(float, 0.0, "the threshold"),
        "direction": Param(str, "above", "fire above or below the level",
                           choices=("above", "below")),
        "hysteresis": Param(float, 0.0, "band the value must leave to turn off", min=0.0),
        "edge": Param(bool, False, "fire only on the tick the condition starts"),
    }

    def reset(self) -> None:
        self._on = False

    def step(self, x: Any) -> dict[str, Any]:
        was_on = self._on
        self._on = crossed(float(x), self.p.level, self.p.hysteresis,
                           self.p.direction == "above", was_on)
        fired = self._on and not was_on if self.p.edge else self._on
        return {"fired": fired, "on": self._on}


@block("stop_when", category="events")
class StopWhen(Block):
    """Ends the run after the tick on which its input is true."""

    inputs = {"x": Port.event(doc="stop when true")}
    params = {"reason": Param(str, "condition met", "recorded in run.json")}

    def step(self, x: Any) -> None:
        if x:
            self.request_stop(self.p.reason)
