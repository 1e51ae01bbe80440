"""Draw a graph: Mermaid or Graphviz DOT text, or a PNG picture.

Subgraph instances become clusters; feedback delays are dashed and labelled
``z^-N``; trigger links are dotted.
"""
from __future__ import annotations

from pathlib import Path

from .model import FlatGraph


def _label(graph: FlatGraph, path: str) -> str:
    node = graph.nodes[path]
    if node.implicit:
        return f"z^-{node.params['n']}"
    return f"{path.split('.')[-1]}: {node.type_name}"


def _id(path: str) -> str:
    return "n_" + "".join(c if c.isalnum() else "_" for c in path)


def _clusters(graph: FlatGraph) -> dict[str, list[str]]:
    """Group path -> the nodes directly inside it ('' is the top level)."""
    members: dict[str, list[str]] = {"": []}
    for group in graph.groups:
        members[group] = []
    for path in graph.nodes:
        parent = path.rsplit(".", 1)[0] if "." in path else ""
        members.setdefault(parent, []).append(path)
    return members


def _links(graph: FlatGraph):
    for edge in graph.edges:
        style = "delay" if graph.nodes[edge.src.node].implicit else "data"
        yield edge.src.node, edge.dst.node, f"{edge.src.port}→{edge.dst.port}", style
    for node in graph.nodes.values():
        for group in node.triggers:
            for src in group:
                yield src.node, node.path, f"trigger {src.port}", "trigger"


def to_mermaid(graph: FlatGraph) -> str:
    lines = ["flowchart LR"]
    members = _clusters(graph)

    def emit(group: str, indent: str) -> None:
        for path in members.get(group, []):
            shape = f'(["{_label(graph, path)}"])' if graph.nodes[path].implicit \
                else f'["{_label(graph, path)}"]'
            lines.append(f"{indent}{_id(path)}{shape}")
        for child in sorted(g for g in members if g and _parent(g) == group):
            kind = graph.groups.get(child, ("", None))[0]
            lines.append(f'{indent}subgraph {_id(child)}["{child.split(".")[-1]}: {kind}"]')
            emit(child, indent + "  ")
            lines.append(f"{indent}end")

    emit("", "  ")
    arrows = {"data": "-->", "delay": "-.->", "trigger": "-.->"}
    for src, dst, label, style in _links(graph):
        lines.append(f'  {_id(src)} {arrows[style]}|"{label}"| {_id(dst)}')
    return "\n".join(lines) + "\n"


def _parent(group: str) -> str:
    return group.rsplit(".", 1)[0] if "." in group else ""


def to_dot(graph: FlatGraph) -> str:
    lines = [f'digraph "{graph.name}" {{', "  rankdir=LR;",
             '  node [shape=box, style="rounded", fontname="Helvetica"];']
    members = _clusters(graph)

    def emit(group: str, indent: str) -> None:
        for path in members.get(group, []):
            shape = ", shape=circle" if graph.nodes[path].implicit else ""
            lines.append(f'{indent}{_id(path)} [label="{_label(graph, path)}"{shape}];')
        for child in sorted(g for g in members if g and _parent(g) == group):
            kind = graph.groups.get(child, ("", None))[0]
            lines.append(f"{indent}subgraph cluster_{_id(child)} {{")
            lines.append(f'{indent}  label="{child.split(".")[-1]}: {kind}";')
            emit(child, indent + "  ")
            lines.append(f"{indent}}}")

    emit("", "  ")
    styles = {"data": "", "delay": ", style=dashed", "trigger": ", style=dotted"}
    for src, dst, label, style in _links(graph):
        lines.append(f'  {_id(src)} -> {_id(dst)} [label="{label}"{styles[style]}];')
    lines.append("}")
    return "\n".join(lines) + "\n"


def to_png(graph: FlatGraph, path: str | Path) -> None:
    """A layered drawing (sources left, sinks right) saved as PNG."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import networkx as nx

    from .atomic import atomic_writer
    from .validate import dependency_graph

    dag = nx.DiGraph()
    dag.add_nodes_from(graph.nodes)
    links = list(_links(graph))
    for src, dst, _, style in links:
        dag.add_edge(src, dst, style=style)
    # Layers come from the schedule's dependency order, which has no cycles.
    deps = dependency_graph(graph)
    layer: dict[str, int] = {}
    for vertex in nx.topological_sort(deps):
        name = vertex.split("#")[0]
        preds = [layer.get(p.split("#")[0], 0) + 1 for p in deps.predecessors(vertex)
                 if p.split("#")[0] != name]
        layer[name] = max([layer.get(name, 0), *preds])
    for name, value in layer.items():
        dag.nodes[name]["layer"] = value
    pos = nx.multipartite_layout(dag, subset_key="layer", align="vertical")
    width = 2.2 * (max(layer.values(), default=0) + 1) + 2
    height = 0.9 * max(sum(1 for v in layer.values() if v == k) for k in set(layer.values()) or {0}) + 2
    fig, ax = plt.subplots(figsize=(min(width, 40), min(max(height, 3), 30)))
    colors = {"data": "#333333", "delay": "#c0392b", "trigger": "#2874a6"}
    for style, dash in (("data", "solid"), ("delay", "dashed"), ("trigger", "dotted")):
        edges = [(u, v) for u, v, d in dag.edges(data=True) if d["style"] == style]
        nx.draw_networkx_edges(dag, pos, edgelist=edges, ax=ax, edge_color=colors[style],
                               style=dash, arrows=True, arrowsize=14, node_size=2600)
    groups = {p: (_parent(p) or "top") for p in graph.nodes}
    palette = ["#d6eaf8", "#d5f5e3", "#fdebd0", "#f5eef8", "#fcf3cf", "#e5e8e8"]
    order = sorted(set(groups.values()))
    face = [palette[order.index(groups[n]) % len(palette)] for n in dag.nodes]
    nx.draw_networkx_nodes(dag, pos, ax=ax, node_color=face, node_shape="s", node_size=2600,
                           edgecolors="#555555")
    nx.draw_networkx_labels(dag, pos, {n: _label(graph, n).replace(": ", "\n") for n in dag.nodes},
                            ax=ax, font_size=7)
    ax.set_title(f"{graph.name}  (dashed: delay, dotted: trigger; colour: subgraph)")
    ax.axis("off")
    fig.tight_layout()
    with atomic_writer(path, "wb") as fh:
        fig.savefig(fh, format="png", dpi=110)
    plt.close(fig)
