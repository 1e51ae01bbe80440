"""Blocks the framework itself needs: the delay that breaks feedback cycles."""
from __future__ import annotations

import copy
from collections import deque
from typing import Any

from .block import Block
from .params import Param
from .registry import REGISTRY, block
from .schema import Port


@block("delay", category="flow")
class Delay(Block):
    """The input from ``n`` ticks earlier; breaks feedback cycles.

    It has no direct feedthrough: this tick's output depends only on past
    inputs, so a cycle through a delay can be scheduled. A feedback edge with
    ``delay: N`` in a graph inserts one of these.
    """

    direct_feedthrough = False
    inputs = {"x": Port(doc="value to delay")}
    outputs = {"y": Port(like="x", doc="the value of x from n ticks earlier")}
    params = {
        "n": Param(int, 1, "delay length in ticks (of this node's own runs)", min=1),
        "initial": Param(object, doc="value output during the first n ticks"),
    }

    def reset(self) -> None:
        self._buffer: deque[Any] = deque(copy.deepcopy(self.p.initial) for _ in range(self.p.n))

    def output(self) -> dict[str, Any]:
        return {"y": self._buffer[0]}

    def update(self, x: Any) -> None:
        self._buffer.append(x)
        self._buffer.popleft()


REGISTRY.toolbox_of["delay"] = "core"
