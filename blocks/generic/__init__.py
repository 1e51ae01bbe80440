"""Generic blocks that exercise the core without domain code.

Sources (constant, counter, clock, noise), arithmetic (arith, scale),
events (threshold, stop_when) and sinks (recorder, logger). The delay block
lives in the core because feedback edges need it.
"""
from . import events, math, sinks, sources  # noqa: F401  (importing registers the blocks)
