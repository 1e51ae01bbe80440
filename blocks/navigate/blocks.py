"""Navigation blocks: thin adapters over :mod:`blocks.navigate` (grid, planner, pursuit, visit).

``navigate.goto`` drives the robot to a list of goals: it plans with A* on the
map it is given (a mapping block's handle, re-read every ``map_period``
seconds) or on the world's true floor plan, follows each path by pure
pursuit, optionally looks around 360 degrees at each goal, and replans when
the path is blocked or the robot strays from it.
"""
from __future__ import annotations

import json
import math
from typing import Any

import numpy as np

from blocks.core import Block, BlockError, Param, Port, block

from .grid import inflate
from .pursuit import PursuitParams
from .visit import Visit, parse_goals


def _canonical(value: Any) -> str:
    """A comparable text form of a goals message (new message = different text)."""
    def plain(v: Any) -> Any:
        if isinstance(v, np.ndarray):
            return v.tolist()
        if isinstance(v, dict):
            return {str(k): plain(x) for k, x in v.items()}
        if isinstance(v, (list, tuple)):
            return [plain(x) for x in v]
        if hasattr(v, "__dataclass_fields__"):
            return plain(vars(v))
        if isinstance(v, np.generic):
            return v.item()
        return v
    return json.dumps(plain(value), sort_keys=True, default=str)


@block("navigate.goto", category="navigate")
class Goto(Block):
    """Goes to each goal in turn: A* on the map, pure pursuit, optional look-around.

    Goals come from the ``goals`` input (a message: a list of ``[x, y]``,
    ``[x, y, spin]`` or ``{x, y, spin, name}``) or, when it is not connected,
    from the ``goals`` parameter.  A goals message that differs from the last
    one replaces the queue (or is appended, with ``append``); an empty list
    stops the robot.  The map is the ``map`` handle's ``snapshot()`` when
    connected, else the true floor plan of ``world``.  A goal that cannot be
    planned to, or that takes longer than ``timeout``, is given up and
    reported; run.json gets the counts and each goal's outcome and times.
    """

    inputs = {"pose": Port.array("float64", (3,), unit="m,m,rad",
                                 doc="the robot's pose in the map frame"),
              "goals": Port.message(required=False, default=None,
                                    doc="goals: list of [x, y], [x, y, spin] or {x, y, spin, name}"),
              "map": Port(kind="handle", required=False, default=None,
                          doc="a map being built (snapshot() gives an OccupancyMap)")}
    outputs = {"v": Port.scalar("float64", unit="m/s", doc="translation velocity"),
               "w": Port.scalar("float64", unit="rad/s", doc="rotation velocity (CCW +)"),
               "active": Port.scalar("bool", doc="true while a goal is pursued or waiting"),
               "reached": Port.event(doc="true on the tick a goal is reached"),
               "failed": Port.event(doc="true on the tick a goal is given up"),
               "done": Port.event(doc="true from the tick the last goal ends")}
    params = {
        "world": Param(str, "", "world whose true floor plan is used when no map is connected",
                       role="world"),
        "goals": Param(list, [], "goals when the goals input is not connected: [[x, y], ...]"),
        "robot": Param(str, "atrv_mini", "robot model (radius and velocity limits)"),
        "radius": Param(float, 0.0, "obstacle inflation; 0: the robot's circumscribed radius",
                        unit="m", min=0.0),
        "cruise": Param(float, 0.4, "speed on straight legs", unit="m/s", min=0.01),
        "lookahead": Param(float, 0.6, "pure-pursuit lookahead at cruise speed", unit="m",
                           min=0.05),
        "tolerance": Param(float, 0.08, "distance to a goal that counts as reached", unit="m",
                           min=0.01),
        "spin": Param(bool, False, "turn 360 degrees at goals that do not say"),
        "spin_rate": Param(float, 0.8, "turn rate of the look-around", unit="rad/s", min=0.05),
        "timeout": Param(float, 90.0, "seconds a goal may take before it is given up", unit="s",
                         min=0.1),
        "unknown": Param(str, "blocked", "unknown map cells: blocked, or crossed at a cost",
                         choices=("blocked", "cost")),
        "map_period": Param(float, 2.0, "seconds between re-reads of the connected map",
                            unit="s", min=0.0),
        "append": Param(bool, False, "a new goals message adds to the queue instead of "
                                     "replacing it"),
        "stop_when_done": Param(bool, False, "stop the run once every goal has ended"),
    }

    def setup(self) -> None:
        from sim2d.robot import load_robot
        spec = load_robot(self.p.robot)
        self._radius = self.p.radius or math.ceil(spec.radius * 100) / 100
        self._follow = PursuitParams(cruise=min(self.p.cruise, spec.limits.max_speed),
                                     max_speed=spec.limits.max_speed,
                                     max_turn_rate=spec.limits.max_turn_rate,
                                     lookahead=self.p.lookahead,
                                     lookahead_min=min(0.3, self.p.lookahead),
                                     goal_tolerance=self.p.tolerance)
        try:
            self._static_goals = parse_goals(self.p.goals)
        except ValueError as exc:
            raise BlockError(str(exc), node=self.name, field="param 'goals'") from None

    def reset(self) -> None:
        self.visit: Visit | None = None
        self._pending = list(self._static_goals)
        self._last_goals: str | None = None
        self._next_map_time = 0.0
        self._world_grid = None

    # ---- the map --------------------------------------------------------------------------
    def _grid_from(self, occupancy_map: Any):
        return inflate(occupancy_map, radius=self._radius, unknown=self.p.unknown)

    def _true_grid(self):
        if self._world_grid is None:
            from blocks.maps.mapio import occupancy_map_from_world
            from sim2d.blocks import resolve_world
            from sim2d.world import load_world
            world = load_world(resolve_world(self.p.world))
            self._world_grid = self._grid_from(occupancy_map_from_world(world))
        return self._world_grid

    def _update_grid(self, handle: Any) -> None:
        now = self.ctx.time
        if handle is None:
            if self.visit is None and self._pending:
                if not self.p.world:
                    raise BlockError("no map to plan on", node=self.name, field="input 'map'",
                                     hint="Connect a map handle (e.g. a mapping block's 'map') "
                                          "or set the 'world' parameter to plan on its floor "
                                          "plan.")
                self._make_visit(self._true_grid())
            return
        if self.visit is not None and now < self._next_map_time:
            return
        snapshot = getattr(handle, "snapshot", None)
        if snapshot is None:
            raise BlockError("the 'map' input has no snapshot()", node=self.name,
                             field="input 'map'", hint="Connect a mapping block's 'map' handle.")
        occupancy_map = snapshot()
        if occupancy_map is None:
            return
        self._next_map_time = now + self.p.map_period
        grid = self._grid_from(occupancy_map)
        if self.visit is None:
            if self._pending:
                self._make_visit(grid)
        else:
            self.visit.set_grid(grid)

    def _make_visit(self, grid: Any) -> None:
        self.visit = Visit(self._pending, grid, params=self._follow, spin=self.p.spin,
                           spin_rate=self.p.spin_rate, timeout=self.p.timeout)
        self._pending = []

    # ---- goals ----------------------------------------------------------------------------
    def _take_goals(self, goals: Any) -> None:
        text = _canonical(goals)
        if text == self._last_goals:
            return  # the same message held from an earlier tick
        self._last_goals = text
        try:
            parsed = parse_goals(goals)
        except ValueError as exc:
            raise BlockError(str(exc), node=self.name, field="input 'goals'") from None
        if self.visit is None:
            self._pending = self._pending + parsed if self.p.append else parsed
        elif self.p.append:
            self.visit.add_goals(parsed)
        else:
            self.visit.replace_goals(parsed)

    def step(self, pose: np.ndarray, goals: Any = None, map: Any = None) -> dict[str, Any]:  # noqa: A002
        if goals is not None:
            self._take_goals(goals)
        self._update_grid(map)
        if self.visit is None:
            return {"v": 0.0, "w": 0.0, "active": bool(self._pending), "reached": False,
                    "failed": False, "done": False}
        v, w, _ = self.visit.step(pose, self.ctx.dt)
        done = self.visit.done
        if done and self.p.stop_when_done:
            self.request_stop("all goals ended")
        return {"v": float(v), "w": float(w), "active": self.visit.active,
                "reached": self.visit.event == "reached", "failed": self.visit.event == "failed",
                "done": done}

    def finish(self) -> None:
        visit = getattr(self, "visit", None)
        if visit is None:
            return
        self.report("goals_reached", len(visit.reached))
        self.report("goals_failed", len(visit.failed))
        self.report("goals", [r.as_dict() for r in visit.results])
