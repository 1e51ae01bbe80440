"""Load a YAML graph: parse it, resolve parameters and overrides, inline subgraphs.

The result is a :class:`FlatGraph` in which every node is a block instance
description with its final parameters and where they came from. Every
mistake becomes a :class:`GraphError` naming the file, line, node and field.
"""
from __future__ import annotations

import difflib
import math
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Iterable

import yaml

from . import builtin  # noqa: F401  (registers the delay block)
from .block import Block
from .errors import GraphError
from .expr import ExprError, evaluate
from .model import Endpoint, FlatEdge, FlatGraph, FlatNode, Origin
from .params import Param, to_float
from .registry import REGISTRY, Registry, SubgraphType
from .scores import parse_scores
from .yamlsrc import LineDict, line_of, load_yaml_file

TOP_KEYS = ("semmap", "name", "doc", "dt", "steps", "params", "inputs", "outputs",
            "nodes", "edges", "scores")
NODE_KEYS = ("id", "type", "include", "params", "period", "offset", "rate", "trigger", "doc")
EDGE_KEYS = ("from", "to", "delay", "initial", "doc")
ID_RE = re.compile(r"^[A-Za-z_][A-Za-z0-9_-]*$")
REF_RE = re.compile(r"\$\{([^}]*)\}")
EDGE_RE = re.compile(r"^\s*(\S+)\s*->\s*(\S+)\s*$")


@dataclass
class Override:
    """One ``--set path=value`` from the command line (or an API caller)."""

    text: str
    path: tuple[str, ...]
    value: Any
    used: bool = False


def parse_overrides(items: Iterable[str] | dict[str, Any] | None) -> list[Override]:
    """Parse ``NODE.PARAM=VALUE`` strings (values are read as YAML scalars)."""
    if not items:
        return []
    if isinstance(items, dict):
        pairs = [(str(k), v, f"{k}={v}") for k, v in items.items()]
    else:
        pairs = []
        for text in items:
            if "=" not in text:
                raise GraphError(f"--set {text!r} has no '='",
                                 hint="Write it as NODE.PARAM=VALUE, e.g. --set ctl.gain=2.")
            key, raw = text.split("=", 1)
            try:
                value = yaml.safe_load(raw) if raw.strip() else ""
            except (yaml.YAMLError, ValueError, RecursionError, OverflowError):
                value = raw  # not YAML: take the text as it is
            pairs.append((key.strip(), value, text))
    result = []
    for key, value, text in pairs:
        parts = tuple(key.split("."))
        if not all(ID_RE.match(p) for p in parts):
            raise GraphError(f"--set {text!r}: {key!r} is not a parameter path",
                             hint="Use PARAM, NODE.PARAM or SUBGRAPH.NODE.PARAM.")
        result.append(Override(text, parts, value))
    return result


@dataclass
class _Expanded:
    """What one graph file contributes once inlined."""

    nodes: list[FlatNode] = field(default_factory=list)
    edges: list[FlatEdge] = field(default_factory=list)
    exposed_in: dict[str, list[Endpoint]] = field(default_factory=dict)
    exposed_out: dict[str, Endpoint] = field(default_factory=dict)


@dataclass
class _LocalNode:
    """A node as its own file sees it: a block, or a subgraph instance."""

    id: str
    line: int | None
    block: FlatNode | None = None
    sub: _Expanded | None = None
    connected_inputs: set[str] = field(default_factory=set)


class GraphLoader:
    """Turns a graph file plus overrides into a FlatGraph."""

    def __init__(self, registry: Registry | None = None,
                 overrides: Iterable[str] | dict[str, Any] | None = None,
                 roles: dict[str, Any] | None = None) -> None:
        self.registry = registry or REGISTRY
        self.overrides = parse_overrides(overrides)
        self.roles = dict(roles or {})  # role -> value, e.g. {"world": "office"}
        self.roles_used: set[str] = set()
        self.groups: dict[str, tuple[str, Origin]] = {}
        self.exposed_outputs: dict[str, Endpoint] = {}
        self.subgraph_params: dict[str, tuple[Any, str]] = {}
        self.param_paths: list[str] = []
        self.dt = 1.0

    # ---- entry ----------------------------------------------------------------
    def load(self, path: str | Path) -> FlatGraph:
        path = Path(path)
        doc = self._read(path)
        self.dt, steps = self._clock(doc, path)
        params, sources = self._graph_params(doc, path, (), {}, None)
        expanded = self._expand_doc(doc, path, (), params, [path.resolve()])
        self._check_overrides_used()
        for role in set(self.roles) - self.roles_used:
            raise GraphError(f"--{role} was given, but no node in the graph takes a {role}",
                             file=path, hint=f"Add a node whose block has a {role} parameter, "
                                             f"or drop --{role}.")
        scope_sub = _Scope(path, (), params)
        steps = scope_sub.subst(steps, line_of(doc, "steps")) if steps is not None else None
        if steps is not None and (isinstance(steps, bool) or not isinstance(steps, int) or steps < 0):
            raise GraphError(f"steps must be a whole number >= 0, got {steps!r}",
                             file=path, line=line_of(doc, "steps"), field="steps")
        nodes = {n.path: n for n in expanded.nodes}
        return FlatGraph(
            name=str(doc.get("name") or path.stem), file=str(path), dt=self.dt, steps=steps,
            nodes=nodes, edges=expanded.edges, params=params, param_sources=sources,
            overrides=[{"set": o.text, "from": "--set"} for o in self.overrides],
            doc=str(doc.get("doc") or ""), groups=self.groups,
            exposed_outputs=self.exposed_outputs, subgraph_params=self.subgraph_params,
            scores=parse_scores(doc.get("scores"), nodes, file=str(path)),
        )

    # ---- reading ----------------------------------------------------------------
    def _read(self, path: Path) -> LineDict:
        doc = load_yaml_file(path)
        if doc is None:
            raise GraphError("the graph file is empty", file=path,
                             hint="A graph needs at least a 'nodes:' list.")
        if not isinstance(doc, dict):
            raise GraphError("a graph file must be a mapping with 'nodes:' and 'edges:'",
                             file=path, line=line_of(doc))
        for key in doc:
            if key not in TOP_KEYS:
                raise GraphError(f"unknown top-level field {key!r}", file=path,
                                 line=line_of(doc, key), hint=_did_you_mean(key, TOP_KEYS))
        return doc

    def _clock(self, doc: LineDict, path: Path) -> tuple[float, Any]:
        dt = doc.get("dt", 0.1)
        try:
            ok = not isinstance(dt, bool) and isinstance(dt, (int, float)) and \
                math.isfinite(to_float(dt)) and 1e-9 <= dt <= 1e6
        except ValueError:
            ok = False
        if not ok:
            raise GraphError(f"dt must be a number of seconds in [1e-9, 1e6], got {_short(dt)}",
                             file=path, line=line_of(doc, "dt"), field="dt")
        return float(dt), doc.get("steps")

    # ---- parameters ---------------------------------------------------------------
    def _graph_params(self, doc: LineDict, path: Path, prefix: tuple[str, ...],
                      given: dict[str, tuple[Any, str, int | None]],
                      caller: Origin | None) -> tuple[dict[str, Any], dict[str, str]]:
        """Resolve a file's declared params from defaults, the caller and --set."""
        specs_raw = doc.get("params") or {}
        if not isinstance(specs_raw, dict):
            raise GraphError("'params' must be a mapping of name: default (or name: {default, "
                             "type, doc, min, max, choices})", file=path,
                             line=line_of(doc, "params"), field="params")
        specs: dict[str, Param] = {}
        for name, spec in specs_raw.items():
            line = line_of(specs_raw, name)
            if not isinstance(name, str) or not ID_RE.match(name):
                raise GraphError(f"parameter name {name!r} is not a valid name", file=path,
                                 line=line, hint="Use letters, digits, '_' and '-'.")
            try:
                specs[name] = Param.from_spec(spec)
            except (ValueError, TypeError) as exc:
                raise GraphError(f"parameter '{name}': {exc}", file=path, line=line,
                                 field=f"param '{name}'") from None
        for name, (_, _, line) in given.items():
            if name not in specs:
                raise GraphError(
                    f"subgraph {path.name} has no parameter '{name}'",
                    file=caller.file if caller else path, line=line,
                    node=".".join(prefix) or None, field=f"param '{name}'",
                    hint=_did_you_mean(name, specs) or
                    f"Its parameters are: {', '.join(specs) or 'none'}.")
        values: dict[str, Any] = {}
        sources: dict[str, str] = {}
        for name, spec in specs.items():
            line = line_of(specs_raw, name)
            self.param_paths.append(".".join(prefix + (name,)))
            value, source = (spec.default, f"{path}:{line}") if not spec.required else (None, "")
            if name in given:
                value, source, _ = given[name]
            if not prefix and name in self.roles:  # `--world X` sets the graph's own `world`
                value, source = self.roles[name], f"--{name}"
                self.roles_used.add(name)
            override = self._take_override(prefix + (name,))
            if override is not None:
                value, source = override.value, "--set"
            if source == "":
                raise GraphError(f"parameter '{name}' has no default and was not given",
                                 file=caller.file if caller else path,
                                 line=caller.line if caller else line,
                                 node=".".join(prefix) or None, field=f"param '{name}'",
                                 hint=f"Pass it in the node's params or with --set "
                                      f"{'.'.join(prefix + (name,))}=VALUE.")
            try:
                values[name] = spec.coerce(value)
            except ValueError as exc:
                raise GraphError(f"graph parameter '{name}': {exc}",
                                 file=path if source != "--set" else None,
                                 line=line if source != "--set" else None,
                                 field=f"param '{name}'" + (" (from --set)" if source == "--set" else ""),
                                 hint=_range_hint(spec)) from None
            sources[name] = source
        return values, sources

    def _take_override(self, path: tuple[str, ...]) -> Override | None:
        found = None
        for override in self.overrides:
            if override.path == path:
                override.used = True
                found = override  # the last --set wins, as on most command lines
        return found

    def _check_overrides_used(self) -> None:
        for override in self.overrides:
            if not override.used:
                key = ".".join(override.path)
                raise GraphError(
                    f"--set {override.text!r}: the graph has no parameter {key!r}",
                    hint=_did_you_mean(key, self.param_paths) or
                    "Run 'semmap check GRAPH --params' to list the settable parameters.")

    # ---- expansion ----------------------------------------------------------------
    def _expand_doc(self, doc: LineDict, path: Path, prefix: tuple[str, ...],
                    params: dict[str, Any], stack: list[Path]) -> _Expanded:
        scope = _Scope(path, prefix, params)
        nodes_raw = doc.get("nodes")
        if nodes_raw is None:
            raise GraphError("the graph has no 'nodes:' list", file=path, line=line_of(doc),
                             hint="Add 'nodes:' with at least one '- id: ..., type: ...'.")
        if not isinstance(nodes_raw, list):
            raise GraphError("'nodes' must be a list of '- id: ..., type: ...' entries",
                             file=path, line=line_of(doc, "nodes"), field="nodes")
        out = _Expanded()
        local: dict[str, _LocalNode] = {}
        for index, raw in enumerate(nodes_raw):
            line = line_of(nodes_raw, index)
            node = self._expand_node(raw, line, scope, stack, local, out)
            local[node.id] = node
        edges_raw = doc.get("edges") or []
        if not isinstance(edges_raw, list):
            raise GraphError("'edges' must be a list of 'a.out -> b.in' strings or "
                             "{from, to, delay, initial} mappings",
                             file=path, line=line_of(doc, "edges"), field="edges")
        for index, raw in enumerate(edges_raw):
            self._expand_edge(raw, line_of(edges_raw, index), scope, local, out)
        self._expose(doc, scope, local, out)
        self._resolve_triggers(nodes_raw, scope, local)
        self._check_subgraph_inputs(local, out, scope)
        return out

    def _expand_node(self, raw: Any, line: int | None, scope: "_Scope", stack: list[Path],
                     local: dict[str, _LocalNode], out: _Expanded) -> _LocalNode:
        path = scope.file
        if not isinstance(raw, dict):
            raise GraphError("each node must be a mapping like '- id: name, type: block'",
                             file=path, line=line)
        for key in raw:
            if key not in NODE_KEYS:
                raise GraphError(f"unknown node field {key!r}", file=path, line=line_of(raw, key),
                                 node=str(raw.get("id", "?")), hint=_did_you_mean(key, NODE_KEYS))
        node_id = raw.get("id")
        if not isinstance(node_id, str) or not ID_RE.match(node_id):
            hint = ("Give every node 'id:' made of letters, digits, '_' or '-' "
                    "(no dots: dots separate subgraph levels).")
            if isinstance(node_id, bool):
                hint = ("YAML reads unquoted yes/no/on/off/true/false as booleans: quote the "
                        "id (id: 'yes') or choose another name.")
            raise GraphError(f"node id {node_id!r} is missing or not a valid name",
                             file=path, line=line_of(raw, "id") if "id" in raw else line,
                             hint=hint)
        if node_id in local:
            raise GraphError(f"duplicate node id '{node_id}' (first defined on line "
                             f"{local[node_id].line})", file=path, line=line_of(raw, "id"),
                             node=node_id, hint="Rename one of the two nodes.")
        full = ".".join(scope.prefix + (node_id,))
        period, offset = self._timing(raw, scope, full)
        node_params_raw = raw.get("params") or {}
        if not isinstance(node_params_raw, dict):
            raise GraphError("'params' must be a mapping of name: value", file=path,
                             line=line_of(raw, "params"), node=full, field="params")
        kind = self._node_kind(raw, scope, full)
        if isinstance(kind, Path):
            sub_path = kind
            if sub_path.resolve() in stack:
                chain = " -> ".join(p.name for p in stack + [sub_path.resolve()])
                raise GraphError(f"include loop: {chain}", file=path, line=line, node=full,
                                 hint="A subgraph may not include itself, directly or not.")
            given = {}
            for name, value in node_params_raw.items():
                pline = line_of(node_params_raw, name)
                given[str(name)] = (scope.subst(value, pline, full), f"{path}:{pline}", pline)
            sub_doc = self._read(sub_path)
            prefix = scope.prefix + (node_id,)
            sub_params, sub_sources = self._graph_params(sub_doc, sub_path, prefix, given,
                                                         Origin(str(path), line))
            for name, value in sub_params.items():
                self.subgraph_params[f"{full}.{name}"] = (value, sub_sources[name])
            expanded = self._expand_doc(sub_doc, sub_path, prefix, sub_params,
                                        stack + [sub_path.resolve()])
            type_label = raw.get("type") or str(raw.get("include"))
            self.groups[full] = (str(type_label), Origin(str(path), line))
            for name, inner_ep in expanded.exposed_out.items():
                self.exposed_outputs[f"{full}.{name}"] = inner_ep
            for inner in expanded.nodes:  # an outer period scales inner periods
                inner.offset = offset + period * inner.offset
                inner.period = period * inner.period
            out.nodes.extend(expanded.nodes)
            out.edges.extend(expanded.edges)
            return _LocalNode(node_id, line, sub=expanded)
        cls: type[Block] = kind
        params, sources = self._block_params(cls, node_params_raw, scope, full, line)
        try:
            inputs, outputs = cls.resolve_ports(params)
        except (ValueError, TypeError, KeyError) as exc:
            raise GraphError(f"the parameters do not give valid ports: {exc}", file=path,
                             line=line, node=full) from None
        flat = FlatNode(path=full, type_name=cls.type_name, cls=cls, params=params,
                        param_sources=sources, origin=Origin(str(path), line),
                        period=period, offset=offset, inputs=dict(inputs), outputs=dict(outputs))
        out.nodes.append(flat)
        return _LocalNode(node_id, line, block=flat)

    def _node_kind(self, raw: dict, scope: "_Scope", full: str) -> type[Block] | Path:
        path = scope.file
        if "include" in raw and "type" in raw:
            raise GraphError("a node has either 'type' or 'include', not both", file=path,
                             line=line_of(raw, "include"), node=full)
        if "include" in raw:
            include = raw["include"]
            if not isinstance(include, str) or not include:
                raise GraphError("'include' must be a path to a YAML subgraph", file=path,
                                 line=line_of(raw, "include"), node=full)
            target = (path.parent / include)
            try:
                found = target.is_file()
            except (OSError, ValueError) as exc:
                raise GraphError(f"cannot use the include path: {exc}", file=path,
                                 line=line_of(raw, "include"), node=full) from None
            if not found:
                raise GraphError(f"included file '{include}' not found (looked in "
                                 f"{target.parent})", file=path, line=line_of(raw, "include"),
                                 node=full, hint="Paths are relative to this graph file.")
            return target
        type_name = raw.get("type")
        if not isinstance(type_name, str) or not type_name:
            raise GraphError("the node has no 'type'", file=path,
                             line=line_of(raw, "type") if "type" in raw else line_of(raw),
                             node=full, hint="Set 'type:' to a block name from 'semmap blocks', "
                                             "or use 'include:' for a subgraph file.")
        found = self.registry.get(type_name)
        if found is None:
            close = self.registry.closest(type_name)
            hint = (f"Did you mean {' or '.join(repr(c) for c in close)}?" if close
                    else "Run 'semmap blocks' to list the block types.")
            raise GraphError(f"unknown block type '{type_name}'", file=path,
                             line=line_of(raw, "type"), node=full, field="type", hint=hint)
        if isinstance(found, SubgraphType):
            return found.path
        return found

    def _timing(self, raw: dict, scope: "_Scope", full: str) -> tuple[int, int]:
        path = scope.file
        period = scope.subst(raw.get("period", 1), line_of(raw, "period"), full)
        if "rate" in raw:
            if "period" in raw:
                raise GraphError("give either 'rate' or 'period', not both", file=path,
                                 line=line_of(raw, "rate"), node=full)
            rate = scope.subst(raw["rate"], line_of(raw, "rate"), full)
            try:
                ticks = 1.0 / (to_float(rate) * self.dt)
                ok = not isinstance(rate, bool) and rate > 0 and math.isfinite(ticks) \
                    and ticks < 1e12
            except (ValueError, TypeError, ZeroDivisionError, OverflowError):
                ok = False
            if not ok:
                raise GraphError(f"rate must be a positive number of Hz, got {_short(rate)}",
                                 file=path, line=line_of(raw, "rate"), node=full, field="rate",
                                 hint=f"At dt = {self.dt} s the fastest rate is "
                                      f"{1 / self.dt:g} Hz.")
            period = round(ticks)
            if period < 1 or abs(ticks - period) > 1e-6 * max(1.0, ticks):
                raise GraphError(f"rate {rate} Hz is not a whole number of ticks at dt = "
                                 f"{self.dt} s ({ticks:.4g} ticks)", file=path,
                                 line=line_of(raw, "rate"), node=full, field="rate",
                                 hint="Choose a rate that divides 1/dt, or set 'period' in ticks.")
        if isinstance(period, bool) or not isinstance(period, int) or period < 1:
            raise GraphError(f"period must be a whole number of ticks >= 1, got {period!r}",
                             file=path, line=line_of(raw, "period"), node=full, field="period")
        offset = scope.subst(raw.get("offset", 0), line_of(raw, "offset"), full)
        if isinstance(offset, bool) or not isinstance(offset, int) or not 0 <= offset < period:
            raise GraphError(f"offset must be a whole number in [0, {period - 1}], got {offset!r}",
                             file=path, line=line_of(raw, "offset"), node=full, field="offset")
        return period, offset

    def _block_params(self, cls: type[Block], given: dict, scope: "_Scope", full: str,
                      node_line: int | None) -> tuple[dict[str, Any], dict[str, str]]:
        path = scope.file
        for name in given:
            if name not in cls.params:
                raise GraphError(
                    f"block type '{cls.type_name}' has no parameter '{name}'", file=path,
                    line=line_of(given, name), node=full, field=f"param '{name}'",
                    hint=_did_you_mean(str(name), cls.params) or
                    f"Its parameters are: {', '.join(cls.params) or 'none'}.")
        values: dict[str, Any] = {}
        sources: dict[str, str] = {}
        for name, spec in cls.params.items():
            self.param_paths.append(f"{full}.{name}")
            line = line_of(given, name) if name in given else node_line
            source = "default"
            value = spec.default
            if name in given:
                value, source = scope.subst(given[name], line, full), f"{path}:{line}"
            if spec.role is not None and spec.role in self.roles:
                value, source = self.roles[spec.role], f"--{spec.role}"
                self.roles_used.add(spec.role)
            override = self._take_override(tuple(full.split(".")) + (name,))
            if override is not None:
                value, source = override.value, "--set"
            if source == "default" and spec.required:
                raise GraphError(f"required parameter '{name}' is not set", file=path,
                                 line=node_line, node=full, field=f"param '{name}'",
                                 hint=f"Add it under the node's 'params:' ({spec.doc}).")
            try:
                values[name] = spec.coerce(value)
            except ValueError as exc:
                raise GraphError(
                    str(exc), file=path if source != "--set" else None,
                    line=line if source != "--set" else None, node=full,
                    field=f"param '{name}'" + (" (from --set)" if source == "--set" else ""),
                    hint=_range_hint(spec)) from None
            sources[name] = source
        return values, sources

    # ---- edges ----------------------------------------------------------------------
    def _expand_edge(self, raw: Any, line: int | None, scope: "_Scope",
                     local: dict[str, _LocalNode], out: _Expanded) -> None:
        path = scope.file
        delay, initial = 0, None
        if isinstance(raw, str):
            match = EDGE_RE.match(raw)
            if not match:
                raise GraphError(f"edge {raw!r} is not of the form 'node.port -> node.port'",
                                 file=path, line=line)
            src_text, dst_text = match.groups()
        elif isinstance(raw, dict):
            for key in raw:
                if key not in EDGE_KEYS:
                    raise GraphError(f"unknown edge field {key!r}", file=path,
                                     line=line_of(raw, key), hint=_did_you_mean(key, EDGE_KEYS))
            src_text, dst_text = raw.get("from"), raw.get("to")
            if not isinstance(src_text, str) or not isinstance(dst_text, str):
                raise GraphError("an edge needs 'from: node.port' and 'to: node.port'",
                                 file=path, line=line)
            if "delay" in raw:
                delay = scope.subst(raw["delay"], line_of(raw, "delay"))
                if isinstance(delay, bool) or not isinstance(delay, int) or delay < 1:
                    raise GraphError(f"delay must be a whole number of ticks >= 1, got {delay!r}",
                                     file=path, line=line_of(raw, "delay"), field="delay")
                if "initial" not in raw:
                    raise GraphError("a delayed edge needs an 'initial' value, used for its "
                                     "first ticks", file=path, line=line_of(raw, "delay"),
                                     hint="Add e.g. 'initial: 0.0' next to 'delay'.")
                initial = scope.subst(raw["initial"], line_of(raw, "initial"))
            elif "initial" in raw:
                raise GraphError("'initial' only applies to an edge with a 'delay'", file=path,
                                 line=line_of(raw, "initial"))
        else:
            raise GraphError("an edge must be 'a.out -> b.in' or a {from, to} mapping",
                             file=path, line=line)
        src = self._source(src_text, scope, local, line)
        dsts = self._destinations(dst_text, scope, local, line)
        origin = Origin(str(path), line)
        if delay:
            dst_node, dst_port = dst_text.rsplit(".", 1)
            dpath = ".".join(scope.prefix + (f"delay@{dst_node}:{dst_port}",))
            cls = self.registry.get("delay")
            assert isinstance(cls, type)
            params = {"n": delay, "initial": initial}
            inputs, outputs = cls.resolve_ports(params)
            out.nodes.append(FlatNode(
                path=dpath, type_name="delay", cls=cls, params=params,
                param_sources={"n": str(origin), "initial": str(origin)}, origin=origin,
                inputs=dict(inputs), outputs=dict(outputs), implicit=True))
            out.edges.append(FlatEdge(src, Endpoint(dpath, "x"), origin))
            src = Endpoint(dpath, "y")
        for dst in dsts:
            out.edges.append(FlatEdge(src, dst, origin))

    def _split(self, text: str, scope: "_Scope", local: dict[str, _LocalNode],
               line: int | None) -> tuple[_LocalNode, str]:
        if "." not in text:
            raise GraphError(f"'{text}' is not of the form node.port", file=scope.file, line=line)
        node_id, port = text.rsplit(".", 1)
        if node_id not in local:
            raise GraphError(f"edge refers to unknown node '{node_id}'", file=scope.file,
                             line=line, hint=_did_you_mean(node_id, local) or
                             f"The nodes here are: {', '.join(local)}.")
        return local[node_id], port

    def _source(self, text: str, scope: "_Scope", local: dict[str, _LocalNode],
                line: int | None) -> Endpoint:
        node, port = self._split(text, scope, local, line)
        names = node.sub.exposed_out if node.sub else node.block.outputs  # type: ignore[union-attr]
        if port not in names:
            raise GraphError(
                f"node '{node.id}' has no output '{port}'", file=scope.file, line=line,
                node=_full(scope, node.id), field=f"port '{port}'",
                hint=_did_you_mean(port, names) or f"Its outputs are: {', '.join(names) or 'none'}.")
        if node.sub:
            return node.sub.exposed_out[port]
        return Endpoint(node.block.path, port)  # type: ignore[union-attr]

    def _destinations(self, text: str, scope: "_Scope", local: dict[str, _LocalNode],
                      line: int | None) -> list[Endpoint]:
        node, port = self._split(text, scope, local, line)
        names = node.sub.exposed_in if node.sub else node.block.inputs  # type: ignore[union-attr]
        if port not in names:
            raise GraphError(
                f"node '{node.id}' has no input '{port}'", file=scope.file, line=line,
                node=_full(scope, node.id), field=f"port '{port}'",
                hint=_did_you_mean(port, names) or f"Its inputs are: {', '.join(names) or 'none'}.")
        node.connected_inputs.add(port)
        if node.sub:
            return list(node.sub.exposed_in[port])
        return [Endpoint(node.block.path, port)]  # type: ignore[union-attr]

    def _check_subgraph_inputs(self, local: dict[str, _LocalNode], out: _Expanded,
                               scope: "_Scope") -> None:
        """A subgraph input feeding a required port must be connected by the caller."""
        by_path = {n.path: n for n in out.nodes}
        for node in local.values():
            if not node.sub:
                continue
            for name, targets in node.sub.exposed_in.items():
                if name in node.connected_inputs:
                    continue
                required = [t for t in targets if t.node in by_path
                            and by_path[t.node].inputs.get(t.port) is not None
                            and by_path[t.node].inputs[t.port].required]
                if required:
                    raise GraphError(
                        f"subgraph input '{name}' is not connected (it feeds the required "
                        f"input {required[0]})", file=scope.file, line=node.line,
                        node=_full(scope, node.id), field=f"port '{name}'",
                        hint=f"Add an edge 'SOURCE.port -> {node.id}.{name}'.")

    def _resolve_triggers(self, nodes_raw: list, scope: "_Scope",
                          local: dict[str, _LocalNode]) -> None:
        for raw in nodes_raw:
            if "trigger" not in raw:
                continue
            spec = raw["trigger"]
            line = line_of(raw, "trigger")
            texts = spec if isinstance(spec, list) else [spec]
            if not texts or not all(isinstance(t, str) for t in texts):
                raise GraphError("'trigger' must be 'node.port' or a list of them",
                                 file=scope.file, line=line, node=_full(scope, raw["id"]),
                                 field="trigger")
            group = [self._source(t, scope, local, line) for t in texts]
            node = local[raw["id"]]
            targets = node.sub.nodes if node.sub else [node.block]
            for target in targets:
                target.triggers.append(group)  # type: ignore[union-attr,arg-type]

    def _expose(self, doc: LineDict, scope: "_Scope", local: dict[str, _LocalNode],
                out: _Expanded) -> None:
        path = scope.file
        for section in ("inputs", "outputs"):
            raw = doc.get(section) or {}
            if not isinstance(raw, dict):
                raise GraphError(f"'{section}' must map exposed names to node.port",
                                 file=path, line=line_of(doc, section), field=section)
            for name, target in raw.items():
                line = line_of(raw, name)
                if not isinstance(name, str) or not ID_RE.match(name):
                    raise GraphError(f"exposed port name {name!r} is not valid", file=path,
                                     line=line, field=section)
                if isinstance(target, dict):
                    target = target.get("to" if section == "inputs" else "from")
                if section == "inputs":
                    texts = target if isinstance(target, list) else [target]
                    if not texts or not all(isinstance(t, str) for t in texts):
                        raise GraphError(f"exposed input '{name}' must name node.port "
                                         "(or a list of them)", file=path, line=line)
                    out.exposed_in[name] = [d for t in texts
                                            for d in self._destinations(t, scope, local, line)]
                else:
                    if not isinstance(target, str):
                        raise GraphError(f"exposed output '{name}' must name one node.port",
                                         file=path, line=line)
                    out.exposed_out[name] = self._source(target, scope, local, line)


class _Scope:
    """One graph file's view: its path, subgraph prefix and parameter values."""

    def __init__(self, file: Path, prefix: tuple[str, ...], params: dict[str, Any]) -> None:
        self.file = file
        self.prefix = prefix
        self.params = params

    def subst(self, value: Any, line: int | None, node: str | None = None) -> Any:
        """Replace ``${name}`` references with graph parameter values."""
        if isinstance(value, str):
            whole = REF_RE.fullmatch(value.strip())
            if whole:
                return self._lookup(whole.group(1).strip(), line, node)
            if "${" in value:
                return REF_RE.sub(lambda m: str(self._lookup(m.group(1).strip(), line, node)),
                                  value)
            return value
        if isinstance(value, dict):
            return {k: self.subst(v, line_of(value, k) or line, node) for k, v in value.items()}
        if isinstance(value, list):
            return [self.subst(v, line, node) for v in value]
        return value

    def _lookup(self, text: str, line: int | None, node: str | None) -> Any:
        if text in self.params:
            return self.params[text]
        if ID_RE.match(text):
            raise GraphError(f"reference ${{{text}}} names no graph parameter", file=self.file,
                             line=line, node=node, hint=_did_you_mean(text, self.params) or
                             "Declare it under the file's top-level 'params:'.")
        try:
            return evaluate(text, self.params)
        except ExprError as exc:
            raise GraphError(f"in ${{{text}}}: {exc}", file=self.file, line=line, node=node,
                             hint="Expressions may use the file's params, numbers, + - * / "
                                  "// % **, comparisons and min, max, abs, round.") from None


def _short(value: Any) -> str:
    text = repr(value)
    return text if len(text) <= 40 else text[:37] + "..."


def _full(scope: _Scope, node_id: str) -> str:
    return ".".join(scope.prefix + (node_id,))


def _did_you_mean(word: str, options: Iterable[Any]) -> str:
    close = difflib.get_close_matches(str(word), [str(o) for o in options], n=3, cutoff=0.5)
    return f"Did you mean {' or '.join(repr(c) for c in close)}?" if close else ""


def _range_hint(spec: Param) -> str:
    allowed = spec.describe_range()
    text = f"Expected {spec.type_name}" + (f", {allowed}" if allowed else "")
    return text + (f" ({spec.doc})." if spec.doc else ".")


def load_graph(path: str | Path, overrides: Iterable[str] | dict[str, Any] | None = None,
               registry: Registry | None = None, roles: dict[str, Any] | None = None
               ) -> FlatGraph:
    """Load and flatten a graph file (validation is separate: see ``check_graph``).

    ``roles`` sets every parameter declared with that role, e.g. ``{"world": path}``.
    """
    return GraphLoader(registry, overrides, roles).load(path)
