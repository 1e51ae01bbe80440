"""The flattened graph that the validator, scheduler and runner share."""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from .block import Block
from .jsonable import to_jsonable as _plain
from .schema import Port


@dataclass(frozen=True)
class Origin:
    """Where something was written: a file and a line."""

    file: str
    line: int | None = None

    def __str__(self) -> str:
        return f"{self.file}:{self.line}" if self.line else self.file


@dataclass(frozen=True)
class Endpoint:
    """A port of a flat node: ``node`` is a dotted path, ``port`` a port name."""

    node: str
    port: str

    def __str__(self) -> str:
        return f"{self.node}.{self.port}"


@dataclass
class FlatNode:
    """One block instance after subgraphs are inlined."""

    path: str
    type_name: str
    cls: type[Block]
    params: dict[str, Any]
    param_sources: dict[str, str]
    origin: Origin
    period: int = 1
    offset: int = 0
    # Run only on ticks when, for every group, some endpoint fired (a
    # node's own trigger list is one any-of group; an enclosing subgraph's adds another).
    triggers: list[list[Endpoint]] = field(default_factory=list)
    inputs: dict[str, Port] = field(default_factory=dict)
    outputs: dict[str, Port] = field(default_factory=dict)
    implicit: bool = False  # inserted by the loader (edge delays)


@dataclass
class FlatEdge:
    """A link between two flat ports."""

    src: Endpoint
    dst: Endpoint
    origin: Origin


@dataclass
class FlatGraph:
    """A whole graph, subgraphs inlined, parameters resolved, ready to check."""

    name: str
    file: str
    dt: float
    steps: int | None
    nodes: dict[str, FlatNode]
    edges: list[FlatEdge]
    params: dict[str, Any]
    param_sources: dict[str, str]
    overrides: list[dict[str, Any]]
    doc: str = ""
    # The nesting of subgraph instances, for rendering: path -> (type, origin).
    groups: dict[str, tuple[str, Origin]] = field(default_factory=dict)
    # Parameters of subgraph instances, ``group.param`` -> (value, source).
    subgraph_params: dict[str, tuple[Any, str]] = field(default_factory=dict)
    # Exposed outputs of subgraph instances, ``group.port`` -> the inner port.
    exposed_outputs: dict[str, Endpoint] = field(default_factory=dict)
    # What a sweep summarises (blocks.core.scores.Score); only the top graph's count.
    scores: list[Any] = field(default_factory=list)

    def incoming(self) -> dict[Endpoint, FlatEdge]:
        return {e.dst: e for e in self.edges}

    def to_dict(self) -> dict[str, Any]:
        """The effective graph, as recorded in run.json."""
        return {
            "name": self.name,
            "file": self.file,
            "dt": self.dt,
            "steps": self.steps,
            "params": {k: {"value": _plain(v), "from": self.param_sources.get(k, "default")}
                       for k, v in self.params.items()},
            "overrides": self.overrides,
            "subgraphs": {
                group: {"type": kind, "origin": str(origin), "params": {
                    key.rsplit(".", 1)[1]: {"value": _plain(v), "from": src}
                    for key, (v, src) in self.subgraph_params.items()
                    if key.rsplit(".", 1)[0] == group}}
                for group, (kind, origin) in self.groups.items()
            },
            "nodes": [
                {
                    "id": n.path,
                    "type": n.type_name,
                    "period": n.period,
                    "offset": n.offset,
                    **({"triggers": [[str(t) for t in g] for g in n.triggers]} if n.triggers else {}),
                    "params": {k: {"value": _plain(v), "from": n.param_sources.get(k, "default")}
                               for k, v in n.params.items()},
                    "origin": str(n.origin),
                }
                for n in self.nodes.values()
            ],
            "edges": [{"from": str(e.src), "to": str(e.dst), "origin": str(e.origin)}
                      for e in self.edges],
            "scores": [s.as_dict() for s in self.scores],
        }
