"""Compile a static schedule into one straight-line Python function.

Interpreting a schedule costs a loop, a few look-ups and a branch per block
call; generating the tick function once removes all of that, which is how the
engine stays near the cost of calling the blocks by hand. The source is kept
(``Runner.tick_source``) so it can be read when debugging.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

FILENAME = "<semmap schedule>"


@dataclass
class SlotPlan:
    """Where each value lives: a flat list indexed by slot."""

    output_slot: dict[tuple[str, str], int] = field(default_factory=dict)
    stamped: set[int] = field(default_factory=set)  # slots whose freshness matters
    probes: dict[int, str] = field(default_factory=dict)  # slot -> probe variable


@dataclass
class NodeCall:
    """Everything codegen needs to emit one task."""

    index: int  # node index, for timing arrays
    path: str
    type_name: str
    phase: str  # step | output | update
    func: str  # variable name of the bound method
    args: list[int]  # input slots, in call order
    outputs: list[tuple[str, int]]  # (port, slot)
    gate: str  # python condition, '' when it runs every tick
    origin: str
    strict: bool = False


def gate_expr(period: int, offset: int, triggers: list[list[int]]) -> str:
    """Condition under which a node runs at tick ``t``."""
    parts = []
    if period > 1:
        parts.append(f"t % {period} == {offset}")
    for group in triggers:
        fired = " or ".join(f"(st[{s}] == t and v[{s}])" for s in group)
        parts.append(f"({fired})" if len(group) > 1 else fired)
    return " and ".join(parts)


def _emit_outputs(call: NodeCall, plan: SlotPlan, pad: str) -> list[str]:
    lines = []
    if not call.outputs:
        return lines
    lines.append(f"{pad}if _o is not None:")
    if call.strict:
        lines.append(f"{pad}    chk_keys({call.index}, _o)")
    for port, slot in call.outputs:
        if slot in plan.stamped:
            lines.append(f"{pad}    if {port!r} in _o:")
            lines.append(f"{pad}        v[{slot}] = _o[{port!r}]; st[{slot}] = t")
            if call.strict:
                lines.append(f"{pad}        chk({call.index}, {port!r}, v[{slot}])")
            if slot in plan.probes:
                lines.append(f"{pad}        {plan.probes[slot]}(t, v[{slot}])")
        else:
            lines.append(f"{pad}    v[{slot}] = _o.get({port!r}, v[{slot}])")
            if call.strict:
                lines.append(f"{pad}    chk({call.index}, {port!r}, v[{slot}])")
    return lines


def generate(calls: list[NodeCall], plan: SlotPlan, profile: bool) -> tuple[str, dict[int, str]]:
    """Source of ``_tick(t)`` and a map from source line to node path."""
    lines = ["def _tick(t):"]
    line_node: dict[int, str] = {}
    if profile:
        lines.append("    _t0 = pc()")
    if not calls:
        lines.append("    pass")
    for call in calls:
        lines.append(f"    # {call.path} ({call.type_name}, {call.phase}) from {call.origin}")
        pad = "    "
        if call.gate:
            lines.append(f"    if {call.gate}:")
            pad = "        "
        args = ", ".join(f"v[{s}]" for s in call.args)
        lines.append(f"{pad}_o = {call.func}({args})")
        line_node[len(lines)] = call.path
        lines.extend(_emit_outputs(call, plan, pad))
        if profile:
            count = f"; nc[{call.index}] += 1" if call.gate and call.phase != "update" else ""
            lines.append(f"{pad}_t1 = pc(); tm[{call.index}] += _t1 - _t0; _t0 = _t1{count}")
    return "\n".join(lines) + "\n", line_node


def compile_tick(source: str, namespace: dict[str, Any]):
    """Compile the generated source; return the ``_tick`` function."""
    code = compile(source, FILENAME, "exec")
    exec(code, namespace)  # noqa: S102 - the source is generated here, never user text
    return namespace["_tick"]
