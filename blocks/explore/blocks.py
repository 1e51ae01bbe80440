"""Blocks of the two-layer fuzzy perimeter follower (thin adapters over controller.py)."""
from __future__ import annotations

import math
from typing import Any

import numpy as np

from ..core import Block, BlockError, Param, Port, block
from ..fuzzy import compile_kb, load_kb
from ..navigate.blocks import MONITORED_ECHO_PARAMS, echo_memory_input
from .controller import (KB_DIR, narrow_corridor_groups, sonar_group_index, sonar_groups,
                         sonar_groups_one)
from .loop import LoopClosure

SUBGRAPHS = "subgraphs"  # publishes perimeter_follower.yaml as a block type

DISTANCE = Port.scalar("float64", unit="m", frame="robot")
PROBABILITY = Port.scalar("float64", doc="collision probability in [0, 1]")


def _robot_spec(model: str):
    from sim2d.robot import load_robot
    return load_robot(model)


@block("explore.sonar_groups", category="explore")
class SonarGroups(Block):
    """Group distances (the minimum of each group's sonar pair) and dRt = Rt1 - Rt2.

    The groups come from the robot file (``sonar.groups``); a sonar without an
    echo reads its maximum range, which the controllers see as VERYFAR.
    """

    inputs = {"ranges": Port.array("float64", (16,), unit="m", frame="robot",
                                   doc="sonar ranges, in the robot file's order")}
    outputs = {name: DISTANCE.with_fields(doc=f"group {name} (m)")
               for name in ("Fr", "FrLt", "FrRt", "Rt", "RtFr", "Lt")}
    outputs["dRt"] = Port.scalar("float64", unit="m", doc="Rt1 - Rt2: 0 when parallel")
    params = {"robot": Param(str, "atrv_mini", "robot model or robot YAML (for the groups)"),
              "narrow_corridors": Param(bool, False, "centre in passages too narrow to keep the "
                                                     "wall distance (uses the left sonars)"),
              "side_target": Param(float, 0.45, "wall distance from the side sonars that the "
                                                "side controller aims for", unit="m", min=0.05)}

    def setup(self) -> None:
        spec = _robot_spec(self.p.robot)
        index = sonar_group_index(spec)
        missing = {"Fr", "FrLt", "FrRt", "Rt", "RtFr", "Lt"} - set(index)
        if missing:
            raise BlockError(f"the robot file has no sonar group(s) {sorted(missing)}",
                             node=self.name, field="param 'robot'")
        self._index = index
        self._names = list(self.outputs)

    def step(self, ranges: np.ndarray) -> dict[str, Any]:
        if not self.p.narrow_corridors:
            groups = sonar_groups_one(ranges, self._index)
            return {name: groups[name] for name in self._names}
        groups = narrow_corridor_groups(sonar_groups(ranges, self._index), self.p.side_target)
        return {name: float(value[0]) for name, value in groups.items()
                if name in self.outputs}


class _FuzzyBlock(Block):
    """Evaluates a knowledge base (compiled) on its scalar inputs."""

    category = "explore"
    default_kb = ""

    def setup(self) -> None:
        self.kb = load_kb(self.p.kb or KB_DIR / self.default_kb)
        expected = set(self.inputs) - {"stop"}
        if set(self.kb.inputs) != expected:
            raise BlockError(f"the knowledge base's inputs {sorted(self.kb.inputs)} are not "
                             f"this block's {sorted(expected)}", node=self.name,
                             field="param 'kb'")
        self.controller = compile_kb(self.kb)
        self._order = self.controller.input_names

    def _evaluate(self, values: dict[str, float]) -> list[float]:
        return self.controller.evaluate_one([values[name] for name in self._order])


KB_PARAM_DOC = "knowledge base YAML (default: the packaged one)"


@block("explore.front_cp", category="explore")
class FrontCollision(_FuzzyBlock):
    """Layer 1, front: collision probability ahead from Fr, FrLt and FrRt (64 rules)."""

    default_kb = "front.yaml"
    inputs = {"Fr": DISTANCE, "FrLt": DISTANCE, "FrRt": DISTANCE}
    outputs = {"FrontCP": PROBABILITY}
    params = {"kb": Param(str, "", KB_PARAM_DOC)}

    def step(self, Fr: float, FrLt: float, FrRt: float) -> dict[str, Any]:  # noqa: N803
        return {"FrontCP": self._evaluate({"Fr": Fr, "FrLt": FrLt, "FrRt": FrRt})[0]}


@block("explore.side_cp", category="explore")
class SideCollision(_FuzzyBlock):
    """Layer 1, side: collision probability on the right from Rt and RtFr (16 rules)."""

    default_kb = "side.yaml"
    inputs = {"Rt": DISTANCE, "RtFr": DISTANCE}
    outputs = {"RightCP": PROBABILITY}
    params = {"kb": Param(str, "", KB_PARAM_DOC)}

    def step(self, Rt: float, RtFr: float) -> dict[str, Any]:  # noqa: N803
        return {"RightCP": self._evaluate({"Rt": Rt, "RtFr": RtFr})[0]}


@block("explore.follow", category="explore")
class Follow(_FuzzyBlock):
    """Layer 2: velocities from FrontCP, RightCP and dRt (48 rules); halts while ``stop``.

    The knowledge base gives fractions; the block scales them by ``v_fraction``
    of the robot's top speed and ``w_fraction`` of its top turn rate (the
    paper's 70 % and 40 %).
    """

    default_kb = "follow.yaml"
    inputs = {"FrontCP": PROBABILITY, "RightCP": PROBABILITY,
              "dRt": Port.scalar("float64", unit="m", doc="Rt1 - Rt2"),
              "stop": Port.scalar("bool", required=False, default=False,
                                  doc="halt while true (e.g. while a sign is read)")}
    outputs = {"v": Port.scalar("float64", unit="m/s", doc="translation velocity"),
               "w": Port.scalar("float64", unit="rad/s", doc="rotation velocity (CCW +)")}
    params = {"kb": Param(str, "", KB_PARAM_DOC),
              "robot": Param(str, "atrv_mini", "robot model (for its velocity limits)"),
              "v_fraction": Param(float, 0.7, "share of the top speed the output spans",
                                  min=0.0, max=1.0),
              "w_fraction": Param(float, 0.4, "share of the top turn rate the output spans",
                                  min=0.0, max=1.0)}

    def setup(self) -> None:
        super().setup()
        limits = _robot_spec(self.p.robot).limits
        self._scale = (float(self.p.v_fraction * limits.max_speed),
                       float(self.p.w_fraction * limits.max_turn_rate))
        self._v, self._w = (self.controller.output_names.index(n) for n in ("v", "w"))

    def step(self, FrontCP: float, RightCP: float, dRt: float,  # noqa: N803
             stop: bool = False) -> dict[str, Any]:
        if stop:
            return {"v": 0.0, "w": 0.0}
        out = self._evaluate({"FrontCP": FrontCP, "RightCP": RightCP, "dRt": dRt})
        return {"v": out[self._v] * self._scale[0], "w": out[self._w] * self._scale[1]}


@block("explore.loop_closure", category="explore")
class LoopClosureBlock(Block):
    """Fires ``done`` once the robot is back at its start after going round.

    The paper's termination rule: having gone round the perimeter, the robot
    returns to where it began. ``min_travel`` and ``min_away`` keep the
    departure from counting; the heading on return (within
    ``max_heading_error`` of the start's) and the net turn (at least
    ``min_turning`` degrees, either sense) keep a robot that turned back in a
    dead end from calling its way back a loop. See :mod:`blocks.explore.loop`.
    """

    inputs = {"pose": Port.array("float64", (3,), unit="m,m,rad",
                                 doc="pose (odometry, or truth for scoring)")}
    outputs = {"done": Port.event(doc="true from the tick the loop closes"),
               "travelled": Port.scalar("float64", unit="m", doc="path length so far")}
    params = {"radius": Param(float, 1.0, "how close to the start counts as back", unit="m",
                              min=0.0),
              "min_travel": Param(float, 10.0, "path length before a return counts", unit="m",
                                  min=0.0),
              "min_away": Param(float, 3.0, "how far from the start the path must get",
                                unit="m", min=0.0),
              "max_heading_error": Param(float, 60.0, "largest heading difference from the "
                                                      "start's on return", unit="deg", min=0.0,
                                         max=180.0),
              "min_turning": Param(float, 270.0, "smallest net turn since the start (a lap "
                                                 "turns 360)", unit="deg", min=0.0)}
    category = "explore"

    def reset(self) -> None:
        self.loop = LoopClosure(self.p.radius, self.p.min_travel, self.p.min_away,
                                math.radians(self.p.max_heading_error),
                                math.radians(self.p.min_turning))

    def step(self, pose: np.ndarray) -> dict[str, Any]:
        done = self.loop.update(float(pose[0]), float(pose[1]), self.ctx.time, float(pose[2]))
        return {"done": done, "travelled": self.loop.travelled}

    def finish(self) -> None:
        if hasattr(self, "loop"):
            self.report("loop_closed", self.loop.closed_at is not None)
            self.report("loop_time_s", self.loop.closed_at)
            self.report("distance_travelled_m", round(self.loop.travelled, 3))
            self.report("passes_refused", self.loop.refused)
            self.report("turned_deg", round(math.degrees(self.loop.turned), 1))


@block("explore.follow_metrics", category="explore")
class FollowMetrics(Block):
    """Scores wall following: mean and 95th-percentile |distance - target|, time within tolerance.

    Feed it the true distance to the right wall (``sim2d.right_wall``); the
    statistics go to run.json. Ticks without a wall within ``wall_within``
    (doors, outer corners) are left out and reported as ``fraction_with_wall``.
    """

    inputs = {"distance": Port.scalar("float64", unit="m", doc="distance to the followed wall")}
    params = {"target": Param(float, 0.7, "wanted distance from the robot's centre", unit="m",
                              min=0.0),
              "tolerance": Param(float, 0.15, "band counted as on target", unit="m", min=0.0),
              "wall_within": Param(float, 2.0, "farther than this counts as no wall", unit="m",
                                   min=0.0)}
    category = "explore"

    def reset(self) -> None:
        from .metrics import FollowStats
        self.stats = FollowStats(self.p.target, self.p.tolerance, self.p.wall_within)

    def step(self, distance: float) -> None:
        self.stats.add(float(distance))

    def finish(self) -> None:
        if hasattr(self, "stats"):
            for key, value in self.stats.summary().items():
                self.report(key, value)


@block("explore.frontiers", category="explore")
class FrontierExploration(Block):
    """Explores the rest of the floor after the follower: frontiers on the robot's own map.

    A behaviour behind the perimeter follower (subsumption): while the
    follower explores, ``v_in`` and ``w_in`` pass through.  Once its loop
    closes (``follower_done``), or once it has driven ``stale_distance``
    without the map gaining floor (circling an island), the block drives
    instead: to the cheapest reachable frontier of ``map`` (planned with A*,
    driven with pure pursuit, a sonar guard checking every command), again and
    again, until none is left.  A bumper pressed, or a command odometry does
    not see (a stall), makes it back off and plan again, with what it touched
    on the map; while the follower drives, it backs the follower off, turns it
    away from the wall and hands back, or takes over for good once the
    follower keeps getting caught.  Stuck (its ways failing one after another
    at one place), it hands back to the follower for a few metres and plans
    again from there.  ``done`` fires when it ends; run.json gets why
    (``explored``, ``stuck`` or ``time budget``) and what it did.  With
    ``enabled`` false it passes the follower through, ``done`` included: the
    paper's perimeter-only exploration.  See :mod:`blocks.explore.explorer`.
    """

    inputs = {"pose": Port.array("float64", (3,), unit="m,m,rad",
                                 doc="the robot's pose, in the map's frame (odometry, "
                                     "or odometry corrected: maps.drift_correction)"),
              "odometry": Port.array("float64", (3,), unit="m,m,rad", required=False,
                                     default=None, doc="the raw odometry pose, when 'pose' is "
                                                       "corrected: stalls are judged on it"),
              "ranges": Port.array("float64", (16,), unit="m", frame="robot",
                                   doc="sonar ranges, in the robot file's order"),
              "map": Port(kind="handle", doc="the robot's map: snapshot() gives an OccupancyMap "
                                             "with unknown cells (e.g. maps.logodds_map)"),
              "v_in": Port.scalar("float64", unit="m/s", doc="the follower's translation"),
              "w_in": Port.scalar("float64", unit="rad/s", doc="the follower's rotation"),
              "follower_done": Port.scalar("bool", required=False, default=False,
                                           doc="the follower is done (its loop closed)"),
              "hold": Port.scalar("bool", required=False, default=False,
                                  doc="stop (e.g. the sign seeker's stop)"),
              "preempted": Port.scalar("bool", required=False, default=False,
                                       doc="another behaviour drives (e.g. a room visit; "
                                           "connect it with a delay of 1)"),
              "bumpers": Port.array("bool", (None,), required=False, default=None,
                                    frame="robot", doc="the contact switches pressed now "
                                                       "(sim2d.bumpers), in the robot "
                                                       "file's order"),
              "monitor_scale": Port.scalar("float64", required=False, default=1.0,
                                           doc="how much of the last command the collision "
                                               "monitor let through (its 'scale', with a "
                                               "delay of 1; with 'monitored')"),
              "echoes": Port(kind="handle", required=False, default=None,
                             doc="with 'monitored': the monitor's navigate.echo_memory, to "
                                 "judge motions on (unconnected: a copy of its own)")}
    outputs = {"v": Port.scalar("float64", unit="m/s", doc="translation velocity"),
               "w": Port.scalar("float64", unit="rad/s", doc="rotation velocity (CCW +)"),
               "exploring": Port.scalar("bool", doc="true while the frontier explorer drives"),
               "done": Port.scalar("bool", doc="exploration has ended")}
    params = {
        "enabled": Param(bool, True, "explore frontiers after the follower; false: the "
                                     "follower's perimeter alone (the paper's exploration)"),
        "robot": Param(str, "atrv_mini", "robot model (sonar mounts and velocity limits)"),
        "radius": Param(float, 0.36, "obstacle inflation of the plans", unit="m", min=0.05),
        "tight_radius": Param(float, 0.2, "inflation of the plans through doors that "
                                          "'radius' closes; under the body's half-width, as "
                                          "a sonar map draws doors narrow (0: never)",
                              unit="m", min=0.0),
        "door_narrow": Param(float, 0.45, "a way nearer than this to walls on both sides "
                                          "passes a doorway: the robot lines up on its axis "
                                          "in front of it and drives through straight "
                                          "(0: never)", unit="m", min=0.0),
        "door_underfoot": Param(bool, False, "a way planned from inside a doorway turns "
                                             "square to it first, and a doorway's jambs must "
                                             "straddle the way (false: a way's first 0.35 m "
                                             "is not looked at for doorways; "
                                             "docs/exploration.md has the measured trade)"),
        "ease_by_ends": Param(bool, False, "too close to something to turn, move straight "
                                           "out by the end of the body farther from the "
                                           "echoes, ahead on a tie (false: by the nearest "
                                           "echo, and a pinned robot backs; docs/"
                                           "exploration.md)"),
        "cruise": Param(float, 0.45, "speed on the way to a frontier", unit="m/s", min=0.01),
        "min_frontier": Param(float, 0.8, "ignore frontiers shorter than this", unit="m",
                              min=0.0),
        "reach": Param(float, 1.0, "a frontier's goal is at most this far from it", unit="m",
                       min=0.1),
        "gain_weight": Param(float, 1.0, "metres of travel one metre of frontier is worth",
                             min=0.0),
        "goal_distance": Param(str, "straight", "a goal's distance: the straight line from "
                                                "the robot, or the way there over the "
                                                "planning grid (docs/exploration.md)",
                               choices=("straight", "path")),
        "seen_radius": Param(float, 0.0, "a goal reached with its frontier still there looked "
                                         "at the frontier this far; the rest of a longer one "
                                         "is approached again, from goals that see it (0: the "
                                         "whole frontier goes with its goal; "
                                         "docs/exploration.md has the measured trade)",
                             unit="m", min=0.0),
        "end_seen_radius": Param(float, 3.0, "seen_radius from when no other frontier is "
                                             "left, before the floor counts as explored: "
                                             "a long frontier dropped with the goal at its "
                                             "middle is looked at along its length (0: "
                                             "never)", unit="m", min=0.0),
        "stop_distance": Param(float, 0.3, "an echo this close in front of the body (or "
                                           "behind it when backing) fails the way", unit="m",
                               min=0.0),
        "wall_margin": Param(float, 0.0, "unknown cells this close to a wall make no frontier",
                             unit="m", min=0.0),
        "trail_time": Param(float, -1.0, "seconds of the robot's track kept passable on the "
                                         "plans (negative: all of it)", unit="s"),
        "stall_time": Param(float, 12.0, "a way with no progress this long fails", unit="s",
                            min=1.0),
        "max_failures": Param(int, 8, "this many failed ways in a row, all within 2 m of the "
                                      "first, and the robot is stuck", min=1),
        "hand_backs": Param(int, 3, "stuck, hand back to the follower for hand_back_distance "
                                    "and plan again from there, at most this often; stuck "
                                    "once more ends it 'stuck' (0: at once)", min=0),
        "hand_back_distance": Param(float, 8.0, "how far the follower drives after a hand-back",
                                    unit="m", min=0.0),
        "stale_distance": Param(float, 40.0, "take over once the follower drove this far "
                                             "without new floor (0: only after its loop)",
                                unit="m", min=0.0),
        "stale_gain": Param(float, 2.0, "...new floor meaning at least this much known area",
                            unit="m^2", min=0.0),
        "retry_given_up": Param(int, 0, "rounds of trying again the frontiers given up after "
                                        "failed ways, once no other is left (0: end "
                                        "'explored' without them)", min=0),
        "monitored": Param(bool, False, "a navigate.collision_monitor (default settings) stands "
                                        "between this block and the wheels: judge every "
                                        "motion as it will, and count a bumper that stays "
                                        "pressed as one bump"),
        **MONITORED_ECHO_PARAMS,
    }
    category = "explore"

    def setup(self) -> None:
        from blocks.navigate.pursuit import PursuitParams

        from .explorer import ExploreParams
        from blocks.navigate.collision_monitor import MonitorParams
        from blocks.navigate.guard import SonarGuard
        spec = _robot_spec(self.p.robot)
        self._guard = SonarGuard.for_robot(spec, ahead=self.p.stop_distance)
        self._bumpers = list(spec.bumpers)
        limits = spec.limits
        self._pursuit = PursuitParams(cruise=min(self.p.cruise, limits.max_speed),
                                      max_speed=limits.max_speed,
                                      max_turn_rate=limits.max_turn_rate,
                                      lookahead=0.5, lookahead_min=0.25, goal_tolerance=0.15)
        self._params = ExploreParams(radius=self.p.radius, tight_radius=self.p.tight_radius,
                                     door_narrow=self.p.door_narrow,
                                     door_underfoot=self.p.door_underfoot,
                                     ease_by_ends=self.p.ease_by_ends,
                                     seen_radius=self.p.seen_radius,
                                     end_seen_radius=self.p.end_seen_radius,
                                     min_frontier=self.p.min_frontier,
                                     reach=self.p.reach, gain_weight=self.p.gain_weight,
                                     goal_distance=self.p.goal_distance,
                                     stall_time=self.p.stall_time,
                                     max_failures=self.p.max_failures,
                                     hand_backs=self.p.hand_backs,
                                     hand_back_distance=self.p.hand_back_distance,
                                     stale_distance=self.p.stale_distance,
                                     stale_gain=self.p.stale_gain,
                                     wall_margin=self.p.wall_margin,
                                     retry_given_up=self.p.retry_given_up,
                                     monitor=(MonitorParams(min_range=spec.sonar.min_range,
                                                            triangulate=self.p.triangulate,
                                                            memory=self.p.echo_memory,
                                                            near_memory=self.p.near_echo_memory)
                                              if self.p.monitored else None),
                                     trail_time=(math.inf if self.p.trail_time < 0
                                                 else self.p.trail_time))

    def reset(self) -> None:
        from .explorer import FrontierExplorer
        self._map: Any = None
        self._echoes: Any = None
        self.explorer = FrontierExplorer(self._snapshot, self._guard, self._params,
                                         self._pursuit, bumpers=self._bumpers)

    def _snapshot(self) -> Any:
        snapshot = getattr(self._map, "snapshot", None)
        if snapshot is None:
            raise BlockError("the 'map' input has no snapshot(): it is not a map handle",
                             node=self.name, field="input 'map'",
                             hint="Connect a map block's 'map' output, e.g. "
                                  "maps.logodds_map's.")
        return snapshot()

    def step(self, pose: np.ndarray, ranges: np.ndarray, map: Any,  # noqa: A002
             v_in: float, w_in: float, follower_done: bool = False, hold: bool = False,
             preempted: bool = False, bumpers: np.ndarray | None = None,
             odometry: np.ndarray | None = None,
             monitor_scale: float = 1.0, echoes: Any = None) -> dict[str, Any]:
        if not self.p.enabled:
            return {"v": float(v_in), "w": float(w_in), "exploring": False,
                    "done": bool(follower_done)}
        if echoes is not None and echoes is not self._echoes:
            self._echoes = echoes
            self.explorer.share_echoes(echo_memory_input(echoes, self.name))
        self._map = map
        if bumpers is not None and len(bumpers) != len(self._bumpers):
            raise BlockError(f"{len(bumpers)} bumpers on the 'bumpers' input, but the robot "
                             f"file '{self.p.robot}' has {len(self._bumpers)}",
                             node=self.name, field="input 'bumpers'",
                             hint="Connect sim2d.bumpers of the same robot model.")
        command = self.explorer.step(self.ctx.time, pose, np.asarray(ranges),
                                     follower_done=bool(follower_done), hold=bool(hold),
                                     preempted=bool(preempted), bumpers=bumpers,
                                     follower_v=float(v_in), follower_w=float(w_in),
                                     odometry=odometry,
                                     monitor_scale=float(monitor_scale))
        done = self.explorer.ended
        if command is None:
            if done:
                return {"v": 0.0, "w": 0.0, "exploring": False, "done": True}
            return {"v": float(v_in), "w": float(w_in), "exploring": False, "done": False}
        return {"v": command[0], "w": command[1], "exploring": True, "done": False}

    def finish(self) -> None:
        if not self.p.enabled:
            self.report("end_reason", "perimeter only")
            return
        if hasattr(self, "explorer"):
            summary = self.explorer.summary(self.ctx.time)
            for key, value in summary.items():
                self.report(key, value)
            self.report("explored", summary["end_reason"] == "explored")
            self.report("stuck", summary["end_reason"] == "stuck")
