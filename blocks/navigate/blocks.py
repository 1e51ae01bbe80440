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
from dataclasses import replace
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
                          doc="a map being built (snapshot() gives an OccupancyMap), or a "
                              "planner's grid (nav_grid() gives the NavGrid)")}
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
        nav_grid = getattr(handle, "nav_grid", None)
        if nav_grid is not None:  # a planner's own grid: drive the legs it planned
            grid = nav_grid()
            if self.visit is None:
                if self._pending:
                    self._make_visit(grid)
            elif self.visit.grid is not grid:
                self.visit.set_grid(grid)
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


#: The echo memory of a behaviour with a collision monitor downstream ('monitored'), when
#: its 'echoes' input is not connected: a copy of the monitor's, set alike.
MONITORED_ECHO_PARAMS = {
    "triangulate": Param(bool, False, "with 'monitored' and no 'echoes': the monitor locates "
                                      "near echoes by their closing rate (its 'triangulate')"),
    "echo_memory": Param(float, 1.0, "with 'monitored' and no 'echoes': the seconds of echoes "
                                     "the monitor remembers (its 'memory')", unit="s", min=0.0),
    "near_echo_memory": Param(float, 30.0, "with 'monitored' and no 'echoes': the seconds the "
                                           "monitor keeps echoes nearer than 0.6 m (its "
                                           "'near_memory')", unit="s", min=0.0),
}


@block("navigate.room_visits", category="navigate")
class RoomVisits(Block):
    """Visits the room behind each sign read: in through its door, a look around, and back.

    A higher-priority behaviour in front of the explorer (subsumption): while
    no visit is under way, ``v_in`` and ``w_in`` (the explorer's commands) pass
    through.  When a new sign arrives on ``signs``, its door is sought on a
    local map of the last ``window`` seconds of sonar scans (the offline
    map's reading model, odometry frame); once found, the block drives
    instead: in along the door's axis, 360 degrees, again deeper in if the
    room allows, back to where it left the explorer, facing the same way.
    ``hold`` (the sign seeker's stop) pauses it, and ``done`` holds the
    explorer's ``done_in`` back until no visit is under way or due.  See
    :mod:`blocks.navigate.rooms`.  run.json gets each room's outcome, the
    time spent and the map builds.

    It also goes back for a readable view of each plate the sign seeker
    could only see at a grazing angle (``plates``, the seeker's ``wanted``):
    to a spot in front of the plate on the same local maps, facing it, while
    ``look_at`` asks the seeker to look at it again, and back
    (:mod:`blocks.navigate.plate_views`; run.json ``plate_views``).
    """

    inputs = {"pose": Port.array("float64", (3,), unit="m,m,rad",
                                 doc="the robot's pose (odometry: the frame of the local maps)"),
              "ranges": Port.array("float64", (16,), unit="m", frame="robot",
                                   doc="sonar ranges, in the robot file's order"),
              "signs": Port(kind="handle", required=False, default=None,
                            doc="the signs read (current() gives {text, x, y, facing} dicts)"),
              "v_in": Port.scalar("float64", unit="m/s", doc="the explorer's translation"),
              "w_in": Port.scalar("float64", unit="rad/s", doc="the explorer's rotation"),
              "hold": Port.scalar("bool", required=False, default=False,
                                  doc="pause (e.g. the sign seeker's stop)"),
              "done_in": Port.scalar("bool", required=False, default=False,
                                     doc="the explorer is done (e.g. its loop closed)"),
              "plates": Port.message(required=False, default=None,
                                     doc="plates worth a better view (signs.seek's wanted: "
                                         "[{key, x, y, facing, top}])"),
              "monitor_scale": Port.scalar("float64", required=False, default=1.0,
                                           doc="how much of the last command the collision "
                                               "monitor let through (its 'scale', with a "
                                               "delay of 1; with 'monitored')"),
              "echoes": Port(kind="handle", required=False, default=None,
                             doc="with 'monitored': the monitor's navigate.echo_memory, to "
                                 "judge motions on (unconnected: a copy of its own)")}
    outputs = {"v": Port.scalar("float64", unit="m/s", doc="translation velocity"),
               "w": Port.scalar("float64", unit="rad/s", doc="rotation velocity (CCW +)"),
               "visiting": Port.scalar("bool", doc="true while a visit or a plate view drives "
                                                   "the robot"),
               "look_at": Port.message(doc="the wanted plate the robot now stands in front of "
                                           "(to signs.seek's look_again), or None"),
               "done": Port.scalar("bool", doc="done_in, held back while a visit is under way "
                                               "or a read sign's door is still sought")}
    params = {
        "enabled": Param(bool, True, "visit rooms; false passes the explorer's commands through"),
        "robot": Param(str, "atrv_mini", "robot model (sonar and velocity limits)"),
        "radius": Param(float, 0.36, "obstacle inflation of the A* legs (the door is crossed "
                                     "straight along its axis)", unit="m", min=0.05),
        "cruise": Param(float, 0.45, "speed on the legs", unit="m/s", min=0.01),
        "map_resolution": Param(float, 0.025, "cell size of the local maps", unit="m",
                                min=0.01, max=0.2),
        "window": Param(float, 30.0, "seconds of scans before a visit its maps include",
                        unit="s", min=1.0),
        "map_radius": Param(float, 6.0, "the local maps hold the scans taken this close to "
                                        "the sign or door", unit="m", min=1.0),
        "half_width": Param(float, 2.2, "how far along the wall from a sign its door may be",
                            unit="m", min=0.1),
        "depth_min": Param(float, 1.0, "look around at least this far behind the wall, or "
                                       "skip the room", unit="m", min=0.3),
        "depth_max": Param(float, 2.2, "...and at most this far on the first look", unit="m",
                           min=0.3),
        "looks": Param(int, 3, "at most this many looks around per room", min=1),
        "look_again": Param(float, 1.0, "a further look is at least this far from the last",
                            unit="m", min=0.1),
        "min_gain": Param(float, 1.5, "...and sees at least this much unseen floor of the room",
                          unit="m^2", min=0.0),
        "give_up_distance": Param(float, 5.0, "skip a room whose door is not found by the time "
                                              "the robot is this far from its sign", unit="m",
                                  min=0.5),
        "revisits": Param(int, 2, "a door not found is sought again when the robot passes "
                                   "within 'revisit_distance' of its sign, at most this often",
                          min=0),
        "revisit_distance": Param(float, 2.5, "see 'revisits'", unit="m", min=0.1),
        "drive_by": Param(bool, True, "a door not found while the robot is near its sign is "
                                   "looked for from close by: a drive along the sign's wall"),
        "leg_timeout": Param(float, 60.0, "seconds a leg may take", unit="s", min=1.0),
        "spin_rate": Param(float, 1.2, "turn rate of the look-around", unit="rad/s", min=0.05),
        "plate_views": Param(bool, True, "go back for a readable view of the plates the seeker "
                                         "saw only at a grazing angle"),
        "monitored": Param(bool, False, "a navigate.collision_monitor stands between this block "
                                        "and the wheels: a leg it stops for 'held_time' is "
                                        "given up"),
        "held_time": Param(float, 0.8, "see 'monitored'", unit="s", min=0.1),
        **MONITORED_ECHO_PARAMS,
    }

    def setup(self) -> None:
        from sim2d.robot import load_robot

        from .rooms import RoomVisitParams
        if self.p.depth_max < self.p.depth_min:
            raise BlockError(f"depth_max ({self.p.depth_max:g}) is below depth_min "
                             f"({self.p.depth_min:g})", node=self.name, field="param 'depth_max'",
                             hint="Make depth_max at least depth_min.")
        from .collision_monitor import MonitorParams
        from .guard import SonarGuard
        spec = load_robot(self.p.robot)
        self._held_time = self.p.held_time if self.p.monitored else math.inf
        self._mounts = np.asarray(spec.sonar_mounts, dtype=np.float64)
        self._guard = SonarGuard.for_robot(spec)
        # the monitor's echoes, so a leg creeps round what it would stop rather than wait
        self._monitor = MonitorParams(min_range=spec.sonar.min_range,
                                      triangulate=self.p.triangulate,
                                      memory=self.p.echo_memory,
                                      near_memory=self.p.near_echo_memory) \
            if self.p.monitored else None
        self._cone, self._max_range = spec.sonar.cone_deg, spec.sonar.max_range
        self._pursuit = PursuitParams(cruise=min(self.p.cruise, spec.limits.max_speed),
                                      max_speed=spec.limits.max_speed,
                                      max_turn_rate=spec.limits.max_turn_rate,
                                      lookahead=0.5, lookahead_min=0.25, goal_tolerance=0.1)
        self._params = RoomVisitParams(half_width=self.p.half_width, depth_min=self.p.depth_min,
                                       depth_max=self.p.depth_max, looks=self.p.looks,
                                       look_again=self.p.look_again, min_gain=self.p.min_gain,
                                       give_up_distance=self.p.give_up_distance,
                                       revisits=self.p.revisits,
                                       revisit_distance=self.p.revisit_distance,
                                       drive_by=self.p.drive_by,
                                       window=self.p.window, radius=self.p.radius,
                                       leg_timeout=self.p.leg_timeout,
                                       spin_rate=self.p.spin_rate, held_time=self._held_time)

    def reset(self) -> None:
        from blocks.maps.local import LocalMaps
        from blocks.maps.offline import OfflineMapParams

        from .collision_monitor import EchoMemory
        from .plate_views import PlateViewer, PlateViewParams
        from .rooms import RoomVisitor
        self._maps = LocalMaps(self._mounts, cone_deg=self._cone, max_range=self._max_range,
                               params=OfflineMapParams(resolution=self.p.map_resolution,
                                                       correct_drift=False))
        self._builds: list[float] = []
        self._version: Any = None
        self._echoes = None if self._monitor is None else EchoMemory(self._guard, self._monitor)
        self._feeds_echoes = True
        self.visitor = RoomVisitor(self._map_since, self._params, self._pursuit,
                                   echoes=self._echoes)
        self.viewer = PlateViewer(self._map_since, self._guard, pursuit=self._pursuit,
                                  params=PlateViewParams(held_time=self._held_time),
                                  echoes=self._echoes)
        self._plates_seen: Any = None

    def _map_since(self, since: float, near: tuple[float, float]):
        """The offline map (no drift fix) of the scans since ``since`` (s) taken within
        ``map_radius`` of ``near``, and their positions."""
        import time

        index = self._maps.window(since, near, self.p.map_radius)
        if len(index) < 2:
            return None
        t0 = time.perf_counter()
        built = self._maps.build(index)
        self._builds.append(time.perf_counter() - t0)
        return built.map, built.poses[:, :2]

    def _take_signs(self, signs: Any) -> None:
        from .doors import SignRef
        version = getattr(signs, "version", None)
        if version is not None and version == self._version:
            return
        self._version = version
        for sign in signs.current():
            try:
                self.visitor.add_sign(SignRef.from_dict(sign), self.ctx.time)
            except (KeyError, TypeError, ValueError):
                raise BlockError(f"a sign on the 'signs' input is not {{text, x, y, facing}}: "
                                 f"{sign!r}", node=self.name, field="input 'signs'",
                                 hint="Connect signs.correlate's 'signs' output.") from None

    def _take_plates(self, plates: list) -> None:
        from .plate_views import WantedPlate
        if plates is self._plates_seen:
            return
        self._plates_seen = plates
        try:
            wanted = [WantedPlate.from_dict(p) for p in plates]
        except (KeyError, TypeError, ValueError):
            raise BlockError(f"a plate on the 'plates' input is not {{key, x, y, facing}}: "
                             f"{plates!r}", node=self.name, field="input 'plates'",
                             hint="Connect signs.seek's 'wanted' output.") from None
        self.viewer.want(wanted, self.ctx.time)

    def step(self, pose: np.ndarray, ranges: np.ndarray, v_in: float, w_in: float,
             signs: Any = None, hold: bool = False, done_in: bool = False,
             plates: list | None = None, monitor_scale: float = 1.0,
             echoes: Any = None) -> dict[str, Any]:
        if not self.p.enabled:
            return {"v": float(v_in), "w": float(w_in), "visiting": False,
                    "done": bool(done_in), "look_at": None}
        self._maps.add(self.ctx.time, pose, ranges)
        if echoes is not None and self._echoes is not None and echoes is not self._echoes:
            self._echoes = self.visitor.echoes = self.viewer.echoes = \
                echo_memory_input(echoes, self.name)
            self._feeds_echoes = False
        if self._echoes is not None and self._feeds_echoes:
            self._echoes.add(self.ctx.time, pose, ranges)
        if signs is not None:
            self._take_signs(signs)
        if plates is not None and self.p.plate_views:
            self._take_plates(plates)
        # one at a time: a plate view under way first, then a room visit, then a plate view
        command = None
        if not self.viewer.active:
            command = self.visitor.step(self.ctx.time, pose, hold=bool(hold),
                                        scale=float(monitor_scale))
        if command is None and not self.visitor.visiting:
            known = [] if signs is None or not (self.viewer.active or self.viewer.queue) \
                else [(float(s["x"]), float(s["y"])) for s in signs.current()]
            command = self.viewer.step(self.ctx.time, pose, ranges, hold=bool(hold),
                                       signs=known, scale=float(monitor_scale))
        look_at = None if self.viewer.look_at is None else {"key": self.viewer.look_at.key}
        busy = self.visitor.visiting or self.viewer.active
        done = bool(done_in) and not busy and not self.visitor.pending \
            and not self.viewer.queue
        if command is None:
            return {"v": float(v_in), "w": float(w_in), "visiting": False, "done": done,
                    "look_at": look_at}
        return {"v": command[0], "w": command[1], "visiting": True, "done": done,
                "look_at": look_at}

    def finish(self) -> None:
        if not self.p.enabled:
            return
        for key, value in self.visitor.summary().items():
            self.report(key, value)
        if self.p.plate_views:
            self.report("plate_views", self.viewer.summary())
        self.report("map_builds", len(self._builds))
        if self._builds:
            self.report("map_build_ms_mean", round(1000 * float(np.mean(self._builds)), 1))


def echo_memory_input(value: Any, node: str) -> Any:
    """The EchoMemory on an 'echoes' input, or a BlockError saying what to connect."""
    from .collision_monitor import EchoMemory
    if not isinstance(value, EchoMemory):
        raise BlockError(f"the 'echoes' input is a {type(value).__name__}, not an echo memory",
                         node=node, field="input 'echoes'",
                         hint="Connect navigate.echo_memory's 'echoes' output.")
    return value


#: The parameters of an echo memory: navigate.echo_memory's, and navigate.collision_monitor's
#: own when it keeps one.
ECHO_MEMORY_PARAMS = {
        "memory": Param(float, 1.0, "echoes this recent count, carried along by odometry",
                        unit="s", min=0.0),
        "near_memory": Param(float, 30.0, "echoes nearer than near_range count this long: the "
                                          "wall beside the robot when its sonars, flush "
                                          "with it, no longer range it", unit="s", min=0.0),
        "near_range": Param(float, 0.6, "see near_memory", unit="m", min=0.0),
        "triangulate": Param(bool, False, "also locate near echoes by how fast their ranges "
                                          "close as the robot drives "
                                          "(navigate.sonar_triangulation)"),
        "wall_extent": Param(float, 0.0, "each point of an echo's arc also stands for a wall "
                                         "through it across the beam, this long either way "
                                         "(a wall met obliquely ahead echoes only at a "
                                         "diagonal sonar's cone edge, beside the body's path); "
                                         "0: points alone", unit="m", min=0.0, max=0.5),
}


@block("navigate.echo_memory", category="navigate")
class EchoMemoryBlock(Block):
    """The sonar echoes of the last moments, carried along by odometry: one memory for the
    collision monitor and every behaviour that asks what the monitor would let through.

    Why a block: the monitor, the frontier explorer and the room visits each
    judge motions on the same echoes; fed once here, before all of them, they
    share one memory (and its arcs, computed once a tick) instead of keeping
    three copies of it.  Connect ``echoes`` to their ``echoes`` inputs; the
    memory's parameters are then this block's, and theirs of the same names
    are unused (:class:`~blocks.navigate.collision_monitor.EchoMemory`).
    """

    inputs = {"pose": Port.array("float64", (3,), unit="m,m,rad",
                                 doc="the robot's odometry pose (carries older echoes along)"),
              "ranges": Port.array("float64", (16,), unit="m", frame="robot",
                                   doc="sonar ranges, in the robot file's order"),
              "bumpers": Port.array("bool", (None,), required=False, default=None,
                                    doc="contact switches pressed now (sim2d.bumpers), in "
                                        "the robot file's order: the walls they felt are "
                                        "remembered as long as near echoes")}
    outputs = {"echoes": Port(kind="handle", doc="the echo memory, this tick's scan added: "
                                                 "for the 'echoes' inputs of "
                                                 "navigate.collision_monitor, explore.frontiers "
                                                 "and navigate.room_visits")}
    params = {
        "robot": Param(str, "atrv_mini", "robot model (body and sonar)"),
        "feel": Param(bool, True, "remember the walls the pressed bumpers felt (false: the "
                                  "'bumpers' input is ignored)"),
        **ECHO_MEMORY_PARAMS,
    }

    def setup(self) -> None:
        from sim2d.robot import load_robot

        from .collision_monitor import MonitorParams
        from .guard import SonarGuard
        spec = load_robot(self.p.robot)
        self._guard = SonarGuard.for_robot(spec)
        self._params = MonitorParams(memory=self.p.memory, near_memory=self.p.near_memory,
                                     near_range=self.p.near_range,
                                     min_range=spec.sonar.min_range,
                                     triangulate=self.p.triangulate,
                                     wall_extent=self.p.wall_extent)
        self._spans = [(start, end) for _, start, end in spec.bumpers]

    def reset(self) -> None:
        from .collision_monitor import EchoMemory
        self.memory = EchoMemory(self._guard, self._params)
        self._poses: list[tuple[float, np.ndarray]] = []

    def step(self, pose: np.ndarray, ranges: np.ndarray,
             bumpers: np.ndarray | None = None) -> dict[str, Any]:
        time, pose = self.ctx.time, np.asarray(pose, dtype=np.float64)
        self.memory.add(time, pose, ranges)
        if bumpers is not None and self.p.feel:
            if len(bumpers) != len(self._spans):
                raise BlockError(f"{len(bumpers)} bumpers on the 'bumpers' input, but the "
                                 f"robot file '{self.p.robot}' has {len(self._spans)}",
                                 node=self.name, field="input 'bumpers'",
                                 hint="Connect sim2d.bumpers of the same robot model.")
            v, w = self._motion(time, pose)
            spans = [span for span, on in zip(self._spans, bumpers) if on]
            self.memory.add_touch(time, pose, spans, v, w)
        return {"echoes": self.memory}

    def _motion(self, time: float, pose: np.ndarray, window: float = 0.3) -> tuple[float, float]:
        """The robot's motion (v, w) over the last ``window`` seconds of odometry: what
        pressed a bumper pressed now (a robot against a wall hardly moves this tick)."""
        self._poses = [(t, p) for t, p in self._poses if t >= time - window - 1e-9]
        self._poses.append((time, pose))
        t0, p0 = self._poses[0]
        if time - t0 <= 1e-9:
            return 0.0, 0.0
        dx, dy = pose[0] - p0[0], pose[1] - p0[1]
        v = (dx * math.cos(p0[2]) + dy * math.sin(p0[2])) / (time - t0)
        return v, math.remainder(pose[2] - p0[2], 2 * math.pi) / (time - t0)


@block("navigate.collision_monitor", category="navigate")
class CollisionMonitorBlock(Block):
    """The last check on every command: slows and stops the robot short of what its sonars hear.

    Whatever behaviour drives, the command is checked against the body's
    swept footprint over the next ``time_before_collision`` seconds and the
    echoes of the last ``memory`` seconds; a command that would reach one
    sooner is scaled down (translation and rotation alike, so the path is
    unchanged) until it would take that long: Nav2's collision monitor in its
    "approach" mode (:mod:`blocks.navigate.collision_monitor`).  Held still
    for a second, it backs or turns the way that is clear for a second.
    run.json gets the share of ticks it slowed and stopped the robot, and
    how often it had to get it out of a corner.
    """

    inputs = {"pose": Port.array("float64", (3,), unit="m,m,rad",
                                 doc="the robot's odometry pose (carries older echoes along)"),
              "ranges": Port.array("float64", (16,), unit="m", frame="robot",
                                   doc="sonar ranges, in the robot file's order"),
              "v_in": Port.scalar("float64", unit="m/s", doc="the translation asked for"),
              "w_in": Port.scalar("float64", unit="rad/s", doc="the rotation asked for"),
              "echoes": Port(kind="handle", required=False, default=None,
                             doc="a navigate.echo_memory's, shared with the behaviours "
                                 "(unconnected: the monitor keeps its own)")}
    outputs = {"v": Port.scalar("float64", unit="m/s", doc="translation velocity, made safe"),
               "w": Port.scalar("float64", unit="rad/s", doc="rotation velocity, made safe"),
               "scale": Port.scalar("float64", doc="how much of the command was let through "
                                                   "(1: all, 0: stopped)")}
    params = {
        "enabled": Param(bool, True, "check commands; false passes them through unchanged"),
        "robot": Param(str, "atrv_mini", "robot model (body and sonar)"),
        "time_before_collision": Param(float, 0.6, "the body may reach an echo no sooner than "
                                                   "this", unit="s", min=0.1),
        "margin": Param(float, 0.03, "the body is grown by this much for the check", unit="m",
                        min=0.0, max=0.3),
        **{name: replace(param, doc=param.doc + " (unused with 'echoes' connected: the "
                                                "memory's own)")
           for name, param in ECHO_MEMORY_PARAMS.items()},
    }

    def setup(self) -> None:
        from sim2d.robot import load_robot

        from .collision_monitor import MonitorParams
        from .guard import SonarGuard
        spec = load_robot(self.p.robot)
        self._guard = SonarGuard.for_robot(spec)
        self._params = MonitorParams(time_before_collision=self.p.time_before_collision,
                                     margin=self.p.margin, wall_extent=self.p.wall_extent,
                                     memory=self.p.memory,
                                     near_memory=self.p.near_memory,
                                     near_range=self.p.near_range,
                                     min_range=spec.sonar.min_range,
                                     triangulate=self.p.triangulate)

    def reset(self) -> None:
        from .collision_monitor import CollisionMonitor
        self.monitor = CollisionMonitor(self._guard, self._params)
        self._ticks = 0

    def step(self, pose: np.ndarray, ranges: np.ndarray, v_in: float,
             w_in: float, echoes: Any = None) -> dict[str, Any]:
        if not self.p.enabled:
            return {"v": float(v_in), "w": float(w_in), "scale": 1.0}
        if echoes is not None and self.monitor.echoes is not echoes:
            self.monitor.share_echoes(echo_memory_input(echoes, self.name))
        self._ticks += 1
        v, w = self.monitor.step(self.ctx.time, pose, ranges, float(v_in), float(w_in))
        return {"v": float(v), "w": float(w), "scale": float(self.monitor.scale)}

    def finish(self) -> None:
        if not self.p.enabled or not self._ticks:
            return
        self.report("slowed_fraction", round(self.monitor.limited_ticks / self._ticks, 4))
        self.report("stopped_fraction", round(self.monitor.stopped_ticks / self._ticks, 4))
        self.report("recoveries", self.monitor.recoveries)
