"""Mapping blocks: thin adapters over :mod:`blocks.maps` (paper online map, its processed
form, log-odds map, offline map).

Every map block writes its map at the end of the run into ``DIR/maps/`` in
ROS map_server format (YAML + PGM, with a PNG preview) and, when it knows the
world (parameter ``world``, set by ``--world``), scores it against the ground
truth into run.json.  Connect the optional ``truth`` input to the true pose
and the scores also cover what the run could see (the ``*_visible`` keys).
"""
from __future__ import annotations

import math
from typing import Any

import numpy as np

from blocks.core import Block, BlockError, Param, Port, RunContext, block

from .logodds import InverseSonarModel, LogOddsMap, clear_ranges
from .mapio import OccupancyMap, write_map
from .pathio import write_path_csv
from .paper import LocalMapper, PaperGlobalMap, SensorMount, free_space_borders

RANGES = Port.array("float64", (16,), unit="m", frame="robot",
                    doc="sonar ranges, in the robot file's order")
POSE = Port.array("float64", (3,), unit="m,m,rad",
                  doc="x, y, theta in the map frame (odometry starts at the world's start)")
LOCAL = Port.array("uint8", (None, None), doc="local map: 2-bit levels, robot at the centre "
                                              "facing +x, rows y up")
ROBOT = Param(str, "atrv_mini", "robot model or robot YAML (sonar poses and range)")
RESOLUTION = Param(float, 0.05, "map cell size", unit="m", min=0.005, max=1.0)
WORLD = Param(str, "", "world to score the map against (name or YAML; empty: do not score)",
              role="world")
TRUTH = Port.array("float64", (3,), unit="m,m,rad", frame="world", required=False,
                   doc="true pose, only to score against what the run could see (optional)")
MAP_HANDLE = Port(kind="handle", doc="the map being built (snapshot() gives an OccupancyMap)")

def _visible(ctx: RunContext, world: Any, world_key: str, path: np.ndarray,
             robot: str) -> np.ndarray:
    """The cells the run's sonar could see (an ideal sonar on the true path), computed
    once per run for all map blocks (kept in ``ctx.shared``)."""
    from .features import sensor_poses_along
    from .visibility import sonar_visible
    key = ("sonar_visible", world_key, robot, path.shape, hash(path.tobytes()))
    if key not in ctx.shared:
        spec = _robot(robot)
        sensors = sensor_poses_along(path, spec.sonar_mounts).reshape(-1, 3)
        ctx.shared[key] = sonar_visible(world, sensors, spec.sonar.cone_deg,
                                        spec.sonar.max_range)
    return ctx.shared[key]


def _robot(model: str):
    from sim2d.robot import load_robot
    return load_robot(model)


class _MapWriter(Block):
    """Shared end-of-run work: write the map files, score them when the world is known."""

    map_name = "map"

    def occupancy_map(self) -> OccupancyMap | None:
        raise NotImplementedError

    def reset(self) -> None:
        self._truth: list[np.ndarray] = []

    def record_truth(self, truth: np.ndarray | None) -> None:
        """Keep the true path (for scoring only: the map never sees it)."""
        if truth is not None:
            self._truth.append(np.asarray(truth, dtype=np.float64)[:3].copy())

    def write_extras(self, folder: Any) -> list[Any]:
        """Files besides the map (wall polylines...); returns their paths."""
        return []

    def finish(self) -> None:
        m = self.occupancy_map()
        if m is None or self.ctx.out_dir is None:
            return
        path = self.output_path(f"maps/{self.map_name}.yaml")
        for written in write_map(path, m)[1:] + self.write_extras(path.parent):
            self.ctx.outputs.append(str(written))
        if self.p.world:
            from sim2d.blocks import resolve_world
            from sim2d.world import load_world

            from .score import score_map
            world_file = resolve_world(self.p.world)
            world = load_world(world_file)
            visible = None
            if getattr(self, "_truth", None):
                visible = _visible(self.ctx, world, str(world_file), np.array(self._truth),
                                   self.p.robot)
            for name, value in score_map(m, world, visible=visible).items():
                self.report(name, value)


@block("maps.local_map", category="maps")
class LocalMap(Block):
    """The paper's local map: the robot model plus the 16 beams clipped by their readings.

    Beams are uniform 30-degree triangles at level 01, 4 m long at 5 cm per
    pixel, pivoted at their sensor poses; the robot is a 10 x 10 pixel square
    at level 11; overlaps superpose up to 11.
    """

    inputs = {"ranges": RANGES}
    outputs = {"local": LOCAL}
    params = {"robot": ROBOT, "resolution": RESOLUTION}

    def setup(self) -> None:
        spec = _robot(self.p.robot)
        if len(spec.sonar_mounts) != 16:
            raise BlockError(f"robot {spec.name!r} has {len(spec.sonar_mounts)} sonars; the "
                             "local map expects 16", node=self.name, field="param 'robot'")
        self.mapper = LocalMapper([SensorMount(*m) for m in spec.sonar_mounts],
                                  resolution=self.p.resolution,
                                  max_range=spec.sonar.max_range)

    def step(self, ranges: np.ndarray) -> dict[str, Any]:
        return {"local": self.mapper.local_map(ranges)}


@block("maps.paper_map", category="maps")
class PaperMap(_MapWriter):
    """The paper's global online map: local maps rotated, shifted and added, saturating at 11.

    Writes ``maps/online.yaml``: free where any reading passed (levels 01-11,
    occupancy 1 - level/3), walls on the border of the free space (unknown
    cells next to free ones, as the paper's border tracing finds them), and
    unknown elsewhere.
    """

    map_name = "online"
    inputs = {"local": LOCAL, "pose": POSE, "truth": TRUTH}
    outputs = {"map": MAP_HANDLE}
    params = {"resolution": RESOLUTION, "world": WORLD, "robot": ROBOT}

    def setup(self) -> None:
        self.map = PaperGlobalMap(self.p.resolution)

    def reset(self) -> None:
        super().reset()
        self.map.clear()

    def step(self, local: np.ndarray, pose: np.ndarray,
             truth: np.ndarray | None = None) -> dict[str, Any]:
        self.map.add(local, pose)
        self.record_truth(truth)
        return {"map": self}

    def snapshot(self) -> OccupancyMap | None:
        """The map as it stands (for the processing block)."""
        levels, corner = self.map.levels()
        if levels.size == 0:
            return None
        return paper_levels_to_map(levels, corner, self.p.resolution)

    def occupancy_map(self) -> OccupancyMap | None:
        levels, (ix, iy) = self.map.levels()
        if levels.size == 0:
            return None
        self.report("updates", self.map.updates)
        self.report("tiles", self.map.grid.n_tiles)
        return paper_levels_to_map(levels, (ix, iy), self.p.resolution)


def paper_levels_to_map(levels: np.ndarray, corner: tuple[int, int],
                        resolution: float) -> OccupancyMap:
    """The 2-bit map as an occupancy map: free levels, border walls, unknown elsewhere.

    Thresholds are chosen so that map_server's trinary reading matches the
    paper: any free level (occupancy 0, 1/3 or 2/3) is free, the border is
    occupied, unknown stays unknown.
    """
    p = np.full(levels.shape, np.nan)
    free = levels > 0
    p[free] = 1.0 - levels[free] / 3.0
    p[free_space_borders(levels)] = 1.0
    origin = (corner[0] * resolution, corner[1] * resolution, 0.0)
    return OccupancyMap(p, resolution, origin, occupied_thresh=0.9, free_thresh=0.7)


@block("maps.logodds_map", category="maps")
class LogOddsMapBlock(_MapWriter):
    """A probabilistic global map: log-odds with an inverse sonar model, on tiles.

    Free inside the cone up to the reading, occupied on an arc at the reading,
    unknown beyond; a max-range reading clears but marks nothing. Writes
    ``maps/probabilistic.yaml``. Unlike the paper's map it tells walls from
    unknown space, so an explorer finds its frontiers on it.
    """

    map_name = "probabilistic"
    inputs = {"ranges": RANGES, "pose": POSE, "truth": TRUTH,
              "walls": Port(kind="handle", required=False, default=None,
                            doc="walls known so far (maps.drift_correction's): a reading "
                                "without an echo then clears up to the nearest one in its "
                                "cone, or its whole range if there is none")}
    outputs = {"map": MAP_HANDLE}
    params = {
        "robot": ROBOT, "resolution": RESOLUTION, "world": WORLD,
        "l_free": Param(float, -0.4, "log-odds added to cells a beam crossed", max=-1e-6),
        "l_occ": Param(float, 0.85, "log-odds added to cells on the arc at the reading",
                       min=1e-6),
        "arc_thickness": Param(float, 0.1, "depth of the occupied arc", unit="m", min=0.01),
        "clamp": Param(float, 4.0, "log-odds are kept within +-clamp", min=0.1),
        "no_echo_reach": Param(float, -1.0, "how far a reading without an echo clears, "
                                            "short against specular losses through walls "
                                            "(negative: the sonar's whole range)", unit="m"),
        "shared_arc": Param(float, -1.0, "width of arc one echo's l_occ covers: a wider "
                                         "(farther) arc gives each cell its share, so the "
                                         "jambs' arcs do not paint doorways shut (negative: "
                                         "every arc cell gets all of l_occ)", unit="m"),
        "occlusion": Param(float, -1.0, "log-odds from which a cell stops the clearing of a "
                                        "reading without an echo, so a wall the map is sure "
                                        "of is not cleared through (negative: nothing stops "
                                        "it)"),
        "seen_through": Param(int, 0, "beams with an echo that must have passed a free cell, "
                                      "0.3 m short of their echo, before an echo's arc is "
                                      "kept off it, so the jambs' arcs do not shut a door "
                                      "seen through (0: every arc cell takes its share)",
                              min=0),
    }

    def setup(self) -> None:
        spec = _robot(self.p.robot)
        self.mounts = np.asarray(spec.sonar_mounts, dtype=np.float64)
        self.model = InverseSonarModel(cone_deg=spec.sonar.cone_deg,
                                       max_range=spec.sonar.max_range,
                                       l_free=self.p.l_free, l_occ=self.p.l_occ,
                                       arc_thickness=self.p.arc_thickness,
                                       l_min=-self.p.clamp, l_max=self.p.clamp,
                                       no_echo_reach=(None if self.p.no_echo_reach < 0
                                                      else self.p.no_echo_reach),
                                       shared_arc=(None if self.p.shared_arc <= 0
                                                   else self.p.shared_arc),
                                       occlusion=(None if self.p.occlusion <= 0
                                                  else self.p.occlusion),
                                       seen_through=self.p.seen_through or None)
        self.map = LogOddsMap(self.model, resolution=self.p.resolution)  # tables built once

    def reset(self) -> None:
        super().reset()
        self.map.clear()
        self._snapshot: OccupancyMap | None = None

    def step(self, ranges: np.ndarray, pose: np.ndarray, truth: np.ndarray | None = None,
             walls: Any = None) -> dict[str, Any]:
        self.record_truth(truth)
        x, y, theta = (float(v) for v in pose[:3])
        c, s = math.cos(theta), math.sin(theta)
        mx, my, mt = self.mounts[:, 0], self.mounts[:, 1], self.mounts[:, 2]
        sensors = np.column_stack([x + c * mx - s * my, y + s * mx + c * my, theta + mt])
        ranges = np.asarray(ranges, dtype=np.float64)
        self.map.add_scan(sensors, ranges, None if walls is None
                          else clear_ranges(sensors, ranges, walls.segments(), self.model))
        self._snapshot = None
        return {"map": self}

    def snapshot(self) -> OccupancyMap | None:
        """The map as it stands (cached until the next scan)."""
        if self._snapshot is None:
            p, (ix, iy) = self.map.probabilities()
            if p.size == 0:
                return None
            origin = (ix * self.p.resolution, iy * self.p.resolution, 0.0)
            self._snapshot = OccupancyMap(p, self.p.resolution, origin)
        return self._snapshot

    def occupancy_map(self) -> OccupancyMap | None:
        self.report("updates", self.map.updates)
        self.report("tiles", self.map.grid.n_tiles)
        return self.snapshot()


@block("maps.drift_correction", category="maps")
class DriftCorrectionBlock(Block):
    """Odometry corrected against the walls the sonar has mapped, while the robot drives.

    Odometry alone is metres out after a few hundred metres, and a map drawn
    on it doubles the walls the robot passes twice: doors close on the plan
    and seen rooms open phantom frontiers.  This is the offline map's drift
    correction (:class:`~blocks.maps.drift.DriftCorrector`) run online: every
    second of scans is aligned with the walls mapped before it, and the
    correction so far is applied to every pose.  With ``truth`` connected it
    reports the corrected and the raw odometry's position errors (scoring only).
    """

    inputs = {"ranges": RANGES, "pose": POSE, "truth": TRUTH}
    outputs = {"pose": Port.array("float64", (3,), unit="m,m,rad",
                                  doc="the odometry pose corrected against the walls"),
               "walls": Port(kind="handle", doc="the walls mapped so far: segments() gives "
                                                "their (F, 4) end points in the corrected "
                                                "frame")}
    params = {
        "robot": ROBOT,
        "enabled": Param(bool, True, "correct the odometry (false: pass it through)"),
        "rectilinear": Param(bool, True, "walls meet at right angles, so every straight wall "
                                         "measures heading, until a long wall that leans a "
                                         "few degrees shows otherwise (false: never assume "
                                         "it)"),
    }

    def setup(self) -> None:
        spec = _robot(self.p.robot)
        self.max_range = float(spec.sonar.max_range)
        self.mounts = np.asarray(spec.sonar_mounts, dtype=np.float64)
        self.cone_deg = float(spec.sonar.cone_deg)

    def reset(self) -> None:
        from .drift import DriftCorrection, DriftCorrector
        self.corrector = DriftCorrector(self.mounts, self.cone_deg,
                                        DriftCorrection(rectilinear=self.p.rectilinear))
        self._errors: list[tuple[float, float]] = []

    def step(self, ranges: np.ndarray, pose: np.ndarray,
             truth: np.ndarray | None = None) -> dict[str, Any]:
        ranges = np.asarray(ranges, dtype=np.float64)
        pose = np.asarray(pose, dtype=np.float64)[:3]
        if not self.p.enabled:
            out = pose.copy()
        else:
            silent = self.max_range - InverseSonarModel.max_range_margin  # the maps' rule
            out = self.corrector.add(pose, ranges, ranges < silent)
        if truth is not None:
            self._errors.append((math.hypot(out[0] - truth[0], out[1] - truth[1]),
                                 math.hypot(pose[0] - truth[0], pose[1] - truth[1])))
        return {"pose": out, "walls": self.corrector}

    def finish(self) -> None:
        if self.p.enabled and self.p.rectilinear:
            # false: a leaning wall showed the floor is not square, and the correction
            # stopped assuming it is
            self.report("rectilinear", self.corrector.rectilinear)
        if self._errors:
            corrected, raw = np.array(self._errors).T
            self.report("error_median_m", round(float(np.median(corrected)), 3))
            self.report("error_max_m", round(float(corrected.max()), 3))
            self.report("odometry_error_median_m", round(float(np.median(raw)), 3))
            self.report("odometry_error_max_m", round(float(raw.max()), 3))


@block("maps.amcl", category="maps")
class AMCLBlock(Block):
    """The robot's pose on a known map: Monte Carlo localisation with the sonar ring.

    Odometry drifts away from the map a plan was made on; this particle
    filter (:class:`~blocks.maps.amcl.MonteCarloLocaliser`, ROS ``amcl``'s
    method with the simulator's sonar model) keeps the pose on it. It starts
    round the first odometry pose (the map's frame starts where the robot
    does) and moves with the odometry between updates. With ``truth``
    connected it reports its own and the raw odometry's position errors
    (scoring only: the filter never sees it).
    """

    inputs = {"pose": POSE, "ranges": RANGES,
              "echo": Port.array("bool", (16,), frame="robot",
                                 doc="true where a real echo came back (sim2d.sonar's echo)"),
              "map": Port(kind="handle", doc="the map to localise on: snapshot() gives its "
                                             "OccupancyMap (semantic.task_planner's grid, or "
                                             "any map block)"),
              "truth": TRUTH}
    outputs = {"pose": Port.array("float64", (3,), unit="m,m,rad",
                                  doc="the pose on the map"),
               "spread": Port.scalar("float64", unit="m",
                                     doc="the particles' position standard deviation")}
    params = {
        "robot": ROBOT,
        "enabled": Param(bool, True, "localise (false: pass the odometry through, to compare)"),
        "particles": Param(int, 300, "number of particles at the start, and the most there "
                                     "may be", min=10, max=100_000),
        "min_particles": Param(int, 100, "the fewest there may be, when the cloud has "
                                         "converged (KLD sampling; = particles: a fixed "
                                         "number)", min=1, max=100_000),
        "sigma_hit": Param(float, 0.15, "spread of a reading about the range the map predicts "
                                        "(sonar noise plus the map's own error)", unit="m",
                           min=0.01),
        "update_min_d": Param(float, 0.2, "update after this much travel", unit="m", min=0.0),
        "update_min_a": Param(float, math.pi / 6, "or after this much turning", unit="rad",
                              min=0.0),
    }

    def setup(self) -> None:
        if self.p.min_particles > self.p.particles:
            raise BlockError(f"min_particles ({self.p.min_particles}) is more than particles "
                             f"({self.p.particles})", node=self.name, field="min_particles",
                             hint="Set min_particles at most particles (equal: a fixed "
                                  "number of particles).")
        spec = _robot(self.p.robot)
        self.mounts = np.asarray(spec.sonar_mounts, dtype=np.float64)
        self.sonar = spec.sonar

    def reset(self) -> None:
        self.localiser = None
        self._map_source: Any = None
        self._errors: list[tuple[float, float]] = []

    def _start(self, handle: Any, pose: np.ndarray) -> None:
        from .amcl import AMCLParams, MonteCarloLocaliser, map_walls
        m = handle.snapshot() if hasattr(handle, "snapshot") else None
        if not isinstance(m, OccupancyMap):
            raise BlockError("the map input gives no occupancy map", node=self.name,
                             field="input 'map'",
                             hint="Connect a handle whose snapshot() is an OccupancyMap: "
                                  "semantic.task_planner's grid or a map block's map.")
        params = AMCLParams(particles=self.p.particles, min_particles=self.p.min_particles,
                            sigma_hit=self.p.sigma_hit,
                            update_min_d=self.p.update_min_d, update_min_a=self.p.update_min_a)
        self.localiser = MonteCarloLocaliser(
            map_walls(m), self.mounts, cone_deg=self.sonar.cone_deg,
            max_range=self.sonar.max_range,
            specular_deg=self.sonar.specular_deg if self.sonar.specular else None,
            start=pose, params=params, rng=self.rng)
        self._map_source = handle

    def step(self, pose: np.ndarray, ranges: np.ndarray, echo: np.ndarray, map: Any,
             truth: np.ndarray | None = None) -> dict[str, Any]:
        pose = np.asarray(pose, dtype=np.float64)[:3]
        if not self.p.enabled:
            out, spread = pose.copy(), math.nan
        else:
            if self.localiser is None or map is not self._map_source:
                self._start(map, pose)
            out, spread = self.localiser.step(pose, ranges, echo), self.localiser.spread_m
        if truth is not None:
            self._errors.append((math.hypot(out[0] - truth[0], out[1] - truth[1]),
                                 math.hypot(pose[0] - truth[0], pose[1] - truth[1])))
        return {"pose": out, "spread": spread}

    def finish(self) -> None:
        if self.localiser is not None:
            self.report("updates", self.localiser.updates)
            self.report("resamples", self.localiser.resamples)
            counts = self.localiser.particle_counts
            if counts:
                self.report("particles_mean", round(float(np.mean(counts)), 1))
                self.report("particles_min", int(min(counts)))
        if self._errors:
            estimate, odometry = np.array(self._errors).T
            self.report("error_median_m", round(float(np.median(estimate)), 3))
            self.report("error_max_m", round(float(estimate.max()), 3))
            self.report("error_final_m", round(float(estimate[-1]), 3))
            self.report("odometry_error_median_m", round(float(np.median(odometry)), 3))
            self.report("odometry_error_max_m", round(float(odometry.max()), 3))
            self.report("odometry_error_final_m", round(float(odometry[-1]), 3))


@block("maps.process_map", category="maps")
class ProcessMap(_MapWriter):
    """The paper's processed online map: smoothing, edge detection and border tracing.

    At the end of the run the online map is cleaned (morphology, median,
    small regions dropped, small holes filled) and its free-space borders are
    traced into wall polylines (OpenCV).  Writes ``maps/processed.yaml`` and
    the walls as GeoJSON in the map frame, ``maps/processed_walls.geojson``.
    """

    map_name = "processed"
    inputs = {"map": MAP_HANDLE, "truth": TRUTH}
    params = {
        "world": WORLD, "robot": ROBOT,
        "smooth": Param(float, 0.15, "radius of the opening that removes slivers", unit="m",
                        min=0.0),
        "min_region": Param(float, 0.25, "free regions and holes smaller than this are noise",
                            unit="m^2", min=0.0),
        "simplify": Param(float, 0.05, "polyline simplification tolerance", unit="m", min=0.0),
        "min_wall": Param(float, 0.3, "shorter polylines are dropped", unit="m", min=0.0),
    }

    def reset(self) -> None:
        super().reset()
        self._source: Any = None
        self._processed: Any = None

    def step(self, map: Any, truth: np.ndarray | None = None) -> None:  # noqa: A002
        self._source = map
        self.record_truth(truth)

    def occupancy_map(self) -> OccupancyMap | None:
        from .processing import process_occupancy_map
        online = self._source.snapshot() if self._source is not None else None
        if online is None:
            return None
        self._processed = process_occupancy_map(
            online, smooth_m=self.p.smooth, min_region_m2=self.p.min_region,
            simplify_m=self.p.simplify, min_wall_m=self.p.min_wall)
        self.report("walls", len(self._processed.walls))
        return self._processed.map

    def write_extras(self, folder: Any) -> list[Any]:
        from .processing import write_walls_geojson
        kinds = [{"kind": k} for k in self._processed.kinds]
        return [write_walls_geojson(folder / "processed_walls.geojson", self._processed.walls,
                                    feature_properties=kinds,
                                    properties={"source": "processed online map"})]


@block("maps.offline_map", category="maps")
class OfflineMapBlock(_MapWriter):
    """The paper's high-resolution offline map, with O'Sullivan's linear feature prediction.

    Records every scan and odometry pose; at the end, corrects the odometry
    drift against the walls, extracts linear features, judges every reading
    by them and draws the map: echo terminations darkened, specular losses
    stopped at the predicted wall, max-range readings marking nothing,
    unexplored space left unknown.  Writes ``maps/offline.yaml`` and the
    features as GeoJSON, ``maps/offline_walls.geojson``, and the drift-corrected
    path in the map's frame, ``maps/offline_path.csv`` (where the robot has been,
    so provably passable: the query planner plans through it).
    """

    map_name = "offline"
    inputs = {"ranges": RANGES, "pose": POSE, "truth": TRUTH}
    outputs = {"map": Port(kind="handle", doc="this map: snapshot() gives the OccupancyMap at "
                                              "the end of the run, corrected_pose(tick) the "
                                              "drift-corrected pose of a tick")}
    params = {
        "robot": ROBOT, "world": WORLD,
        "resolution": Param(float, 0.025, "offline map cell size", unit="m", min=0.005,
                            max=1.0),
        "correct_drift": Param(bool, True, "correct the odometry against the walls first"),
        "rectilinear": Param(bool, True, "walls meet at right angles, so every straight wall "
                                         "measures heading, until a long wall that leans a "
                                         "few degrees shows otherwise (false: never assume "
                                         "it)"),
        "agree_tol": Param(float, 0.1, "an echo this close to its predicted range confirms it",
                           unit="m", min=0.0),
        "min_support": Param(int, 8, "features need this many echoes", min=2),
    }

    def reset(self) -> None:
        super().reset()
        self._scans: list[np.ndarray] = []
        self._poses: list[np.ndarray] = []
        self._ticks: list[int] = []
        self._result: Any = None

    def step(self, ranges: np.ndarray, pose: np.ndarray,
             truth: np.ndarray | None = None) -> dict[str, Any]:
        self._scans.append(np.array(ranges, dtype=np.float64))
        self._poses.append(np.array(pose[:3], dtype=np.float64))
        self._ticks.append(self.ctx.tick)
        self.record_truth(truth)
        return {"map": self}

    def _build(self) -> Any:
        """The offline map, built once at the end of the run (None before any scan)."""
        from .offline import OfflineMapParams, build_offline_map
        if self._result is None and self._scans:
            spec = _robot(self.p.robot)
            params = OfflineMapParams(resolution=self.p.resolution, agree_tol=self.p.agree_tol,
                                      min_support=self.p.min_support,
                                      correct_drift=self.p.correct_drift,
                                      rectilinear=self.p.rectilinear)
            self._result = build_offline_map(np.array(self._poses), np.array(self._scans),
                                             spec.sonar_mounts, cone_deg=spec.sonar.cone_deg,
                                             max_range=spec.sonar.max_range, params=params)
        return self._result

    def occupancy_map(self) -> OccupancyMap | None:
        result = self._build()
        if result is None:
            return None
        self.report("features", len(result.features))
        self.report("readings", result.class_counts())
        if self.p.correct_drift and self.p.rectilinear:
            # false: a leaning wall showed the floor is not square; corrected without it
            self.report("rectilinear", result.leaning_wall is None)
        return result.map

    def snapshot(self) -> OccupancyMap | None:
        """The finished offline map (built on first use)."""
        result = self._build()
        return None if result is None else result.map

    def corrected_path(self) -> np.ndarray | None:
        """(T, 3) drift-corrected poses, one per recorded tick."""
        result = self._build()
        return None if result is None else np.asarray(result.poses)

    def corrected_pose(self, tick: int, pose: np.ndarray) -> np.ndarray:
        """Where the drift correction puts the robot that odometry had at ``pose`` on ``tick``.

        The correction is rigid per chunk, so the odometry pose of ``tick`` is
        mapped by the same rotation and shift as the recorded one.
        """
        result = self._build()
        pose = np.asarray(pose, dtype=np.float64)[:3]
        if result is None or not self._ticks:
            return pose.copy()
        i = int(np.clip(np.searchsorted(self._ticks, tick), 0, len(self._ticks) - 1))
        before, after = self._poses[i], np.asarray(result.poses[i], dtype=np.float64)
        dth = after[2] - before[2]
        c, s = math.cos(dth), math.sin(dth)
        rel = pose[:2] - before[:2]
        return np.array([after[0] + c * rel[0] - s * rel[1], after[1] + s * rel[0] + c * rel[1],
                         pose[2] + dth])

    def write_extras(self, folder: Any) -> list[Any]:
        from .processing import write_walls_geojson
        result = self._build()
        features = result.features
        return [write_path_csv(folder / "offline_path.csv", self._ticks, result.poses),
                write_walls_geojson(
            folder / "offline_walls.geojson", [np.array([f.p0, f.p1]) for f in features],
            feature_properties=[{"support": f.support, "residual_m": round(f.residual, 4)}
                                for f in features],
            properties={"source": "offline map linear features"})]
