"""semmap blocks: the dataflow core (``blocks.core``) and the block library.

Write a block::

    from blocks import Block, Port, Param, block

    @block("scale", category="math")
    class Scale(Block):
        \"\"\"Multiplies its input by a gain.\"\"\"
        inputs = {"x": Port.scalar()}
        outputs = {"y": Port.scalar()}
        params = {"gain": Param(float, 1.0, "multiplier")}

        def step(self, x):
            return {"y": self.p.gain * x}
"""
from .core import (
    Block, BlockError, GraphError, Param, Port, Runner, SemmapError, block, check_graph,
    load_graph, load_probes,
)

__all__ = ["Block", "BlockError", "GraphError", "Param", "Port", "Runner", "SemmapError",
           "block", "check_graph", "load_graph", "load_probes"]
