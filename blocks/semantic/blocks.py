"""The semantic knowledge block: the paper's semantic knowledge mapping module as one node.

While the robot runs, every newly read sign and every newly seen object
updates the knowledge base, which is reasoned over again at once (the
reasoning time is reported to run.json). When the run finishes, the map is
segmented into places, the signs label the rooms behind their doors, and the
semantic map is written: ``DIR/semantic_map.ttl``, ``DIR/places.geojson`` and
``DIR/maps/semantic.png``. With ``world`` set, the places are scored against
the world's true rooms and doors, and, when the world names a commands file,
the task planner is scored on its commands on the run's own map.
"""
from __future__ import annotations

import time
from typing import Any

import numpy as np

from blocks.core import Block, Param, Port, block

WORLD = Param(str, "", "world whose true rooms score the places, and whose timetable is used "
              "when `timetable` is empty (name or YAML; empty: none)", role="world")


@block("semantic.knowledge", category="semantic")
class Knowledge(Block):
    """Semantic knowledge mapping: a reasoned knowledge base of places, signs, objects, people.

    Connect the sign correlation's ``signs`` handle, the offline map's ``map``
    handle and, optionally, the object recogniser's ``objects``. The knowledge
    base is re-reasoned whenever a sign or an object is added; at the end the
    map's places are segmented, labelled and written out with the knowledge.
    With ``world`` set, run.json gets the places' scores against its true rooms
    (``rooms_*``) and, if the world names a commands file, the task planner's
    score on those commands, asked on the map this run wrote (``commands_total``,
    ``commands_right``, ``commands_right_fraction``, ``commands_<category>_right_fraction``
    and ``commands_cases``, one row per command).
    """

    inputs = {
        "signs": Port(kind="handle", doc="the sign correlation: current() gives the signs read"),
        "map": Port(kind="handle", required=False, default=None,
                    doc="the map to segment into places (snapshot() gives an OccupancyMap)"),
        "objects": Port(kind="handle", required=False, default=None,
                        doc="the object recogniser: current() gives the objects seen so far"),
        "pose": Port.array("float64", (3,), unit="m,m,rad", required=False, default=None,
                           doc="the robot's pose (its path tells the corridor from the rooms)"),
    }
    params = {
        "ontology": Param(str, "", "ontology file in Turtle (empty: the packaged indoor.ttl)"),
        "timetable": Param(str, "", "timetable YAML (empty: the world's, if it names one)"),
        "world": WORLD,
        "door_width_max": Param(float, 1.3, "openings narrower than this separate places",
                                unit="m", min=0.2),
        "min_place_area": Param(float, 1.0, "smaller regions join their neighbour",
                                unit="m^2", min=0.0),
        "explored_coverage": Param(float, 0.5, "a room counts as explored once the map has "
                                   "seen this share of it", min=0.0, max=1.0),
        "live": Param(bool, True, "re-reason while running, as each sign or object arrives"),
    }

    def setup(self) -> None:
        from semantic.vocabulary import load_vocabulary
        self._vocabulary = load_vocabulary()
        self._timetable = self._load_timetable()
        self._commands = self._load_commands()

    def reset(self) -> None:
        self._signs: Any = None
        self._objects: Any = None
        self._map: Any = None
        self._seen = (-1, -1)
        self._owl: Any = None  # the last live base's OWL pass, handed on to the next one
        self._reason_ms: list[float] = []
        self._path: list[np.ndarray] = []

    # ---- run time ------------------------------------------------------------------------
    def step(self, signs: Any, map: Any = None, objects: Any = None,  # noqa: A002
             pose: np.ndarray | None = None) -> None:
        self._signs, self._map = signs, map if map is not None else self._map
        if objects is not None:
            self._objects = objects
        if pose is not None:
            self._path.append(np.asarray(pose[:2], dtype=np.float64))
        if not self.p.live:
            return
        version = (getattr(signs, "version", 0), getattr(objects, "version", 0))
        if version == self._seen:
            return
        self._seen = version
        sign_list, object_list = self._current()
        if not sign_list and not object_list:
            return
        from semantic.semantic_map import live_kb
        kb = live_kb(sign_list, object_list, ontology=self.p.ontology or None,
                     timetable=self._timetable, vocabulary=self._vocabulary, owl=self._owl)
        self._owl = kb.owl
        t0 = time.perf_counter()
        kb.reason()
        self._reason_ms.append((time.perf_counter() - t0) * 1e3)

    def _current(self) -> tuple[list[dict], list[dict]]:
        signs = self._signs.current() if self._signs is not None else []
        objects = self._objects.current() if self._objects is not None else []
        return list(signs), list(objects)

    # ---- the end of the run ----------------------------------------------------------------
    def finish(self) -> None:
        if self._reason_ms:
            self.report("live_updates", len(self._reason_ms))
            self.report("live_reason_ms_mean", float(np.mean(self._reason_ms)))
            self.report("live_reason_ms_max", float(np.max(self._reason_ms)))
        snapshot = getattr(self._map, "snapshot", None)
        occupancy = snapshot() if snapshot is not None else None
        if occupancy is None:
            self.report("places", 0)
            return
        from semantic.semantic_map import build_semantic_map, write_semantic_map
        signs, objects = self._current()
        path = self._corrected_path()
        sm = build_semantic_map(occupancy, signs, objects, ontology=self.p.ontology or None,
                                timetable=self._timetable, vocabulary=self._vocabulary,
                                segment_options={"door_width_max": self.p.door_width_max,
                                                 "min_place_area": self.p.min_place_area},
                                path=path)
        self.semantic_map = sm
        self.report("places", len(sm.places.places))
        self.report("doors", len(sm.places.doors))
        self.report("signed_places", len(sm.names))
        self.report("signs_without_place", sum(1 for p in sm.sign_places.values() if p is None))
        self.report("objects", len(objects))
        for key, value in sm.timings_ms.items():
            self.report(key, round(value, 2))
        if self.ctx.out_dir is not None:
            write_semantic_map(self.ctx.out_dir, sm, occupancy, signs=signs, objects=objects)
            for name in ("semantic_map.ttl", "places.geojson", "maps/semantic.png"):
                self.output_path(name)  # listed among the run's outputs
        if self.p.world:
            self._score(sm)
        if self._commands is not None and self.ctx.out_dir is not None:
            self._score_commands()

    def _corrected_path(self) -> np.ndarray | None:
        corrected = getattr(self._map, "corrected_path", None)
        if corrected is not None:
            path = corrected()
            if path is not None and len(path):
                return np.asarray(path)[:, :2]
        return np.array(self._path) if self._path else None

    def _world(self):
        if getattr(self, "_loaded_world", None) is None:
            from sim2d.blocks import resolve_world
            from sim2d.world import load_world
            self._loaded_world = load_world(resolve_world(self.p.world))
        return self._loaded_world

    def _load_timetable(self):
        from semantic.timetable import load_timetable
        if self.p.timetable:
            return load_timetable(self.p.timetable)
        if self.p.world:
            path = getattr(self._world(), "timetable", None)
            if path is not None:
                return load_timetable(path)
        return None

    def _load_commands(self):
        """The world's commands and the moment they are asked at, or None."""
        path = getattr(self._world(), "commands", None) if self.p.world else None
        if path is None:
            return None
        from semantic.query.exam import load_commands
        return load_commands(path)

    def _score(self, sm) -> None:
        from semantic.place_score import score_places
        score = score_places(sm.places, self._world(), names=sm.names,
                             explored=self.p.explored_coverage)
        for key, value in score.items():
            self.report(f"rooms_{key}" if not key.startswith("rooms") else key, value)

    def _score_commands(self) -> None:
        """The task planner on the world's commands, on the map this run wrote (the
        offline map's files are written before this node finishes)."""
        from semantic.query import MapSourceError, load_run_map
        from semantic.query.exam import score_commands
        try:
            qm = load_run_map(self.ctx.out_dir)
        except MapSourceError as exc:
            self.report("commands_error", str(exc))
            return
        score = score_commands(qm, *self._commands, world=self._world())
        for key in ("total", "right", "right_fraction"):
            self.report(f"commands_{key}", score[key])
        for name, tally in score["categories"].items():
            self.report(f"commands_{name}_right_fraction", tally["right_fraction"])
        self.report("commands_cases", score["cases"])


@block("semantic.task_planner", category="semantic")
class TaskPlanner(Block):
    """The text query planner as a node: an English command to goals for ``navigate.goto``.

    At setup the command is parsed, grounded in the map (a semantic mapping
    run's folder, or the ``world`` surveyed) and planned (see
    ``semantic.query``); a command that cannot be grounded stops the graph
    from loading with the planner's message. Every tick it offers the plan's
    ``go to`` steps as ``goals`` and its planning grid as ``grid`` (connect it
    to ``navigate.goto``'s ``map`` so the robot drives the legs planned here).
    Writes ``plan.json`` and ``plan.png`` (the plan on the map); given the
    robot's ``pose`` on the map (``maps.amcl``'s), the picture also shows the
    path driven, and run.json gets the places the robot was in, in order.
    """

    inputs = {"pose": Port.array("float64", (3,), unit="m,m,rad", required=False, default=None,
                                 doc="the robot's pose in the map frame (to record the places "
                                     "it reaches)")}
    outputs = {"goals": Port.message(doc="the plan's go-to points: [{x, y, name}]"),
               "grid": Port(kind="handle", doc="the planning grid: nav_grid() gives the "
                                                "NavGrid the legs were planned on, snapshot() "
                                                "the OccupancyMap it came from")}
    params = {
        "command": Param(str, "", "the English command (\"fetch the manager's mail\")"),
        "map": Param(str, "", "a semantic mapping run's folder (empty: the world surveyed)"),
        "world": Param(str, "", "world to survey when `map` is empty (name or YAML)",
                       role="world"),
        "now": Param(str, "monday 09:00", "the moment the command is given, for times and "
                                          "days it leaves out (\"monday 10:30\" or ISO)"),
    }

    def setup(self) -> None:
        from blocks.core import BlockError
        from semantic.query import ask, load_map, parse_now
        from blocks.core.errors import SemmapError
        if not self.p.command.strip():
            raise BlockError("no command to plan", node=self.name, field="param 'command'",
                             hint="Set it, e.g. --set plan.command=\"go to the kitchen\".")
        source = self.p.map or self.p.world
        if not source:
            raise BlockError("no map to plan on", node=self.name, field="param 'map'",
                             hint="Set `map` to a semantic mapping run's folder or `world` to "
                                  "a world.")
        try:
            self.qm = load_map(source)
            self.plan = ask(self.p.command, self.qm, now=parse_now(self.p.now))
        except SemmapError as exc:
            raise BlockError(exc.message, node=self.name, field="param 'command'",
                             hint=exc.hint) from None
        self._goals = self.plan.goals()

    def reset(self) -> None:
        self._driven: list[tuple[float, float]] = []
        self._visited: list[str] = []

    def nav_grid(self):
        """The grid the plan's legs were planned on."""
        return self.qm.grid

    def snapshot(self):
        """The occupancy map the plan was made on (map frame): what maps.amcl localises on."""
        return self.qm.occupancy

    def step(self, pose: np.ndarray | None = None) -> dict[str, Any]:
        if pose is not None:
            x, y = float(pose[0]), float(pose[1])
            self._driven.append((x, y))
            place = self.qm.place_at(x, y, hint=self._visited[-1] if self._visited else None)
            if place is not None and (not self._visited or self._visited[-1] != place):
                self._visited.append(place)
        return {"goals": self._goals, "grid": self}

    def finish(self) -> None:
        self.report("plan", self.plan.to_dict())
        self.report("places_visited", [self.qm.label(p) for p in self._visited])
        if self.ctx.out_dir is None:
            return
        from blocks.core.atomic import atomic_write_json
        from semantic.query.draw import draw_plan
        atomic_write_json(self.output_path("plan.json"), self.plan.to_dict())
        driven = np.array(self._driven) if self._driven else None
        draw_plan(self.output_path("plan.png"), self.plan, self.qm, driven=driven)
