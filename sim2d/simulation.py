"""The physics: walls and skid-steer robots in a pymunk space, with odometry and sonars.

Each robot is a dynamic box dragged by a kinematic "control body" through a
pivot joint (translation) and a gear joint (rotation), as in Chipmunk's tank
demo. The control body carries the commanded velocity; the joints have finite
force, so walls win: pymunk resolves every contact and the robot stops at the
wall instead of being teleported through it. Physics runs in substeps of at
most 10 ms, so at the top speed of 1 m/s a robot moves 1 cm per substep,
far less than any wall's thickness.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import pymunk

from .robot import RobotSpec
from .sonar import segments_near, sensor_poses, sonar_readings
from .world import World

WALL, ROBOT = 1, 2
MAX_SUBSTEP = 0.005  # s: at 1 m/s, 5 mm per substep; impacts overlap walls by <= 3 mm
MIN_BEARING_STEP = 0.01  # m: a shorter odometry step is a rotation (amcl's threshold)
COLLISION_DEBOUNCE = 0.25  # s without contact before a new contact counts as a new collision


def wrap_angle(a: float) -> float:
    """An angle in [-pi, pi)."""
    return (a + math.pi) % (2 * math.pi) - math.pi


def approach(current: float, target: float, max_step: float) -> float:
    """Move ``current`` toward ``target`` by at most ``max_step`` (acceleration limit)."""
    return current + max(-max_step, min(max_step, target - current))


@dataclass
class RobotState:
    """One robot in the simulation."""

    name: str
    spec: RobotSpec
    body: pymunk.Body
    control: pymunk.Body
    shape: pymunk.Poly
    command: tuple[float, float] = (0.0, 0.0)  # requested (v, w), clipped to limits
    velocity: tuple[float, float] = (0.0, 0.0)  # after acceleration limits
    odom: np.ndarray = field(default_factory=lambda: np.zeros(3))
    last_true: np.ndarray = field(default_factory=lambda: np.zeros(3))
    collisions: int = 0
    collision_log: list = field(default_factory=list)  # (time, x, y, contact x, contact y)
    in_contact: int = 0
    last_contact_time: float = -1e9
    rng_odom: np.random.Generator | None = None
    rng_sonar: np.random.Generator | None = None
    sonar_ranges: np.ndarray | None = None
    sonar_echo: np.ndarray | None = None
    sonar_log: list = field(default_factory=list)  # (tick, ranges, echo) per reading

    @property
    def pose(self) -> np.ndarray:
        """Ground-truth pose (x, y, theta) in the world frame."""
        p = self.body.position
        return np.array([p.x, p.y, wrap_angle(self.body.angle)])


class Simulation:
    """A world with robots in it, stepped in lockstep with the dataflow clock."""

    def __init__(self, world: World, robots: list[tuple[str, RobotSpec, tuple[float, float, float]]],
                 *, seed: int = 0) -> None:
        self.world = world
        self.space = pymunk.Space()
        self.space.iterations = 20
        self.space.collision_slop = 0.0005  # m of allowed overlap: effectively none
        self.time = 0.0
        self.physics_time = 0.0
        self.ticks = 0
        self._add_walls()
        self.robots: dict[str, RobotState] = {}
        self._edges_tick = -1
        self._edges: tuple = ()
        seeds = np.random.SeedSequence(seed).spawn(2 * max(1, len(robots)))
        for i, (name, spec, start) in enumerate(robots):
            self._add_robot(name, spec, start, seeds[2 * i], seeds[2 * i + 1])
        self.space.on_collision(ROBOT, WALL, begin=self._contact_begin, separate=self._contact_end)
        self.space.on_collision(ROBOT, ROBOT, begin=self._contact_begin,
                                separate=self._contact_end)

    # ---- building ---------------------------------------------------------------------
    def _add_walls(self) -> None:
        body = self.space.static_body
        shapes = []
        for x1, y1, x2, y2, r in self.world.segments:
            shape = pymunk.Segment(body, (x1, y1), (x2, y2), r)
            shape.collision_type = WALL
            shape.friction = 0.6
            shapes.append(shape)
        self.space.add(*shapes)

    def _add_robot(self, name: str, spec: RobotSpec, start: tuple[float, float, float],
                   odom_seed: np.random.SeedSequence, sonar_seed: np.random.SeedSequence) -> None:
        if name in self.robots:
            raise ValueError(f"two robots are named '{name}'")
        size = (spec.length, spec.width)
        body = pymunk.Body(spec.mass, pymunk.moment_for_box(spec.mass, size))
        body.position = start[:2]
        body.angle = start[2]
        shape = pymunk.Poly.create_box(body, size)
        shape.collision_type = ROBOT
        shape.friction = 0.6
        control = pymunk.Body(body_type=pymunk.Body.KINEMATIC)
        control.position = body.position
        control.angle = body.angle
        pivot = pymunk.PivotJoint(control, body, (0, 0), (0, 0))
        pivot.max_bias = 0  # match velocities, never yank the robot to a position
        pivot.max_force = 40.0 * spec.mass  # drive force: walls (infinite force) win
        gear = pymunk.GearJoint(control, body, 0.0, 1.0)
        gear.error_bias = 0
        gear.max_bias = spec.limits.max_turn_rate
        gear.max_force = 40.0 * spec.mass
        self.space.add(body, shape, control, pivot, gear)
        shape.robot_name = name  # type: ignore[attr-defined]
        state = RobotState(name=name, spec=spec, body=body, control=control, shape=shape,
                           rng_odom=np.random.default_rng(odom_seed),
                           rng_sonar=np.random.default_rng(sonar_seed))
        state.odom = np.array(start, dtype=np.float64)
        state.last_true = state.pose
        self.robots[name] = state

    # ---- contacts -----------------------------------------------------------------------
    def _robots_of(self, arbiter: pymunk.Arbiter) -> list[RobotState]:
        return [self.robots[s.robot_name] for s in arbiter.shapes if hasattr(s, "robot_name")]

    def _contact_begin(self, arbiter: pymunk.Arbiter, space: pymunk.Space, data: object) -> None:
        for robot in self._robots_of(arbiter):
            if robot.in_contact == 0 and self.physics_time - robot.last_contact_time \
                    >= COLLISION_DEBOUNCE:
                robot.collisions += 1
                points = arbiter.contact_point_set.points
                at = points[0].point_a if points else robot.body.position
                robot.collision_log.append((self.physics_time, *robot.body.position, *at))
            robot.in_contact += 1
            robot.last_contact_time = self.physics_time

    def _contact_end(self, arbiter: pymunk.Arbiter, space: pymunk.Space, data: object) -> None:
        for robot in self._robots_of(arbiter):
            robot.in_contact = max(0, robot.in_contact - 1)
            robot.last_contact_time = self.physics_time

    # ---- commands and stepping -------------------------------------------------------------
    def command(self, name: str, v: float, w: float) -> None:
        """Request translation ``v`` (m/s) and rotation ``w`` (rad/s), clipped to the limits."""
        robot = self.robots[name]
        lim = robot.spec.limits
        v = 0.0 if not math.isfinite(v) else max(-lim.max_speed, min(lim.max_speed, v))
        w = 0.0 if not math.isfinite(w) else max(-lim.max_turn_rate, min(lim.max_turn_rate, w))
        robot.command = (v, w)

    def step(self, dt: float) -> None:
        """Advance the physics by ``dt`` seconds, then update odometry."""
        substeps = max(1, math.ceil(dt / MAX_SUBSTEP - 1e-9))
        h = dt / substeps
        for _ in range(substeps):
            for robot in self.robots.values():
                self._drive(robot, h)
            self.space.step(h)
            self.physics_time += h
        self.time += dt
        self.ticks += 1
        for robot in self.robots.values():
            self._odometry(robot)

    def _drive(self, robot: RobotState, h: float) -> None:
        lim = robot.spec.limits
        v = approach(robot.velocity[0], robot.command[0], lim.max_accel * h)
        w = approach(robot.velocity[1], robot.command[1], lim.max_turn_accel * h)
        robot.velocity = (v, w)
        body, control = robot.body, robot.control
        control.position = body.position  # no stored error: only velocities are imposed
        control.angle = body.angle
        c, s = math.cos(body.angle), math.sin(body.angle)
        control.velocity = (v * c, v * s)
        control.angular_velocity = w

    def _odometry(self, robot: RobotState) -> None:
        """Dead reckoning: the true motion as rot1-trans-rot2, each with noise, re-composed.

        This is the odometry motion model of Thrun, Burgard and Fox (Probabilistic
        Robotics, 5.4): with zero noise the odometry pose follows the truth exactly.
        Backward motion keeps rot1 small (a skid-steer reverses, it does not spin round).
        A step shorter than ``MIN_BEARING_STEP`` has no bearing worth the name
        (a body turning on the spot or jostled against a wall moves a fraction
        of a millimetre in any direction): it is all rot2, as in ROS ``amcl``'s
        motion model. Else the bearing, up to a quarter turn either way, would
        draw rotation noise for a rotation the wheels never made, and a robot
        jammed in a corner would see its heading wander by tenths of a radian.
        """
        true, prev = robot.pose, robot.last_true
        dx, dy = true[0] - prev[0], true[1] - prev[1]
        trans = math.hypot(dx, dy)
        if trans >= MIN_BEARING_STEP:
            rot1 = wrap_angle(math.atan2(dy, dx) - prev[2])
            if abs(rot1) > math.pi / 2:  # moving backward
                trans, rot1 = -trans, wrap_angle(rot1 + math.pi)
        else:  # along the heading, signed
            trans, rot1 = dx * math.cos(prev[2]) + dy * math.sin(prev[2]), 0.0
        rot2 = wrap_angle(true[2] - prev[2] - rot1)
        n = robot.spec.odometry
        rng = robot.rng_odom

        def noisy(value: float, std: float) -> float:
            return value + rng.normal(0.0, std) if std > 0 else value

        rot_sum = abs(rot1) + abs(rot2)
        rot1_m = noisy(rot1, n.rot_per_rot * abs(rot1) + n.rot_per_trans * abs(trans))
        trans_m = noisy(trans, n.trans_per_trans * abs(trans) + n.trans_per_rot * rot_sum)
        rot2_m = noisy(rot2, n.rot_per_rot * abs(rot2) + n.rot_per_trans * abs(trans))
        ox, oy, oth = robot.odom
        heading = oth + rot1_m
        robot.odom = np.array([ox + trans_m * math.cos(heading), oy + trans_m * math.sin(heading),
                               wrap_angle(heading + rot2_m)])
        robot.last_true = true

    # ---- sensing -------------------------------------------------------------------------
    def sonar(self, name: str) -> tuple[np.ndarray, np.ndarray]:
        """Read the robot's sonar array now: (ranges in m, echo flags)."""
        robot = self.robots[name]
        spec = robot.spec
        pose = robot.pose
        reach = spec.sonar.max_range + spec.radius
        segments = segments_near(self.world.segments, pose[0], pose[1], reach)
        others = self._other_robot_edges(robot, pose, reach)
        if len(others):
            segments = np.vstack([segments, others])
        sensors = sensor_poses(pose, spec.sonar_mounts)
        ranges, echo = sonar_readings(sensors, segments, spec.sonar, robot.rng_sonar)
        robot.sonar_ranges, robot.sonar_echo = ranges, echo
        robot.sonar_log.append((self.ticks, ranges, echo))
        return ranges, echo

    def _other_robot_edges(self, robot: RobotState, pose: np.ndarray, reach: float) -> np.ndarray:
        """Body edges (as zero-radius capsules) of the other robots within ``reach``."""
        if len(self.robots) < 2:
            return np.zeros((0, 5))
        if self._edges_tick != self.ticks:  # all robots' edges, once per physics step
            names, centres, edges = [], [], []
            for other in self.robots.values():
                corners = np.array([tuple(other.body.local_to_world(v))
                                    for v in other.shape.get_vertices()])
                nxt = np.roll(corners, -1, axis=0)
                edges.append(np.c_[corners, nxt, np.zeros(len(corners))])
                centres.append(tuple(other.body.position))
                names.append(other.name)
            self._edges = (names, np.array(centres), np.stack(edges),
                           np.array([o.spec.radius for o in self.robots.values()]))
            self._edges_tick = self.ticks
        names, centres, edges, radii = self._edges
        near = np.hypot(centres[:, 0] - pose[0], centres[:, 1] - pose[1]) <= reach + radii
        near[names.index(robot.name)] = False
        return edges[near].reshape(-1, 5)

    def bumpers(self, name: str) -> np.ndarray:
        """Which of the robot's bumpers are pressed now: something touches the body in its span.

        Each contact's normal (from the robot towards what it touches) is put
        in the robot frame; a bumper is pressed if its bearing lies within the
        bumper's span.  The normal, not the contact point: a body pressed flat
        against a wall touches it at two corners, whose bearings say nothing
        about which face is pressed.
        """
        robot = self.robots[name]
        spans = robot.spec.bumpers
        pressed = np.zeros(len(spans), dtype=bool)
        if not spans or robot.in_contact == 0:
            return pressed
        robot.shape.cache_bb()
        theta = float(robot.body.angle)
        for info in self.space.shape_query(robot.shape):
            if not info.contact_point_set.points:
                continue
            normal = info.contact_point_set.normal
            bearing = math.atan2(normal.y, normal.x) - theta
            for k, (_, start, end) in enumerate(spans):
                if (bearing - start) % (2 * math.pi) <= (end - start) % (2 * math.pi):
                    pressed[k] = True
        return pressed

    def penetration(self, name: str) -> float:
        """How deep (m) the robot overlaps anything now; 0 when it touches nothing."""
        robot = self.robots[name]
        robot.shape.cache_bb()
        depth = 0.0
        for info in self.space.shape_query(robot.shape):
            for point in info.contact_point_set.points:
                # Only overlapping shapes are reported; the sign of `distance` changed
                # between pymunk versions, its size is the depth.
                depth = max(depth, abs(point.distance))
        return depth
