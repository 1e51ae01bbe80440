"""Contracts every shipped graph keeps: ground truth is for scoring only."""
from __future__ import annotations

from pathlib import Path

import pytest

from blocks.core.loader import load_graph

ROOT = Path(__file__).resolve().parents[1]
GRAPHS = sorted(p for p in (ROOT / "graphs").rglob("*.yaml"))
GROUND_TRUTH = {"sim2d.true_pose"}  # blocks that read the simulator's answers


@pytest.mark.parametrize("path", GRAPHS, ids=lambda p: str(p.relative_to(ROOT / "graphs")))
def test_ground_truth_feeds_only_scoring_inputs(path):
    graph = load_graph(path)  # flattened: subgraphs' edges included
    truth = {n for n, node in graph.nodes.items() if node.type_name in GROUND_TRUTH}
    for edge in graph.edges:
        if edge.src.node in truth:
            assert edge.dst.port == "truth", (
                f"{path.name}: {edge.src.node}.{edge.src.port} -> {edge.dst.node}."
                f"{edge.dst.port}: the true pose may only feed a scorer's 'truth' input; "
                "decisions take odometry (or a localiser)")


def test_the_contract_sees_the_main_graphs():
    names = {p.name for p in GRAPHS}
    assert {"semantic_mapping.yaml", "mapping.yaml", "ask.yaml"} <= names


def test_the_behaviours_judge_motions_on_the_monitors_memory():
    """The explorer and the room visits replay the monitor's echo memory to creep round
    what it would stop: one memory, set by the graph parameters, feeds all three, so
    they cannot disagree."""
    graph = load_graph(ROOT / "graphs" / "semantic_mapping.yaml",
                       ["echo_memory=3", "near_echo_memory=12", "echo_walls=0.05"])
    memory = graph.nodes["echoes"]
    assert memory.type_name == "navigate.echo_memory"
    assert memory.params["memory"] == 3.0 and memory.params["near_memory"] == 12.0
    assert memory.params["wall_extent"] == 0.05
    fed = {(e.dst.node, e.dst.port) for e in graph.edges if e.src.node == "echoes"}
    assert fed == {("monitor", "echoes"), ("explorer", "echoes"), ("rooms", "echoes")}


def test_the_bumpers_reach_the_shared_memory():
    """What the bumpers felt goes into the one memory, so every behaviour and the monitor
    refuse to push on into it, not only the explorer that reads the switches itself."""
    graph = load_graph(ROOT / "graphs" / "semantic_mapping.yaml", ["feel_bumpers=true"])
    into = {(e.src.node, e.src.port) for e in graph.edges
            if (e.dst.node, e.dst.port) == ("echoes", "bumpers")}
    assert into == {("bumpers", "pressed")} and graph.nodes["echoes"].params["feel"] is True
