"""Checks a flattened graph before anything runs, and computes its static schedule.

Checks: every input fed at most once, required inputs fed, schemas match
along every edge (with ``like`` inference for generic blocks), triggers are
events, and every cycle passes through a block without direct feedthrough.
"""
from __future__ import annotations

from dataclasses import dataclass

import networkx as nx

from .errors import GraphError
from .model import Endpoint, FlatEdge, FlatGraph, FlatNode
from .schema import Port, mismatch


@dataclass(frozen=True)
class Task:
    """One entry of the static schedule: call ``phase`` of ``node``.

    ``phase`` is ``step`` for ordinary blocks; blocks without direct
    feedthrough get an ``output`` task early and an ``update`` task late.
    """

    node: str
    phase: str


def check_graph(graph: FlatGraph) -> dict[Endpoint, Port]:
    """Validate ``graph``; return the resolved schema of every output port."""
    incoming = _check_inputs(graph)
    schemas = _resolve_schemas(graph, incoming)
    _check_edges(graph, schemas, incoming)
    _check_triggers(graph, schemas)
    schedule(graph)
    return schemas


def _check_inputs(graph: FlatGraph) -> dict[Endpoint, FlatEdge]:
    incoming: dict[Endpoint, FlatEdge] = {}
    for edge in graph.edges:
        if edge.dst in incoming:
            first = incoming[edge.dst]
            raise GraphError(
                f"input {edge.dst} is fed twice: by {first.src} ({first.origin}) and by {edge.src}",
                file=edge.origin.file, line=edge.origin.line, node=edge.dst.node,
                field=f"port '{edge.dst.port}'",
                hint="An input takes one edge; combine the sources with a block first.")
        incoming[edge.dst] = edge
    for node in graph.nodes.values():
        for name, port in node.inputs.items():
            if port.required and Endpoint(node.path, name) not in incoming:
                raise GraphError(
                    f"required input '{name}' ({port.describe()}) is not connected",
                    file=node.origin.file, line=node.origin.line, node=node.path,
                    field=f"port '{name}'",
                    hint=f"Add an edge 'SOURCE.port -> {node.path.split('.')[-1]}.{name}'.")
    return incoming


def _resolve_schemas(graph: FlatGraph, incoming: dict[Endpoint, FlatEdge]) -> dict[Endpoint, Port]:
    """Output schemas, with ``like`` ports copying their input's source (to a fixpoint)."""
    schemas: dict[Endpoint, Port] = {}
    for node in graph.nodes.values():
        for name, port in node.outputs.items():
            schemas[Endpoint(node.path, name)] = port.with_fields(like=None) if port.like else port
    for _ in range(len(graph.nodes) + 1):
        changed = False
        for node in graph.nodes.values():
            for name, port in node.outputs.items():
                if not port.like:
                    continue
                edge = incoming.get(Endpoint(node.path, port.like))
                if edge is None or edge.src not in schemas:
                    continue
                resolved = schemas[edge.src].with_fields(doc=port.doc, like=None)
                key = Endpoint(node.path, name)
                if schemas[key] != resolved:
                    schemas[key] = resolved
                    changed = True
        if not changed:
            break
    return schemas


def _check_edges(graph: FlatGraph, schemas: dict[Endpoint, Port],
                 incoming: dict[Endpoint, FlatEdge]) -> None:
    for edge in graph.edges:
        src = schemas[edge.src]
        dst_node = graph.nodes[edge.dst.node]
        dst = dst_node.inputs[edge.dst.port]
        why = mismatch(src, dst)
        if why is None and dst.like:
            other = incoming.get(Endpoint(edge.dst.node, dst.like))
            if other is not None:
                why = mismatch(src, schemas[other.src])
                if why:
                    why = f"it must match input '{dst.like}' (fed by {other.src}): {why}"
        if why:
            raise GraphError(
                f"edge {edge.src} -> {edge.dst} does not type-check: {edge.src} gives "
                f"{src.describe()} but {edge.dst} takes {dst.describe()} ({why})",
                file=edge.origin.file, line=edge.origin.line, node=edge.dst.node,
                field=f"port '{edge.dst.port}'",
                hint="Connect a port of the right type, or convert the value with a block "
                     "in between.")


def _check_triggers(graph: FlatGraph, schemas: dict[Endpoint, Port]) -> None:
    for node in graph.nodes.values():
        for group in node.triggers:
            for src in group:
                port = schemas[src]
                ok = port.kind in ("event", "any") or (port.kind == "scalar"
                                                      and port.dtype in ("bool", None))
                if not ok:
                    raise GraphError(
                        f"trigger {src} gives {port.describe()}, but a trigger must be an "
                        "event (a bool that is true on the ticks it fires)",
                        file=node.origin.file, line=node.origin.line, node=node.path,
                        field="trigger",
                        hint="Turn the value into an event first, e.g. with a 'threshold' block.")


def _vertices(node: FlatNode) -> tuple[str, str]:
    """(vertex that produces outputs, vertex that consumes inputs)."""
    if node.cls.direct_feedthrough:
        return node.path, node.path
    return node.path + "#output", node.path + "#update"


def dependency_graph(graph: FlatGraph) -> nx.DiGraph:
    """Vertices are schedule tasks; an arc means 'must run before'."""
    dag = nx.DiGraph()
    for node in graph.nodes.values():
        out_v, in_v = _vertices(node)
        dag.add_node(out_v)
        dag.add_node(in_v)
        if out_v != in_v:
            dag.add_edge(out_v, in_v)
    for edge in graph.edges:
        dag.add_edge(_vertices(graph.nodes[edge.src.node])[0],
                     _vertices(graph.nodes[edge.dst.node])[1], edge=edge)
    for node in graph.nodes.values():
        for group in node.triggers:
            for src in group:
                src_v = _vertices(graph.nodes[src.node])[0]
                for v in set(_vertices(node)):
                    dag.add_edge(src_v, v, trigger=src)
    return dag


def schedule(graph: FlatGraph) -> list[Task]:
    """The static run order: a topological sort, ties broken by file order."""
    dag = dependency_graph(graph)
    try:
        cycle = nx.find_cycle(dag)
    except nx.NetworkXNoCycle:
        cycle = None
    if cycle:
        names = [u.split("#")[0] for u, _ in cycle]
        first = graph.nodes[names[0]]
        arcs = [dag.edges[u, v] for u, v in cycle]
        where = [f"{a['edge'].src} -> {a['edge'].dst} ({a['edge'].origin})"
                 for a in arcs if "edge" in a]
        raise GraphError(
            "cycle without a delay: " + " -> ".join(names + [names[0]]),
            file=first.origin.file, line=first.origin.line, node=names[0],
            hint="Break it with a feedback edge: give one of its edges 'delay: 1' and "
                 "'initial: VALUE'" + (f", e.g. {where[-1]}" if where else "") + ".")
    order = {n: i for i, n in enumerate(graph.nodes)}

    def key(vertex: str) -> tuple[int, int]:
        name, _, phase = vertex.partition("#")
        return order[name], 1 if phase == "update" else 0

    tasks = []
    for vertex in nx.lexicographical_topological_sort(dag, key=key):
        name, _, phase = vertex.partition("#")
        tasks.append(Task(name, phase or "step"))
    return tasks
