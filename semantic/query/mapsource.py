"""What the task planner knows: a semantic mapping run's output, or a world surveyed.

The planner needs three things about a building: the knowledge base (places,
people, objects, reasoned over), a grid to plan paths on, and where the robot
is. :func:`load_run_map` reads them from a semantic mapping run's folder
(``semantic_map.ttl``, ``maps/offline.yaml``, ``maps/offline_path.csv``);
:func:`survey_map` builds them from a sim2d world's ground truth, as a
building's floor plan and room schedule would give them. Both give a
:class:`QueryMap`, so grounding and planning cannot tell them apart.

Paths are planned on the map coarsened to ``resolution`` (0.05 m: A* stays
within milliseconds) and inflated by the robot's radius. On a sonar map the
jambs of a door are drawn thicker than they are, so the doors the robot went
through could look closed; the cells on the robot's own drift-corrected path
are opened again (:func:`blocks.navigate.grid.unblock_traversed`): where it
has been, it fits.
"""
from __future__ import annotations

import functools
import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from blocks.core.errors import SemmapError
from blocks.maps.mapio import OccupancyMap, read_map
from blocks.navigate.grid import DEFAULT_RADIUS, NavGrid, inflate, unblock_traversed
from semantic.kb import KnowledgeBase

__all__ = ["MapSourceError", "PlaceInfo", "QueryMap", "coarsen", "load_map", "load_run_map",
           "survey_map"]

#: Cell size (m) the planner plans on.
PLAN_RESOLUTION = 0.05


class MapSourceError(SemmapError):
    """The folder or world given as the planner's map cannot be used."""


@dataclass(frozen=True)
class PlaceInfo:
    """A place of the map as the planner names it.

    Attributes
    ----------
    id
        The knowledge base's place id (``P3``).
    name
        The sign text naming it (``"MANAGER"``), or None.
    kind
        Its most specific place class (``"ManagerOffice"``).
    centre
        (x, y) of its centroid, map frame (m).
    polygon
        (N, 2) outline, or None.
    """

    id: str
    name: str | None
    kind: str | None
    centre: tuple[float, float] | None
    polygon: np.ndarray | None = field(default=None, compare=False, repr=False)

    @property
    def label(self) -> str:
        """How answers call it: its sign text, else ``"a corridor (P6)"``."""
        if self.name:
            return self.name
        kind = _words(self.kind or "Place").lower()
        article = "an" if kind[:1] in "aeiou" else "a"
        return f"{article} {kind} ({self.id})"


def _words(camel: str) -> str:
    """``"MailRoom"`` -> ``"Mail Room"``."""
    out = "".join(f" {c}" if c.isupper() and i else c for i, c in enumerate(camel))
    return out.strip()


@dataclass(eq=False)  # one per building loaded: hashed by identity (caches)
class QueryMap:
    """A building as the task planner sees it (see the module docstring).

    Attributes
    ----------
    kb
        The reasoned knowledge base.
    occupancy
        The map paths are planned on (map frame).
    grid
        ``occupancy`` coarsened, inflated by ``radius`` and opened along ``track``.
    home
        (x, y, theta): where the robot is when a plan starts, and where the
        person asking stands ("bring me ..."): the start of the mapping run.
    source
        The run folder or world file.
    world
        The sim2d world the map is of (for executing plans), when known.
    track
        (N, 2) where the robot has been, map frame (empty for a survey).
    """

    kb: KnowledgeBase
    occupancy: OccupancyMap
    grid: NavGrid
    home: tuple[float, float, float]
    source: Path
    world: Path | None = None
    track: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    surveyed: bool = False

    @functools.cached_property
    def places(self) -> dict[str, PlaceInfo]:
        """Every place of the map by id, in id order (P2 before P10)."""
        g = self.kb.place_graph()
        out = {}
        for pid, data in sorted(g.nodes(data=True), key=lambda n: _id_order(n[0])):
            centre = (data["x"], data["y"]) if data.get("x") is not None else None
            out[pid] = PlaceInfo(pid, data.get("name"), data.get("kind"), centre,
                                 self.kb.polygon(pid))
        return out

    @functools.cached_property
    def place_graph(self):
        """The KB's place graph (nodes: place ids; edges: doors)."""
        return self.kb.place_graph()

    @functools.cached_property
    def people(self) -> list[str]:
        """The names of the people the KB knows (from the timetable)."""
        return self.kb.people_names()

    def label(self, place_id: str) -> str:
        """The name answers give a place."""
        info = self.places.get(place_id)
        return info.label if info is not None else place_id

    def known_places(self) -> str:
        """The named places, for messages: ``"ADMIN, KITCHEN, LAB"`` (or a count of places)."""
        names = sorted({p.name for p in self.places.values() if p.name})
        unnamed = sum(1 for p in self.places.values() if not p.name)
        text = ", ".join(names) if names else "none named"
        return text + (f" (and {unnamed} unnamed)" if unnamed else "")

    @functools.lru_cache(maxsize=None)  # noqa: B019 - one QueryMap per session
    def place_point(self, place_id: str) -> tuple[float, float] | None:
        """Where to stop in a place: the free cell reachable from home that is well clear
        of walls (up to the grid's safe clearance) and nearest the place's centre.
        None when the robot cannot reach any part of the place on this map."""
        info = self.places.get(place_id)
        if info is None:
            return None
        g = self.grid
        home = g.world_to_cell(*self.home[:2])
        reach = int(g.labels[home]) if g.inside(*home) and not g.blocked[home] else None
        if reach is None:
            near = g.nearest_free(*home, 0.5)
            reach = int(g.labels[near]) if near is not None else None
        if reach is None:
            return None
        mask = self._place_mask(info) & (g.labels == reach)
        if not mask.any():
            return None
        clear = np.where(mask, np.minimum(g.clearance, g.safe_clearance), -1.0)
        best = clear.max()
        rows, cols = np.nonzero(clear >= best - g.resolution)
        xy = g.cell_to_world(rows, cols)
        centre = np.asarray(info.centre if info.centre else xy.mean(axis=0))
        k = int(np.argmin(np.hypot(*(xy - centre).T)))
        return float(xy[k, 0]), float(xy[k, 1])

    def _place_mask(self, info: PlaceInfo) -> np.ndarray:
        g = self.grid
        mask = np.zeros(g.shape, dtype=np.uint8)
        if info.polygon is not None and len(info.polygon) >= 3:
            rows, cols = g.cells_of(np.asarray(info.polygon, dtype=np.float64))
            cv2.fillPoly(mask, [np.stack([cols, rows], axis=1).astype(np.int32)], 1)
        elif info.centre is not None:
            r, c = g.world_to_cell(*info.centre)
            cv2.circle(mask, (int(c), int(r)), int(1.0 / g.resolution), 1, -1)
        return mask.astype(bool)

    def place_at(self, x: float, y: float, hint: str | None = None) -> str | None:
        """The id of the place whose outline holds (x, y), or None; ``hint`` (e.g. the
        place the robot was in a tick ago) is tested first."""
        order = [hint] if hint in self.places else []
        for pid in order + [p for p in self.places if p != hint]:
            outline = self._outlines.get(pid)
            if outline is not None and cv2.pointPolygonTest(
                    outline, (float(x), float(y)), False) >= 0:
                return pid
        return None

    @functools.cached_property
    def _outlines(self) -> dict[str, np.ndarray]:
        return {pid: info.polygon.astype(np.float32) for pid, info in self.places.items()
                if info.polygon is not None and len(info.polygon) >= 3}


def _id_order(pid: str) -> tuple[str, int, str]:
    head = pid.rstrip("0123456789")
    tail = pid[len(head):]
    return head, int(tail) if tail else -1, pid


def coarsen(m: OccupancyMap, resolution: float) -> OccupancyMap:
    """The map at a coarser ``resolution`` (a whole multiple of the map's cell size).

    A coarse cell is occupied if any of its cells is (a wall never thins away),
    else free if at least half its cells are free, else unknown.
    """
    factor = int(round(resolution / m.resolution))
    if factor <= 1:
        return m
    occupied, free, _ = m.classes()
    h, w = m.shape
    H, W = -(-h // factor), -(-w // factor)
    pad = ((0, H * factor - h), (0, W * factor - w))
    occ = np.pad(occupied, pad).reshape(H, factor, W, factor).any(axis=(1, 3))
    fre = np.pad(free, pad).reshape(H, factor, W, factor).mean(axis=(1, 3)) >= 0.5
    grid = np.full((H, W), np.nan)
    grid[fre] = 0.0
    grid[occ] = 1.0
    return OccupancyMap(occupancy=grid, resolution=m.resolution * factor, origin=m.origin,
                        occupied_thresh=m.occupied_thresh, free_thresh=m.free_thresh)


def _grid(m: OccupancyMap, resolution: float, radius: float, track: np.ndarray) -> NavGrid:
    grid = inflate(coarsen(m, resolution), radius=radius)
    if len(track):
        grid = unblock_traversed(grid, track)
    return grid


def load_map(spec: str | Path, **options: Any) -> QueryMap:
    """A run folder (:func:`load_run_map`), else a world name or file (:func:`survey_map`)."""
    path = Path(spec)
    if path.is_dir():
        return load_run_map(path, **options)
    if path.suffix in (".yaml", ".yml") or not path.exists():
        from sim2d.worlds import available_worlds
        if path.suffix in (".yaml", ".yml") or str(spec) in available_worlds():
            return survey_map(spec, **options)
    raise MapSourceError(f"{str(spec)!r} is neither a semantic mapping run's folder nor a "
                         "world", hint="Give the --out folder of `semmap run "
                                       "graphs/semantic_mapping.yaml`, or a world name "
                                       f"({', '.join(available_worlds())}) or world file.")


def _run_world(run_dir: Path) -> Path | None:
    """The world a run simulated (absolute path in run.json, else its name in the graph)."""
    from sim2d.blocks import resolve_world
    try:
        meta = json.loads((run_dir / "run.json").read_text())
    except (OSError, ValueError):
        return None
    recorded = (meta.get("metrics", {}).get("world", {}) or {}).get("world")
    if recorded and Path(recorded).exists():
        return Path(recorded)
    name = ((meta.get("graph", {}).get("params", {}) or {}).get("world", {}) or {}).get("value")
    if recorded:
        name = name or Path(recorded).stem
    if not name:
        return None
    try:
        return resolve_world(str(name))
    except SemmapError:
        return None


def load_run_map(run_dir: str | Path, *, resolution: float = PLAN_RESOLUTION,
                 radius: float = DEFAULT_RADIUS) -> QueryMap:
    """The planner's view of a semantic mapping run's output folder.

    Raises
    ------
    MapSourceError
        A file the planner needs is missing (names it and the command that writes it).
    """
    from blocks.maps.pathio import read_path_csv
    run_dir = Path(run_dir)
    ttl = run_dir / "semantic_map.ttl"
    occupancy_file = run_dir / "maps" / "offline.yaml"
    for needed in (ttl, occupancy_file):
        if not needed.exists():
            raise MapSourceError(f"{run_dir} has no {needed.relative_to(run_dir)}: it is not the "
                                 "output of a semantic mapping run", file=needed,
                                 hint="Run `semmap run graphs/semantic_mapping.yaml --out DIR` "
                                      "and give DIR.")
    kb = KnowledgeBase.load(ttl)
    occupancy = read_map(occupancy_file)
    path_file = run_dir / "maps" / "offline_path.csv"
    track = np.zeros((0, 2))
    home: tuple[float, float, float] | None = None
    if path_file.exists():
        _, poses = read_path_csv(path_file)
        if len(poses):
            track = poses[:, :2]
            home = (float(poses[0, 0]), float(poses[0, 1]), float(poses[0, 2]))
    world = _run_world(run_dir)
    if home is None:
        home = _world_start(world) if world is not None else None
    if home is None:
        raise MapSourceError(f"{run_dir} does not say where the robot started (no "
                             "maps/offline_path.csv, and its world is unknown)",
                             file=path_file, hint="Re-run the semantic mapping with this "
                                                  "version of semmap.")
    return QueryMap(kb=kb, occupancy=occupancy, grid=_grid(occupancy, resolution, radius, track),
                    home=home, source=run_dir, world=world, track=track)


def _world_start(world: Path) -> tuple[float, float, float]:
    from sim2d.world import load_world
    w = load_world(world)
    return tuple(float(v) for v in w.start)  # type: ignore[return-value]


def survey_map(world: str | Path, *, resolution: float = PLAN_RESOLUTION,
               radius: float = DEFAULT_RADIUS) -> QueryMap:
    """The planner's view of a world's ground truth: its floor plan, places, doors,
    signs, objects (as observed) and timetable, reasoned over like a mapped one."""
    from blocks.maps.mapio import occupancy_map_from_world
    from sim2d.blocks import resolve_world
    from sim2d.world import load_world
    path = resolve_world(str(world))
    w = load_world(path)
    kb = KnowledgeBase.from_world(w)
    kb.reason()
    occupancy = occupancy_map_from_world(w)
    home = tuple(float(v) for v in w.start)
    return QueryMap(kb=kb, occupancy=occupancy, grid=_grid(occupancy, resolution, radius,
                                                           np.zeros((0, 2))),
                    home=home, source=path, world=path, surveyed=True)  # type: ignore[arg-type]
