"""Mapping blocks: thin adapters over :mod:`blocks.maps` (paper online map, log-odds map).

Every map block writes its map at the end of the run into ``DIR/maps/`` in
ROS map_server format (YAML + PGM, with a PNG preview) and, when it knows the
world (parameter ``world``, set by ``--world``), scores it against the ground
truth into run.json.
"""
from __future__ import annotations

import math
from typing import Any

import numpy as np

from blocks.core import Block, BlockError, Param, Port, block

from .logodds import InverseSonarModel, LogOddsMap
from .mapio import OccupancyMap, write_map
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


def _robot(model: str):
    from sim2d.robot import load_robot
    return load_robot(model)


class _MapWriter(Block):
    """Shared end-of-run work: write the map files, score them when the world is known."""

    map_name = "map"

    def occupancy_map(self) -> OccupancyMap | None:
        raise NotImplementedError

    def finish(self) -> None:
        m = self.occupancy_map()
        if m is None or self.ctx.out_dir is None:
            return
        path = self.output_path(f"maps/{self.map_name}.yaml")
        for written in write_map(path, m)[1:]:
            self.ctx.outputs.append(str(written))
        if self.p.world:
            from sim2d.blocks import resolve_world
            from sim2d.world import load_world

            from .score import score_map
            for name, value in score_map(m, load_world(resolve_world(self.p.world))).items():
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
    inputs = {"local": LOCAL, "pose": POSE}
    params = {"resolution": RESOLUTION, "world": WORLD}

    def setup(self) -> None:
        self.map = PaperGlobalMap(self.p.resolution)

    def reset(self) -> None:
        self.map.clear()

    def step(self, local: np.ndarray, pose: np.ndarray) -> None:
        self.map.add(local, pose)

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
    ``maps/probabilistic.yaml``.
    """

    map_name = "probabilistic"
    inputs = {"ranges": RANGES, "pose": POSE}
    params = {
        "robot": ROBOT, "resolution": RESOLUTION, "world": WORLD,
        "l_free": Param(float, -0.4, "log-odds added to cells a beam crossed", max=-1e-6),
        "l_occ": Param(float, 0.85, "log-odds added to cells on the arc at the reading",
                       min=1e-6),
        "arc_thickness": Param(float, 0.1, "depth of the occupied arc", unit="m", min=0.01),
        "clamp": Param(float, 4.0, "log-odds are kept within +-clamp", min=0.1),
    }

    def setup(self) -> None:
        spec = _robot(self.p.robot)
        self.mounts = np.asarray(spec.sonar_mounts, dtype=np.float64)
        self.model = InverseSonarModel(cone_deg=spec.sonar.cone_deg,
                                       max_range=spec.sonar.max_range,
                                       l_free=self.p.l_free, l_occ=self.p.l_occ,
                                       arc_thickness=self.p.arc_thickness,
                                       l_min=-self.p.clamp, l_max=self.p.clamp)
        self.map = LogOddsMap(self.model, resolution=self.p.resolution)  # tables built once

    def reset(self) -> None:
        self.map.clear()

    def step(self, ranges: np.ndarray, pose: np.ndarray) -> None:
        x, y, theta = (float(v) for v in pose[:3])
        c, s = math.cos(theta), math.sin(theta)
        mx, my, mt = self.mounts[:, 0], self.mounts[:, 1], self.mounts[:, 2]
        sensors = np.column_stack([x + c * mx - s * my, y + s * mx + c * my, theta + mt])
        self.map.add_scan(sensors, ranges)

    def occupancy_map(self) -> OccupancyMap | None:
        p, (ix, iy) = self.map.probabilities()
        if p.size == 0:
            return None
        self.report("updates", self.map.updates)
        self.report("tiles", self.map.grid.n_tiles)
        origin = (ix * self.p.resolution, iy * self.p.resolution, 0.0)
        return OccupancyMap(p, self.p.resolution, origin)
