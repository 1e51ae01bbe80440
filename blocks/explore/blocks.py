"""Blocks of the two-layer fuzzy perimeter follower (thin adapters over controller.py)."""
from __future__ import annotations

from typing import Any

import numpy as np

from ..core import Block, BlockError, Param, Port, block
from ..fuzzy import compile_kb, load_kb
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
    """Fires ``done`` once the robot is back at its start after real progress.

    The paper's termination rule: having gone round the perimeter, the robot
    returns to where it began. ``min_travel`` and ``min_away`` keep the
    departure from counting.
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
                                unit="m", min=0.0)}
    category = "explore"

    def reset(self) -> None:
        self.loop = LoopClosure(self.p.radius, self.p.min_travel, self.p.min_away)

    def step(self, pose: np.ndarray) -> dict[str, Any]:
        done = self.loop.update(float(pose[0]), float(pose[1]), self.ctx.time)
        return {"done": done, "travelled": self.loop.travelled}

    def finish(self) -> None:
        if hasattr(self, "loop"):
            self.report("loop_closed", self.loop.closed_at is not None)
            self.report("loop_time_s", self.loop.closed_at)
            self.report("distance_travelled_m", round(self.loop.travelled, 3))


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
