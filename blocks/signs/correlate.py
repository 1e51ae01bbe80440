"""Sign labeling and correlation: read plates placed on the map, the paper's hybrid map.

Each capture of a plate that the reader could make something of becomes a
:class:`Sighting`: the text, the plate's estimated pose in the world (from
:mod:`blocks.signs.geometry`), and the robot pose it was taken from. A robot
passing a plate sees it several times (and again on the next lap), so the
:class:`SignMap` merges sightings of one plate: close together, facing the
same way, and not disagreeing about a confidently read text, or so close
that they can only be one plate, whatever the reader made of it (two plates
do not hang within a plate's width of each other). Each merged sign keeps the
text most of its confident readings agree on, and a position weighted
towards its best views.

Because every sighting keeps the sign's pose *relative to the robot*, a map
whose robot path is corrected afterwards (loop closure, scan matching) can
move its signs with it: :meth:`SignMap.replace_poses`.

Outputs: ``signs.json`` (:func:`write_signs_json`), the hybrid-map picture
(:func:`draw_hybrid_map`) and a score against the world's true signs
(:func:`score_signs`).

Conventions: positions in metres in the map (odometry/world) frame; a
:class:`Sighting`'s facing is in radians (like :class:`sim2d.world.Sign`),
the dicts of :meth:`SignMap.signs` and ``signs.json`` give it in **degrees**,
like a world file's ``signs:``.
"""
from __future__ import annotations

import json
import math
import re
import warnings
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from blocks.core.atomic import atomic_write_figure, atomic_write_text
from blocks.core.jsonable import to_jsonable
from semantic.vocabulary import same_name

from .geometry import camera_pose_of, compose, estimate_plate, relative, wrap
from .types import PLATE_HEIGHT, PLATE_WIDTH, Capture, Reading

__all__ = [
    "Sighting",
    "SignCluster",
    "SignMap",
    "draw_hybrid_map",
    "normalise_text",
    "score_signs",
    "SIGHTING_COLUMNS",
    "sighting_from_capture",
    "write_signs_json",
    "write_sightings_csv",
]

#: Heading uncertainty (rad) assumed for the robot pose when weighting sightings: a
#: far view suffers more from a heading error than a near one.
HEADING_SIGMA = math.radians(2.0)
#: Smallest confidence weight, so an unread sighting still helps place its plate.
MIN_WEIGHT = 0.1


def normalise_text(text: str | None) -> str:
    """Upper case, single spaces, no leading or trailing space: how texts are compared."""
    return re.sub(r"\s+", " ", (text or "").upper()).strip()


@dataclass
class Sighting:
    """One reading of one plate, placed in the map frame.

    Attributes
    ----------
    text, raw_text, confidence
        From the :class:`~blocks.signs.types.Reading` (``text`` normalised and
        vocabulary-matched, ``''`` when nothing matched).
    x, y : float
        The plate's centre in the map frame (m).
    facing : float
        The plate's outward normal, map frame (rad).
    tick, time
        When the frame was taken.
    range : float
        Camera-to-plate distance (m), ``nan`` if unknown.
    viewing_angle : float
        Estimated angle between the plate's normal and the line of sight (rad).
    sigma : float
        Standard deviation of the plate's position from the image alone (m);
        ``nan`` if unknown.
    robot_pose : ndarray (3,) or None
        The robot pose (map frame) the sighting is placed from: the odometry
        pose at first, a corrected one after :meth:`SignMap.replace_poses`.
    rel : (x, y, facing) or None
        The plate's pose in the robot frame, so a corrected robot pose can
        re-place it (:meth:`SignMap.replace_poses`).
    extra : dict
        Anything else (zoom, pan, OCR scores, ...), kept for diagnostics.
    original_pose : ndarray (3,) or None
        The robot pose the sighting was first placed from (set from
        ``robot_pose``): what a correction maps, so correcting twice is harmless.
    cam_rel : (x, y, yaw) or None
        The camera's pose in the robot frame when the frame was taken.
    scale : float
        The plate's size relative to the standard plate the image estimate
        assumes: ``rel`` is where a standard plate would be, and the plate is
        ``scale`` times as far from the camera (:meth:`SignMap.place_on_walls`).
    seen_scale : float
        The size the views on the way to the plate measured (the capture's
        ``scale``): where the map has no wall for it, the plate keeps it.
    on_wall : bool
        Whether :meth:`SignMap.place_on_walls` measured ``scale`` by the map's wall.
    """

    text: str
    raw_text: str
    confidence: float
    x: float
    y: float
    facing: float
    tick: int = 0
    time: float = 0.0
    range: float = math.nan
    viewing_angle: float = math.nan
    sigma: float = math.nan
    robot_pose: np.ndarray | None = None
    rel: tuple[float, float, float] | None = None
    extra: dict = field(default_factory=dict)
    original_pose: np.ndarray | None = None
    cam_rel: tuple[float, float, float] | None = None
    scale: float = 1.0
    seen_scale: float = 1.0
    on_wall: bool = False

    def __post_init__(self) -> None:
        self.text = normalise_text(self.text)
        if self.robot_pose is not None:
            self.robot_pose = np.asarray(self.robot_pose, dtype=np.float64).reshape(3)
            if self.original_pose is None:
                self.original_pose = self.robot_pose.copy()
            if self.rel is None:  # keep the sign's pose relative to the robot for later
                self.rel = relative(self.robot_pose, (self.x, self.y, self.facing))

    def place(self, robot_pose: np.ndarray) -> None:
        """Put the sighting where ``robot_pose`` and its plate's size say it is."""
        self.robot_pose = np.asarray(robot_pose, dtype=np.float64).reshape(3)
        self.x, self.y, self.facing = compose(self.robot_pose, self.rel)
        if self.cam_rel is not None and self.scale != 1.0:
            cx, cy, _ = compose(self.robot_pose, self.cam_rel)
            self.x, self.y = cx + self.scale * (self.x - cx), cy + self.scale * (self.y - cy)

    def weight(self) -> float:
        """How much this sighting counts in its sign's position.

        The inverse of the variance of its position, made up of the image's
        ``sigma`` (or, without it, a penalty for oblique views) and a heading
        error growing with range, times the reading's confidence (at least
        :data:`MIN_WEIGHT`): near, frontal, well-read views count most.
        """
        rng = self.range if math.isfinite(self.range) else 1.0
        var = (HEADING_SIGMA * max(rng, 0.3)) ** 2
        if math.isfinite(self.sigma):
            var += self.sigma ** 2
        elif math.isfinite(self.viewing_angle):
            var /= max(math.cos(self.viewing_angle), 0.1)
        return max(float(self.confidence), MIN_WEIGHT) / var

    def quality(self) -> tuple[float, float]:
        """Sort key of the best reading: higher confidence, then nearer and more frontal."""
        rng = self.range if math.isfinite(self.range) else 1e3
        view = self.viewing_angle if math.isfinite(self.viewing_angle) else math.pi / 2
        return round(float(self.confidence), 9), -rng / max(math.cos(view), 0.05)


def sighting_from_capture(capture: Capture, reading: Reading, *,
                          mount: tuple[float, float] = (0.15, 0.0),
                          plate_height: float = PLATE_HEIGHT,
                          plate_width: float | None = PLATE_WIDTH,
                          sigma_px: float = 1.0) -> Sighting | None:
    """Place a read capture in the map frame of its ``robot_pose``.

    Parameters
    ----------
    capture, reading
        The zoomed frame (with its detection, intrinsics, pan and robot pose)
        and what the reader made of it.
    mount : (x, y)
        Position of the camera's pan axis in the robot frame (m), e.g.
        ``(spec.mount_x, spec.mount_y)`` of a :class:`sim2d.camera.CameraSpec`.
    plate_height, plate_width, sigma_px
        Passed to :func:`~blocks.signs.geometry.estimate_plate`.

    Returns
    -------
    Sighting or None
        ``None`` when the plate cannot be placed (degenerate or too clipped).
    """
    det = capture.detection
    est = estimate_plate(det.corners, capture.camera, plate_height, plate_width=plate_width,
                         clipped=det.clipped, sigma_px=sigma_px)
    if est is None:
        return None
    robot = np.asarray(capture.robot_pose, dtype=np.float64).reshape(3)
    cam_rel = camera_pose_of((0.0, 0.0, 0.0), mount[0], mount[1], capture.pan)
    rel = compose(cam_rel, est.as_tuple())
    x, y, facing = compose(robot, rel)
    sighting = Sighting(text=reading.text, raw_text=reading.raw_text,
                        confidence=float(reading.confidence), x=x, y=y, facing=facing,
                        tick=int(capture.tick), time=float(capture.time), range=est.range,
                        viewing_angle=est.viewing_angle, sigma=est.sigma_xy, robot_pose=robot,
                        rel=rel, cam_rel=tuple(float(v) for v in cam_rel),
                        scale=float(capture.scale), seen_scale=float(capture.scale),
                        extra={"zoom": float(capture.zoom), "pan": float(capture.pan),
                               "tilt": float(capture.tilt), "method": est.method,
                               "sigma_facing": est.sigma_facing,
                               "ocr_score": float(reading.ocr_score),
                               "match_score": float(reading.match_score)})
    if sighting.scale != 1.0:  # where a plate of the measured size is, along the same ray
        sighting.place(robot)
    return sighting


# ---- merging ---------------------------------------------------------------------------------
@dataclass
class SignCluster:
    """The sightings of one plate, with their merged pose and best reading."""

    sightings: list[Sighting] = field(default_factory=list)
    x: float = 0.0
    y: float = 0.0
    facing: float = 0.0
    confident: float = 0.5  # readings this confident outvote weaker ones (the map's conflict_confidence)
    core_radius: float = 1.0  # the readings this close to the best-supported one place the plate

    def votes(self) -> dict[str, float]:
        """Each text read, with the summed confidence of the readings that say it.

        Only the confident readings vote when there are any: three weak reads of a
        shorter word do not outvote one clear read.
        """
        read = [s for s in self.sightings if s.text]
        sure = [s for s in read if s.confidence >= self.confident] or read
        votes: dict[str, float] = {}
        for s in sure:
            votes[s.text] = votes.get(s.text, 0.0) + float(s.confidence)
        return votes

    def confident_texts(self) -> set[str]:
        """The texts this plate's confident readings say."""
        return {s.text for s in self.sightings if s.text and s.confidence >= self.confident}

    @property
    def disputed(self) -> bool:
        """Whether confident readings of this plate say different things."""
        return len(self.confident_texts()) > 1

    @property
    def top_confidence(self) -> float:
        """The confidence of its most confident reading with a text (0 if none)."""
        return max((s.confidence for s in self.sightings if s.text), default=0.0)

    @property
    def best(self) -> Sighting:
        """The reading kept: of the text the most confidence supports (:meth:`votes`), the
        most confident reading, ties to the nearer, more frontal view.

        One misread digit ("OFFICE 182" for 102) must not name the plate when
        the other reads agree.
        """
        votes = self.votes()  # a reading with no text, or outvoted, ranks last
        return max(self.sightings, key=lambda s: (votes.get(s.text, -1.0), s.quality()))

    def add(self, s: Sighting) -> None:
        self.sightings.append(s)
        self._update()

    def _update(self) -> None:
        """Position: the weighted mean of the core; facing: its weighted circular mean.

        The core is the readings within ``core_radius`` of the reading whose
        neighbourhood holds the most weight: a reading placed along its line of
        sight by a wrong guess of the plate's size joins its plate by its text
        but does not drag the plate off where the others agree.
        """
        w = np.array([s.weight() for s in self.sightings])
        xs = np.array([[s.x, s.y, math.cos(s.facing), math.sin(s.facing)]
                       for s in self.sightings])
        near = np.hypot(xs[:, None, 0] - xs[None, :, 0],
                        xs[:, None, 1] - xs[None, :, 1]) <= self.core_radius
        core = near[int(np.argmax(near @ w))]
        m = (w[core, None] * xs[core]).sum(axis=0) / w[core].sum()
        self.x, self.y = float(m[0]), float(m[1])
        self.facing = math.atan2(m[3], m[2]) if np.hypot(m[2], m[3]) > 1e-9 else \
            self.best.facing

    def as_dict(self) -> dict[str, Any]:
        """The signs.json record (facing in degrees)."""
        best = self.best
        return {"text": best.text, "raw_text": best.raw_text,
                "confidence": round(float(best.confidence), 4),
                "x": round(self.x, 3), "y": round(self.y, 3),
                "facing": round(math.degrees(wrap(self.facing)), 1),
                "sightings": len(self.sightings)}


class SignMap:
    """Sightings merged into signs.

    Parameters
    ----------
    merge_radius : float
        Two sightings within this distance (m) may be the same plate.
    merge_facing_deg : float
        ... if their facings differ by less than this (deg): plates on the
        two sides of a wall, or round a corner, stay apart.
    text_merge_radius : float
        The larger radius (m) for sightings whose confident texts agree, so
        a sign seen again after some odometry drift, or placed along its line
        of sight by a wrong guess of its size, still merges (no two plates
        share a text on 150 generated floors or the shipped ones; where two
        did, within this distance and facing the same way they would be one).
        The plate stays where most of its readings agree
        (:meth:`SignCluster._update`).
    conflict_confidence : float
        Texts read at least this confidently must agree for a merge; a
        weaker reading (or an empty text) agrees with anything.
    same_plate_radius : float
        ...except within this distance (m), facing the same way, where two
        readings can only be of one plate: two plates do not hang within a
        plate's width of each other (on 150 generated floors, plates facing
        the same way are at least 1.09 m apart), and a reader that read a
        plate as "OFFICE 102" eight times and "OFFICE 182" once has read one
        plate, not two.  The plate's text is then put to the vote
        (:meth:`SignCluster.votes`).  0: confident readings that disagree
        never merge (weak readings are still put to the vote).
    """

    def __init__(self, merge_radius: float = 1.0, merge_facing_deg: float = 60.0,
                 text_merge_radius: float = 3.0, conflict_confidence: float = 0.5,
                 same_plate_radius: float = 0.5) -> None:
        if merge_radius <= 0 or text_merge_radius < merge_radius:
            raise ValueError("need 0 < merge_radius <= text_merge_radius")
        if same_plate_radius < 0:
            raise ValueError("need same_plate_radius >= 0")
        self.same_plate_radius = float(same_plate_radius)
        self.merge_radius = float(merge_radius)
        self.merge_facing = math.radians(merge_facing_deg)
        self.text_merge_radius = float(text_merge_radius)
        self.conflict_confidence = float(conflict_confidence)
        self._sightings: list[Sighting] = []
        self.clusters: list[SignCluster] = []

    def __len__(self) -> int:
        return len(self.clusters)

    @property
    def sightings(self) -> list[Sighting]:
        """Every sighting added, in order."""
        return list(self._sightings)

    def _confident_text(self, s: Sighting) -> str:
        return s.text if s.confidence >= self.conflict_confidence else ""

    def _match(self, s: Sighting) -> int | None:
        """Index of the cluster ``s`` belongs to, or None.

        The nearest cluster whose confident texts include the reading's (or
        where one side has none); failing that, the nearest within
        ``same_plate_radius`` that read something else: a misread joins its
        plate, never a neighbour that read it right.
        """
        text = self._confident_text(s)
        agreeing: tuple[float, int | None] = (math.inf, None)
        same_plate: tuple[float, int | None] = (math.inf, None)
        for i, c in enumerate(self.clusters):
            d = math.hypot(s.x - c.x, s.y - c.y)
            if abs(wrap(s.facing - c.facing)) >= self.merge_facing:
                continue
            others = c.confident_texts()
            if text and others and text not in others:
                if self.same_plate_radius > 0 and d <= self.same_plate_radius:
                    same_plate = min(same_plate, (d, i))
                continue
            radius = self.text_merge_radius if text and text in others else self.merge_radius
            if d <= radius:
                agreeing = min(agreeing, (d, i))
        return agreeing[1] if agreeing[1] is not None else same_plate[1]

    def _place(self, s: Sighting) -> int:
        i = self._match(s)
        if i is None:
            self.clusters.append(SignCluster(confident=self.conflict_confidence,
                                             core_radius=self.merge_radius))
            i = len(self.clusters) - 1
        self.clusters[i].add(s)
        return i

    def add(self, sighting: Sighting) -> int:
        """Merge a sighting into its plate (or start a new one); returns the plate's index."""
        if not all(math.isfinite(v) for v in (sighting.x, sighting.y, sighting.facing)):
            raise ValueError(f"sighting has a non-finite pose: {sighting!r}")
        self._sightings.append(sighting)
        return self._place(sighting)

    def rebuild(self) -> None:
        """Merge all sightings again from scratch, in the order they were added."""
        self.clusters = []
        for s in self._sightings:
            self._place(s)

    def replace_poses(self, pose_of_tick: Callable[[int, np.ndarray], np.ndarray]) -> int:
        """Re-place every sighting from a corrected robot pose, then merge again.

        Parameters
        ----------
        pose_of_tick : callable (tick, old_robot_pose) -> new_robot_pose
            The corrected robot pose (x, y, theta) at a sighting's tick, given
            the pose the sighting was first placed from (its odometry pose,
            ``original_pose``), e.g. an offline map's ``corrected_pose``. Each
            call starts from the original poses, so calling it again with a
            better correction replaces the previous one.

        Returns
        -------
        int
            How many sightings moved (those without a ``robot_pose`` and
            ``rel`` stay where they are).
        """
        moved = 0
        for s in self._sightings:
            if s.robot_pose is None or s.rel is None:
                continue
            original = s.robot_pose if s.original_pose is None else s.original_pose
            s.place(np.asarray(pose_of_tick(s.tick, original.copy()), dtype=np.float64))
            moved += 1
        self.rebuild()
        return moved

    #: A sonar map's wall is a band of occupied cells; the plate hangs on the wall's face,
    #: within the band's first this many metres (m): its middle is the guess.
    WALL_BAND = 0.3

    def place_on_walls(self, occupancy: Any, scales: tuple[float, float] = (0.3, 3.0)) -> int:
        """Measure each plate's size by the wall it hangs on, then merge again.

        The image gives the ray from the camera to a plate and where along it
        a standard plate would be, but a plate of unknown size could be
        anywhere along it. A door sign hangs on a wall, and the robot's map
        has the wall: the plate is where the ray meets it (the middle of the
        band of occupied cells a sonar map draws a wall as). A wall nearer or
        farther than ``scales`` times the standard distance is not the
        plate's (a frame, furniture, or a wall the map missed): that sighting
        keeps the standard size.

        Parameters
        ----------
        occupancy : OccupancyMap
            The map, in the frame of the sightings' robot poses
            (:meth:`~blocks.maps.mapio.OccupancyMap.first_occupied`).
        scales : (low, high)
            The plate sizes, relative to the standard plate, to believe.

        Returns
        -------
        int
            How many sightings were placed on a wall.
        """
        placed = 0
        for s in self._sightings:
            if s.robot_pose is None or s.rel is None or s.cam_rel is None:
                continue
            s.scale = 1.0
            s.place(s.robot_pose)
            cx, cy, _ = compose(s.robot_pose, s.cam_rel)
            s.scale, s.on_wall = s.seen_scale, False  # unless a wall says otherwise
            dx, dy = s.x - cx, s.y - cy
            standard = math.hypot(dx, dy)
            if standard < 1e-6:
                continue
            band = occupancy.first_occupied(cx, cy, dx / standard, dy / standard,
                                            scales[1] * standard)
            hit = None if band is None else band[0] + min(band[1] - band[0], self.WALL_BAND) / 2
            if hit is not None and hit >= scales[0] * standard:  # the band's middle
                s.scale = min(hit, scales[1] * standard) / standard
                s.on_wall = True
                placed += 1
            s.place(s.robot_pose)
        self.rebuild()
        return placed

    def _is_read(self, c: SignCluster, min_confidence: float) -> bool:
        """Read: some reading with a text is at least ``min_confidence``; the vote names it."""
        return bool(c.best.text) and c.top_confidence >= min_confidence

    def signs(self, min_confidence: float = 0.5) -> list[dict[str, Any]]:
        """The read signs: ``{text, raw_text, confidence, x, y, facing (deg), sightings}``.

        Only plates one of whose readings has a (vocabulary-matched) text and
        at least ``min_confidence``, named by the vote
        (:attr:`SignCluster.best`); sorted by text, then x, then y.
        """
        out = [c.as_dict() for c in self.clusters if self._is_read(c, min_confidence)]
        return sorted(out, key=lambda d: (d["text"], d["x"], d["y"]))

    def sighting_rows(self, min_confidence: float = 0.5) -> list[dict[str, Any]]:
        """One record per reading: where it was placed, and the plate it went to.

        Why: a plate placed wrong, or read twice as two, is explained by its
        readings (each from a pose, a range and a size guess), which
        :meth:`signs` merges away.  ``plate`` numbers the merged plates in
        order of their first reading; ``published`` says whether the plate is
        among :meth:`signs`; ``on_wall`` whether the reading was put where its
        ray meets the map's wall (:meth:`place_on_walls`); angles in degrees.
        """
        plate_of = {id(s): k for k, c in enumerate(self.clusters) for s in c.sightings}
        published = {k for k, c in enumerate(self.clusters) if self._is_read(c, min_confidence)}
        rows = []
        for s in self._sightings:
            k = plate_of.get(id(s), -1)
            pose = s.robot_pose if s.robot_pose is not None else np.full(3, math.nan)
            rows.append({"plate": k, "published": k in published, "tick": s.tick,
                         "time": round(s.time, 2), "text": s.text, "raw_text": s.raw_text,
                         "confidence": round(float(s.confidence), 4), "x": round(s.x, 3),
                         "y": round(s.y, 3), "facing": round(math.degrees(wrap(s.facing)), 1),
                         "range": round(s.range, 3),
                         "viewing_angle": round(math.degrees(s.viewing_angle), 1),
                         "scale": round(s.scale, 3), "on_wall": s.on_wall,
                         "robot_x": round(float(pose[0]), 3), "robot_y": round(float(pose[1]), 3),
                         "robot_theta": round(math.degrees(float(pose[2])), 1)})
        return rows

    def rejected(self, min_confidence: float = 0.5) -> list[dict[str, Any]]:
        """The plates left out of :meth:`signs`, with why and every raw text read."""
        out = []
        for c in self.clusters:
            if self._is_read(c, min_confidence):
                continue
            d = c.as_dict()
            d["reason"] = "no text" if not c.best.text else \
                f"confidence {c.top_confidence:.2f} < {min_confidence:.2f}"
            d["raw_texts"] = [s.raw_text for s in c.sightings]
            out.append(d)
        return sorted(out, key=lambda d: (d["x"], d["y"]))


# ---- outputs ---------------------------------------------------------------------------------
def write_signs_json(path: str | Path, signs: Sequence[Mapping[str, Any]],
                     extra: Mapping[str, Any] | None = None) -> list[Path]:
    """Write ``signs.json``: a JSON list of ``{text, raw_text, confidence, x, y, facing,
    sightings}`` (facing in degrees), atomically.

    Parameters
    ----------
    path
        The file (usually ``DIR/signs.json``).
    signs
        The records, e.g. :meth:`SignMap.signs`.
    extra
        Anything else worth keeping (parameters, rejected plates, a score):
        written next to it as ``NAME.meta.json``, so the list stays the
        file's top level.

    Returns
    -------
    list of Path
        The files written.
    """
    path = Path(path)
    records = [dict(s) for s in signs]
    atomic_write_text(path, json.dumps(to_jsonable(records), indent=2) + "\n")
    written = [path]
    if extra is not None:
        meta = path.with_name(path.stem + ".meta.json")
        atomic_write_text(meta, json.dumps(to_jsonable(dict(extra)), indent=2) + "\n")
        written.append(meta)
    return written


#: The columns of ``signs/sightings.csv`` (:func:`write_sightings_csv`).
SIGHTING_COLUMNS = ("plate", "published", "tick", "time", "text", "raw_text", "confidence",
                    "x", "y", "facing", "range", "viewing_angle", "scale", "on_wall",
                    "robot_x", "robot_y", "robot_theta")


def write_sightings_csv(path: str | Path, rows: Sequence[Mapping[str, Any]]) -> Path:
    """Write :meth:`SignMap.sighting_rows` as CSV (columns :data:`SIGHTING_COLUMNS`), atomically."""
    import csv
    import io
    buf = io.StringIO()
    writer = csv.DictWriter(buf, fieldnames=SIGHTING_COLUMNS, lineterminator="\n")
    writer.writeheader()
    writer.writerows(rows)
    atomic_write_text(Path(path), buf.getvalue())
    return Path(path)


def _as_sign(obj: Any) -> tuple[str, float, float, float]:
    """``(text, x, y, facing_rad)`` of a sign given as a dict (facing in **degrees**, the
    world-file and signs.json convention) or an object such as :class:`sim2d.world.Sign`
    (facing in **radians**)."""
    if isinstance(obj, Mapping):
        facing = obj.get("facing")
        return (normalise_text(obj.get("text")), float(obj["x"]), float(obj["y"]),
                math.radians(float(facing)) if facing is not None else math.nan)
    return (normalise_text(obj.text), float(obj.x), float(obj.y), float(obj.facing))


def _map_rgba(m) -> tuple[np.ndarray, tuple[float, float, float, float]]:
    """An RGBA picture of an occupancy map (row 0 lowest y, :func:`blocks.maps.mapio.map_rgba`)
    and its world extent."""
    from blocks.maps.mapio import map_rgba

    h, w = m.shape
    ox, oy = float(m.origin[0]), float(m.origin[1])
    return map_rgba(m), (ox, ox + w * m.resolution, oy, oy + h * m.resolution)


def draw_hybrid_map(occupancy_map, signs: Sequence[Mapping[str, Any]], path: str | Path, *,
                    trajectory: np.ndarray | None = None,
                    true_signs: Iterable[Any] | None = None, title: str | None = None,
                    size_px: int = 1000, tolerance: float = 1.0) -> Path:
    """The hybrid map: the read signs drawn on the occupancy map, as a PNG.

    Parameters
    ----------
    occupancy_map : blocks.maps.mapio.OccupancyMap or None
        The metric map (``None``: signs and path on a blank background).
    signs
        Records as in signs.json (facing in degrees): a filled marker, an
        arrow along the facing and the text.
    path
        The PNG to write (atomically).
    trajectory : array (N, >= 2), optional
        The robot's path (x, y, ...), drawn as a line.
    true_signs : optional
        The world's signs (:class:`sim2d.world.Sign`, facing in radians, or
        dicts with facing in degrees), drawn as hollow markers; an estimate
        within ``tolerance`` (m) of one is joined to it by a thin line, and
        those with no estimate that near are named in grey italics.
    title : str, optional
    size_px : int
        Width of the picture (px).

    Returns
    -------
    Path
    """
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    est = [_as_sign(s) for s in signs]
    truth = [_as_sign(s) for s in (true_signs or [])]
    points = [(x, y) for _, x, y, _ in est + truth]
    traj = None if trajectory is None else np.asarray(trajectory, dtype=np.float64)
    if traj is not None and traj.ndim == 2 and len(traj):
        points += [tuple(p) for p in traj[:, :2]]
    if occupancy_map is not None:
        rgb, extent = _map_rgba(occupancy_map)
    else:
        rgb = None
        pts = np.array(points) if points else np.zeros((1, 2))
        extent = (pts[:, 0].min() - 1, pts[:, 0].max() + 1, pts[:, 1].min() - 1,
                  pts[:, 1].max() + 1)
    width, height = max(extent[1] - extent[0], 1.0), max(extent[3] - extent[2], 1.0)
    from blocks.maps.mapio import display_sized
    fig_h = max(3.0, size_px / 100 * height / width) + 0.6
    fig, ax = plt.subplots(figsize=(size_px / 100, fig_h), dpi=100)
    try:
        if rgb is not None:
            ax.imshow(display_sized(rgb, size_px, 100 * fig_h), origin="lower", extent=extent,
                      interpolation="nearest", zorder=0)
        if traj is not None and traj.ndim == 2 and len(traj):
            ax.plot(traj[:, 0], traj[:, 1], color="#1f77b4", lw=1.0, alpha=0.8,
                    label="robot path", zorder=2)
        arrow = min(1.5, max(0.4, 0.03 * max(width, height)))  # m: visible at any map size
        for k, (text, x, y, facing) in enumerate(truth):
            ax.plot(x, y, "s", mfc="none", mec="#555555", ms=8, mew=1.2, zorder=3,
                    label="true sign" if k == 0 else None)
            if not any(math.hypot(x - ex, y - ey) <= tolerance for _, ex, ey, _ in est):
                # a sign not found: name it in grey, behind it (in its room)
                off = -1.0 * arrow
                ax.text(x + off * math.cos(facing) if math.isfinite(facing) else x,
                        y + off * math.sin(facing) if math.isfinite(facing) else y + off,
                        text, fontsize=6, color="#777777", style="italic", ha="center",
                        va="center", zorder=3)
        for k, (text, x, y, facing) in enumerate(est):
            if truth:
                d = [math.hypot(x - tx, y - ty) for _, tx, ty, _ in truth]
                j = int(np.argmin(d))
                if d[j] <= tolerance:
                    ax.plot([x, truth[j][1]], [y, truth[j][2]], color="#555555", lw=0.8,
                            zorder=3)
            ax.plot(x, y, "s", color="#b03a2e", ms=5, zorder=5,
                    label="read sign" if k == 0 else None)
            if math.isfinite(facing):
                dx, dy = arrow * math.cos(facing), arrow * math.sin(facing)
                ax.annotate("", xy=(x + dx, y + dy), xytext=(x, y), zorder=5,
                            arrowprops={"arrowstyle": "->", "color": "#b03a2e", "lw": 1.2})
                # the label goes behind the plate: in the room the sign names
                lx, ly = x - 1.0 * dx, y - 1.0 * dy
            else:
                lx, ly = x, y + arrow
            ax.text(lx, ly, text, fontsize=7, color="#b03a2e", ha="center", va="center",
                    zorder=6, bbox={"boxstyle": "round,pad=0.15", "fc": "white", "ec": "none",
                                    "alpha": 0.7})
        ax.set_xlim(extent[0], extent[1])
        ax.set_ylim(extent[2], extent[3])
        ax.set_aspect("equal")
        ax.set_xlabel("x [m]")
        ax.set_ylabel("y [m]")
        ax.set_title(title if title is not None else f"hybrid map: {len(est)} signs")
        if est or truth or traj is not None:
            ax.legend(loc="upper right", fontsize=7)
        with warnings.catch_warnings():
            # a very small map (a short run) leaves no room to tighten: keep the layout
            warnings.filterwarnings("ignore", message="Tight layout not applied")
            fig.tight_layout()
        return atomic_write_figure(path, fig)
    finally:
        plt.close(fig)


# ---- scoring ---------------------------------------------------------------------------------
def score_signs(signs: Sequence[Any], true_signs: Sequence[Any],
                tolerance: float = 1.0) -> dict[str, Any]:
    """Compare estimated signs with the world's.

    Estimates and true signs are paired one-to-one by position (Hungarian
    assignment on the distances, pairs farther than ``tolerance`` m do not
    count); the text is only compared afterwards.

    Parameters
    ----------
    signs
        Estimated signs: dicts as in signs.json (facing in **degrees**).
    true_signs
        :class:`sim2d.world.Sign` objects (facing in **radians**) or dicts
        (facing in degrees, like a world file).
    tolerance : float
        Largest distance (m) at which an estimate counts as the true sign.

    Returns
    -------
    dict
        ``true_signs``, ``estimated``; ``found`` (true signs with an estimate
        within tolerance); ``read_exactly`` (found, and the normalised texts
        are equal, case and spacing aside: a plate saying "POSTROOM" is read
        exactly as the vocabulary's "POST ROOM"); ``wrong_text`` (found, text
        differs); ``false_positions`` (estimates with no true sign paired);
        ``false_signs`` = ``false_positions + wrong_text``; ``missed`` (true
        signs not found); ``precision`` (read_exactly / estimated) and
        ``recall`` (read_exactly / true_signs); ``position_error_mean`` and
        ``_max`` (m) and ``facing_error_max_deg`` over the found signs
        (``None`` if none); ``per_sign``: one record per true sign (in the
        given order) then per unpaired estimate, with ``status`` in
        ``read``, ``wrong_text``, ``missed``, ``false_position``.
    """
    from scipy.optimize import linear_sum_assignment

    est = [_as_sign(s) for s in signs]
    truth = [_as_sign(s) for s in true_signs]
    pairs: dict[int, int] = {}  # true index -> estimate index
    if est and truth:
        d = np.array([[math.hypot(ex - tx, ey - ty) for _, ex, ey, _ in est]
                      for _, tx, ty, _ in truth])
        big = 1e6
        rows, cols = linear_sum_assignment(np.where(d <= tolerance, d, big))
        pairs = {int(r): int(c) for r, c in zip(rows, cols) if d[r, c] <= tolerance}
    per_sign: list[dict[str, Any]] = []
    errors, facing_errors = [], []
    read = wrong = 0
    for i, (text, tx, ty, tf) in enumerate(truth):
        rec: dict[str, Any] = {"true_text": text, "true_x": tx, "true_y": ty}
        if i not in pairs:
            rec.update(status="missed", text=None, x=None, y=None, position_error=None,
                       facing_error_deg=None)
        else:
            etext, ex, ey, ef = est[pairs[i]]
            err = math.hypot(ex - tx, ey - ty)
            ferr = abs(math.degrees(wrap(ef - tf))) if math.isfinite(ef + tf) else None
            errors.append(err)
            if ferr is not None:
                facing_errors.append(ferr)
            ok = same_name(etext, text)
            read += ok
            wrong += not ok
            rec.update(status="read" if ok else "wrong_text", text=etext, x=ex, y=ey,
                       position_error=round(err, 4),
                       facing_error_deg=None if ferr is None else round(ferr, 2))
        per_sign.append(rec)
    paired = set(pairs.values())
    false_positions = 0
    for j, (etext, ex, ey, _) in enumerate(est):
        if j in paired:
            continue
        false_positions += 1
        per_sign.append({"true_text": None, "true_x": None, "true_y": None,
                         "status": "false_position", "text": etext, "x": ex, "y": ey,
                         "position_error": None, "facing_error_deg": None})
    return {
        "true_signs": len(truth),
        "estimated": len(est),
        "found": len(pairs),
        "read_exactly": read,
        "wrong_text": wrong,
        "false_positions": false_positions,
        "false_signs": false_positions + wrong,
        "missed": len(truth) - len(pairs),
        "precision": read / len(est) if est else None,
        "recall": read / len(truth) if truth else None,
        "position_error_mean": float(np.mean(errors)) if errors else None,
        "position_error_max": float(np.max(errors)) if errors else None,
        "facing_error_max_deg": float(np.max(facing_errors)) if facing_errors else None,
        "tolerance": float(tolerance),
        "per_sign": per_sign,
    }
