"""sim2d blocks: the world (physics), drive, sonar, odometry, true pose and PTZ camera.

The ``sim2d.world`` node owns the simulation and outputs it as a handle;
every robot-side block takes that handle, which orders it after the physics
step. A drive command given at tick t moves the robot during tick t+1, like a
real robot's one-cycle actuation latency.
"""
from __future__ import annotations

import csv
import io
import math
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from blocks.core import Block, BlockError, Param, Port, block
from blocks.core.atomic import atomic_write_text

from .robot import load_robot
from .simulation import Simulation
from .world import World, load_world

POSE_UNIT = "m,m,rad"
SIM = Port(kind="handle", doc="the simulation (from a sim2d.world node)")


def resolve_world(name_or_path: str) -> Path:
    """A world library name (``office``), a path to a world YAML, or a generated building
    (``gen:KIND:SEED``, see :mod:`sim2d.worlds.family`)."""
    if str(name_or_path).startswith("gen:"):
        from .worlds.family import generated_world
        return generated_world(str(name_or_path))
    path = Path(name_or_path)
    if path.suffix in (".yaml", ".yml") or path.exists():
        return path
    from .worlds import world_path
    return world_path(name_or_path)


@block("sim2d.world", category="sim2d")
class WorldBlock(Block):
    """Owns the simulated world and its robots; steps the physics every tick.

    Writes ``trajectory.csv`` (tick, time, robot, true pose, odometry pose) and
    reports the number of collisions to run.json.
    """

    outputs = {"sim": Port(kind="handle", doc="the simulation, for the robot-side blocks"),
               "time": Port.scalar("float64", unit="s", doc="simulated time")}
    params = {
        "world": Param(str, "office", "world library name or world YAML path", role="world"),
        "robots": Param(list, [{"name": "robot", "model": "atrv_mini"}],
                        "robots: [{name, model, start: [x, y, theta]}]; start defaults to "
                        "the world's starts in order"),
        "trajectory": Param(bool, True, "write trajectory.csv"),
        "path_png": Param(bool, False, "draw the paths over the world into path.png at the end"),
        "specular": Param(str, "robot", "specular sonar loss: as the robot file says, or forced "
                          "on or off for every robot", choices=("robot", "on", "off")),
    }

    def setup(self) -> None:
        self.world: World = load_world(resolve_world(self.p.world))
        self._robots = self._robot_list()

    def _robot_list(self) -> list[tuple[str, Any, tuple[float, float, float]]]:
        robots = []
        for i, entry in enumerate(self.p.robots):
            if not isinstance(entry, dict) or not isinstance(entry.get("name", "robot"), str):
                raise BlockError(f"robots[{i}] must be a mapping {{name, model, start}}",
                                 node=self.name, field="param 'robots'")
            name = entry.get("name", f"robot{i}")
            spec = load_robot(entry.get("model", "atrv_mini"))
            if self.p.specular != "robot":
                spec = replace(spec, sonar=replace(spec.sonar, specular=self.p.specular == "on"))
            start = entry.get("start")
            if start is None:
                if len(self.world.starts) > i:
                    start = self.world.starts[i]
                else:  # more robots than start poses: line them up behind the first
                    x, y, th = self.world.starts[0]
                    back = 0.8 * i
                    start = (x - back * math.cos(th), y - back * math.sin(th), th)
            if not (isinstance(start, (list, tuple)) and len(start) == 3):
                raise BlockError(f"robots[{i}].start must be [x, y, theta]", node=self.name,
                                 field="param 'robots'")
            robots.append((name, spec, tuple(float(v) for v in start)))
        names = [r[0] for r in robots]
        if len(set(names)) != len(names):
            raise BlockError(f"robot names must be unique, got {names}", node=self.name,
                             field="param 'robots'")
        return robots

    def reset(self) -> None:
        seed = int(self.rng.integers(2**63))
        self.sim = Simulation(self.world, self._robots, seed=seed)
        self._rows: list[tuple] = []

    def step(self) -> dict[str, Any]:
        if self.ctx.tick > 0:
            self.sim.step(self.ctx.dt)
        if self.p.trajectory:
            for robot in self.sim.robots.values():
                pose, odom = robot.pose, robot.odom
                self._rows.append((self.ctx.tick, self.ctx.tick * self.ctx.dt, robot.name,
                                   *pose, *odom, *robot.velocity))
        return {"sim": self.sim, "time": self.sim.time}

    def finish(self) -> None:
        if not hasattr(self, "sim"):
            return
        collisions = {r.name: r.collisions for r in self.sim.robots.values()}
        self.report("collisions", sum(collisions.values()))
        self.report("collisions_by_robot", collisions)
        # where and when, for telling which behaviour drove into what (scoring only)
        self.report("collision_log", [
            {"robot": r.name, "t": round(t, 2), "at": [round(x, 2), round(y, 2)],
             "contact": [round(cx, 2), round(cy, 2)]}
            for r in self.sim.robots.values() for t, x, y, cx, cy in r.collision_log])
        self.report("world", self.world.source or self.world.name)
        self.report("robots", [{"name": name, "model": spec.name, "length": spec.length,
                                "width": spec.width} for name, spec, _ in self._robots])
        if self.ctx.out_dir is None or not self.p.trajectory:
            return
        text = io.StringIO()
        writer = csv.writer(text)
        writer.writerow(["tick", "time", "robot", "x", "y", "theta", "odom_x", "odom_y",
                         "odom_theta", "v", "w"])
        for row in self._rows:
            writer.writerow([row[0], f"{row[1]:.6f}", row[2],
                             *(f"{v:.6f}" for v in row[3:])])
        atomic_write_text(self.output_path("trajectory.csv"), text.getvalue())
        self._write_sonar_log()
        if self.p.path_png:
            from .render import draw_run, record_from_simulation
            record = record_from_simulation(self.sim, self._rows, self.ctx.dt,
                                            Path(self.ctx.out_dir))
            draw_run(record, self.output_path("path.png"))

    def _write_sonar_log(self) -> None:
        """sonar.npz: per robot NAME@tick, NAME@ranges, NAME@echo, plus the sensor mounts."""
        from blocks.core.npzio import save_npz
        arrays: dict[str, np.ndarray] = {}
        for robot in self.sim.robots.values():
            if not robot.sonar_log:
                continue
            ticks, ranges, echo = zip(*robot.sonar_log)
            arrays[f"{robot.name}@tick"] = np.asarray(ticks, dtype=np.int64)
            arrays[f"{robot.name}@ranges"] = np.asarray(ranges)
            arrays[f"{robot.name}@echo"] = np.asarray(echo)
            arrays[f"{robot.name}@mounts"] = robot.spec.sonar_mounts
            arrays[f"{robot.name}@cone_deg"] = np.asarray(robot.spec.sonar.cone_deg)
            arrays[f"{robot.name}@max_range"] = np.asarray(robot.spec.sonar.max_range)
        if arrays:
            save_npz(self.output_path("sonar.npz"), arrays)


class _RobotBlock(Block):
    """Common to blocks that act for one named robot."""

    category = "sim2d"
    _next_time = 0.0

    def _due(self, rate_hz: float) -> bool:
        """Is a new reading due at this tick, for a sensor running at ``rate_hz``?"""
        now = self.ctx.tick * self.ctx.dt
        if rate_hz > 0 and now + 1e-9 < self._next_time:
            return False
        self._next_time = now + (1.0 / rate_hz if rate_hz > 0 else 0.0)
        return True

    def _robot(self, sim: Simulation):
        if sim is None:
            raise BlockError("no simulation on the 'sim' input", node=self.name)
        try:
            return sim.robots[self.p.robot]
        except KeyError:
            raise BlockError(f"the world has no robot named '{self.p.robot}'", node=self.name,
                             field="param 'robot'",
                             hint=f"Robots: {', '.join(sim.robots)}.") from None


ROBOT = Param(str, "robot", "name of the robot (see the world node's robots)")


@block("sim2d.drive", category="sim2d")
class Drive(_RobotBlock):
    """Sends translation and rotation velocity commands to a robot (clipped to its limits)."""

    inputs = {"sim": SIM,
              "v": Port.scalar("float64", unit="m/s", doc="translation velocity command"),
              "w": Port.scalar("float64", unit="rad/s", doc="rotation velocity command (CCW +)")}
    outputs = {"v_cmd": Port.scalar("float64", unit="m/s", doc="command after limits"),
               "w_cmd": Port.scalar("float64", unit="rad/s", doc="command after limits")}
    params = {"robot": ROBOT}

    def step(self, sim: Simulation, v: float, w: float) -> dict[str, Any]:
        robot = self._robot(sim)
        sim.command(robot.name, float(v if v is not None else 0.0),
                    float(w if w is not None else 0.0))
        return {"v_cmd": robot.command[0], "w_cmd": robot.command[1]}


@block("sim2d.sonar", category="sim2d")
class Sonar(_RobotBlock):
    """The robot's sonar ring: ranges, and which readings are real echoes.

    A reading with no echo (nothing within range, or lost to specular
    reflection) is ``max_range`` with ``echo`` false. It reads at the sonar
    rate and holds its outputs in between; ``fresh`` fires on new readings.
    """

    inputs = {"sim": SIM}
    outputs = {
        "ranges": Port.array("float64", (16,), unit="m", frame="robot",
                             doc="range per sensor, in the robot file's order"),
        "echo": Port.array("bool", (16,), frame="robot", doc="true where a real echo came back"),
        "fresh": Port.event(doc="true on ticks with a new reading"),
    }
    params = {"robot": ROBOT,
              "rate_hz": Param(float, 0.0, "readings per second; 0 uses the robot's sonar rate",
                               min=0.0)}

    def reset(self) -> None:
        self._next_time = 0.0

    def step(self, sim: Simulation) -> dict[str, Any]:
        robot = self._robot(sim)
        if not self._due(self.p.rate_hz or robot.spec.sonar.rate_hz):
            return {"fresh": False}
        ranges, echo = sim.sonar(robot.name)
        return {"ranges": ranges, "echo": echo, "fresh": True}


@block("sim2d.bumpers", category="sim2d")
class Bumpers(_RobotBlock):
    """The robot's contact switches (the robot file's ``bumpers``): which are pressed now.

    A real robot's last line of defence, and how it knows it is jammed
    against something its sonars cannot hear (a wall's end seen edge on).
    ``any`` is true while one is pressed.
    """

    inputs = {"sim": SIM}
    outputs = {"pressed": Port.array("bool", (None,), frame="robot",
                                     doc="per bumper, in the robot file's order"),
               "any": Port.scalar("bool", doc="true while any bumper is pressed")}
    params = {"robot": ROBOT}

    def step(self, sim: Simulation) -> dict[str, Any]:
        pressed = sim.bumpers(self._robot(sim).name)
        return {"pressed": pressed, "any": bool(pressed.any())}


@block("sim2d.odometry", category="sim2d")
class Odometry(_RobotBlock):
    """Dead-reckoned pose (x, y, theta), starting at the true start pose, drifting with motion."""

    inputs = {"sim": SIM}
    outputs = {"pose": Port.array("float64", (3,), unit=POSE_UNIT, frame="odom",
                                  doc="x, y, theta by odometry")}
    params = {"robot": ROBOT}

    def step(self, sim: Simulation) -> dict[str, Any]:
        return {"pose": self._robot(sim).odom.copy()}


@block("sim2d.true_pose", category="sim2d")
class TruePose(_RobotBlock):
    """Ground-truth pose (x, y, theta) in the world frame: for scoring, not for control."""

    inputs = {"sim": SIM}
    outputs = {"pose": Port.array("float64", (3,), unit=POSE_UNIT, frame="world",
                                  doc="true x, y, theta")}
    params = {"robot": ROBOT}

    def step(self, sim: Simulation) -> dict[str, Any]:
        return {"pose": self._robot(sim).pose}


CAMERA_DYNAMICS = ("pan_rate_deg", "zoom_rate", "rate_hz")


def camera_spec_of(robot_spec: Any):
    """The robot's CameraSpec and head dynamics (pan rate, zoom rate, frame rate)."""
    from .camera import CameraSpec
    section = dict(robot_spec.camera)
    dynamics = {key: float(section.pop(key)) for key in CAMERA_DYNAMICS if key in section}
    spec = CameraSpec.from_dict(section, file=robot_spec.source)
    return spec, {"pan_rate_deg": 90.0, "zoom_rate": 4.0, "rate_hz": 5.0, **dynamics}


@block("sim2d.camera", category="sim2d")
class Camera(_RobotBlock):
    """The robot's PTZ camera: a rendered view of walls, door openings and sign plates.

    Pan, tilt and zoom follow their commands at the head's slew rates (from the
    robot file); the field of view narrows with zoom. Frames come at the camera
    rate; ``fresh`` fires on each. ``visible`` lists the plates in view with
    their true bearing and distance: ground truth for scoring, not for control.
    """

    inputs = {
        "sim": SIM,
        "pan": Port.scalar("float64", unit="rad", required=False, default=0.0,
                           doc="pan command (CCW +, relative to the robot's heading)"),
        "tilt": Port.scalar("float64", unit="rad", required=False, default=0.0,
                            doc="tilt command (up +)"),
        "zoom": Port.scalar("float64", required=False, default=1.0,
                            doc="zoom command (focal length factor)"),
    }
    outputs = {
        "image": Port(kind="image", dtype="uint8", shape=("H", "W", 3), frame="camera",
                      doc="BGR frame"),
        "pan": Port.scalar("float64", unit="rad", doc="current pan"),
        "tilt": Port.scalar("float64", unit="rad", doc="current tilt"),
        "zoom": Port.scalar("float64", doc="current zoom"),
        "pose": Port.array("float64", (3,), unit=POSE_UNIT, frame="world",
                           doc="camera x, y and viewing direction"),
        "fresh": Port.event(doc="true on ticks with a new frame"),
        "visible": Port.message(doc="ground truth: plates in view (text, bearing, distance, "
                                    "viewing angle, bbox)"),
        "objects_visible": Port.message(doc="ground truth: world objects in view (label, "
                                            "bearing, distance, bbox)"),
    }
    params = {"robot": ROBOT,
              "rate_hz": Param(float, 0.0, "frames per second; 0 uses the robot's camera rate",
                               min=0.0)}

    def setup(self) -> None:
        from .noise import NoiseAhead
        # the frames' noise, drawn a frame ahead on a thread; it outlives reset, like self.rng
        self._noise = NoiseAhead(self.rng)

    def reset(self) -> None:
        self._spec = None
        self._renderer = None  # CameraRenderer of the world being drawn
        self._next_time = 0.0
        self._head = [0.0, 0.0, 1.0]  # pan, tilt, zoom

    def _slew(self, pan: float, tilt: float, zoom: float) -> None:
        from .camera import clamp_ptz
        pan, tilt, zoom = clamp_ptz(self._spec, pan, tilt, zoom)
        dt = self.ctx.dt
        turn = math.radians(self._dyn["pan_rate_deg"]) * dt
        self._head[0] += max(-turn, min(turn, pan - self._head[0]))
        self._head[1] += max(-turn, min(turn, tilt - self._head[1]))
        self._head[2] += max(-self._dyn["zoom_rate"] * dt,
                             min(self._dyn["zoom_rate"] * dt, zoom - self._head[2]))

    def step(self, sim: Simulation, pan: float = 0.0, tilt: float = 0.0,
             zoom: float = 1.0) -> dict[str, Any]:
        from .camera import CameraRenderer, camera_pose
        robot = self._robot(sim)
        if self._spec is None:
            self._spec, self._dyn = camera_spec_of(robot.spec)
        self._slew(float(pan if pan is not None else 0.0), float(tilt if tilt is not None else 0.0),
                   float(zoom if zoom is not None else 1.0))
        head = {"pan": self._head[0], "tilt": self._head[1], "zoom": self._head[2]}
        if not self._due(self.p.rate_hz or self._dyn["rate_hz"]):
            return {**head, "fresh": False}
        cam = camera_pose(robot.pose, self._spec, self._head[0])
        if self._renderer is None or self._renderer.world is not sim.world:
            self._renderer = CameraRenderer(sim.world, self._spec)
        frame = self._renderer.frame(cam, self._head[1], self._head[2], self._noise)
        return {**head, "image": frame.image, "pose": np.asarray(cam, dtype=np.float64),
                "fresh": True, "visible": frame.signs, "objects_visible": frame.objects}


def right_wall_distance(segments: np.ndarray, pose: np.ndarray, reach: float = 4.0) -> float:
    """Distance (m) from the robot's centre to the nearest wall straight to its right; inf if none."""
    from .sonar import cone_ranges, segments_near
    near = segments_near(segments, pose[0], pose[1], reach)
    ranges, _ = cone_ranges(np.array([[pose[0], pose[1], pose[2] - math.pi / 2]]), near,
                            math.radians(1.0), reach)
    return float(ranges[0])


@block("sim2d.right_wall", category="sim2d")
class RightWall(_RobotBlock):
    """Ground truth for scoring: the true distance from the robot's centre to the wall on its right."""

    inputs = {"sim": SIM}
    outputs = {"distance": Port.scalar("float64", unit="m",
                                       doc="distance to the right wall; inf if none within 4 m")}
    params = {"robot": ROBOT}

    def step(self, sim: Simulation) -> dict[str, Any]:
        robot = self._robot(sim)
        return {"distance": right_wall_distance(sim.world.segments, robot.pose)}
