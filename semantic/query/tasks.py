"""Objectives to a plan: ordered steps with collision-free legs between them.

Each objective of a :class:`~semantic.query.ground.Grounding` becomes a ``go
to`` step (a leg planned with A* on the map inflated by the robot's radius)
followed by what is done there (``pick up``, ``hand over``, ``look for``).
A leg longer than :data:`GUIDE_DISTANCE` is guided by the place graph: the
shortest chain of places through their doors (networkx, weighted by the
distance between doorways) gives the A* searches short hops from door to door,
and the answer can say which places the route crosses. If the doorways of the
chain cannot be planned through (a door drawn too narrow on a sonar map), the
leg falls back to one A* search over the whole map.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import networkx as nx
import numpy as np

from blocks.navigate.planner import PlannedPath, PlanningError, plan, plan_via

from .ground import Grounding, GroundingError, Objective, Target
from .mapsource import QueryMap

__all__ = ["GUIDE_DISTANCE", "Step", "TaskPlan", "plan_task"]

#: Legs longer than this (m, straight line) follow the place graph's chain of doors.
GUIDE_DISTANCE = 8.0


@dataclass(frozen=True)
class Step:
    """One step of a plan. ``leg_m`` and ``route`` are set on ``go to`` steps."""

    action: str
    place: str
    place_id: str | None
    object: str | None
    x: float
    y: float
    leg_m: float | None = None
    route: tuple[str, ...] = ()

    def to_dict(self) -> dict[str, Any]:
        out = {"action": self.action, "place": self.place, "object": self.object,
               "x": round(self.x, 3), "y": round(self.y, 3), "place_id": self.place_id}
        if self.leg_m is not None:
            out["leg_m"] = round(self.leg_m, 3)
            out["route"] = list(self.route)
        return out


@dataclass
class TaskPlan:
    """A grounded request with its steps and paths.

    Attributes
    ----------
    grounding
        The request and its objectives.
    steps
        In order; ``go to`` steps carry their leg's length and place route.
    legs
        The planned path of each ``go to`` step, in order.
    """

    grounding: Grounding
    steps: list[Step] = field(default_factory=list)
    legs: list[PlannedPath] = field(default_factory=list)

    @property
    def path(self) -> np.ndarray:
        """(N, 2) the whole path, legs joined."""
        parts = [leg.points if k == 0 else leg.points[1:] for k, leg in enumerate(self.legs)]
        return np.vstack(parts) if parts else np.zeros((0, 2))

    @property
    def path_length(self) -> float:
        return float(sum(leg.length for leg in self.legs))

    @property
    def answer(self) -> str:
        return self.grounding.answer

    def goals(self) -> list[dict[str, Any]]:
        """The ``go to`` steps as goals for ``navigate.goto``: ``{x, y, name}``."""
        return [{"x": s.x, "y": s.y, "name": s.place} for s in self.steps if s.action == "go to"]

    def to_dict(self) -> dict[str, Any]:
        """The stable machine-readable form (``semmap ask --json``)."""
        g = self.grounding
        return {"command": g.request.text,
                "request": g.request.to_dict(),
                "objectives": [o.to_dict() for o in g.objectives],
                "steps": [s.to_dict() for s in self.steps],
                "answer": g.answer,
                "path_length_m": round(self.path_length, 3),
                "when": g.when.isoformat(timespec="minutes") if g.when else None}


def _door_graph(qm: QueryMap) -> nx.Graph:
    """The place graph weighted for routing: each edge costs the distance from one place's
    centre to the other's through the door (the shortest door when several join them)."""
    g = nx.Graph()
    for a, b, data in qm.place_graph.edges(data=True):
        ca, cb = qm.places[a].centre, qm.places[b].centre
        best = None
        for door in data.get("doors", []):
            pos = qm.kb.door_position(door)
            if pos is None or ca is None or cb is None:
                continue
            cost = math.dist(ca, pos) + math.dist(pos, cb)
            if best is None or cost < best[0]:
                best = (cost, pos)
        if best is not None:
            g.add_edge(a, b, weight=best[0], door=best[1])
    return g


def _route(qm: QueryMap, a: tuple[float, float], b: tuple[float, float]
           ) -> tuple[list[str], list[tuple[float, float]]]:
    """The chain of places from the one holding ``a`` to the one holding ``b``, and the door
    points between them (empty when either end is in no place or no chain exists)."""
    pa, pb = qm.place_at(*a), qm.place_at(*b)
    if pa is None or pb is None or pa == pb:
        return [], []
    g = qm.__dict__.get("_door_graph")
    if g is None:  # built once per map (setdefault would build it on every call)
        g = qm.__dict__["_door_graph"] = _door_graph(qm)
    try:
        chain = nx.shortest_path(g, pa, pb, weight="weight")
    except (nx.NetworkXNoPath, nx.NodeNotFound):
        return [], []
    return chain, [g.edges[u, v]["door"] for u, v in zip(chain, chain[1:])]


def _leg(qm: QueryMap, start: tuple[float, float], target: Target) -> tuple[PlannedPath,
                                                                              list[str]]:
    """A* from ``start`` to the target, through the place chain's doors on long legs."""
    goal = (target.x, target.y)
    chain, doors = _route(qm, start, goal)
    if doors and math.dist(start, goal) > GUIDE_DISTANCE:
        try:
            return plan_via(qm.grid, [start, *doors, goal]), chain
        except PlanningError:
            pass  # a doorway too narrow on this map: search the whole map instead
    try:
        return plan(qm.grid, start, goal), chain
    except PlanningError as exc:
        raise GroundingError(f"no way to {target.label} on this map: {exc.message}",
                             hint="The map may not show a way in; map the building again "
                                  "with room visits on.") from None


def plan_task(grounding: Grounding, qm: QueryMap) -> TaskPlan:
    """Plan the steps of a grounded request, starting where the robot is (``qm.home``).

    Raises
    ------
    GroundingError
        A target cannot be reached on this map.
    """
    out = TaskPlan(grounding)
    here = (float(qm.home[0]), float(qm.home[1]))
    for objective in grounding.objectives:
        target = objective.target
        leg, chain = _leg(qm, here, target)
        out.legs.append(leg)
        out.steps.append(Step("go to", target.label, target.place_id, None, target.x, target.y,
                              leg.length, tuple(qm.label(p) for p in chain)))
        if objective.action != "go to":
            out.steps.append(_act(objective))
        here = (float(leg.points[-1][0]), float(leg.points[-1][1]))
    return out


def _act(objective: Objective) -> Step:
    t = objective.target
    return Step(objective.action, t.label, t.place_id, objective.thing, t.x, t.y)
