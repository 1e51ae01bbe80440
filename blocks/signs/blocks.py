"""Sign blocks: thin adapters over :mod:`blocks.signs` (detector, stop-and-zoom, reader,
labeling and correlation).

The detector runs on every camera frame; the stop-and-zoom behaviour halts the
follower and drives the camera head; the reader runs only on captures; the
correlation places the read signs on the map and writes ``DIR/signs.json`` and
the hybrid map ``DIR/maps/hybrid.png``.
"""
from __future__ import annotations

import csv
import functools
import io
import math
from typing import Any

import numpy as np

from blocks.core import Block, Param, Port, block

from .types import Capture, CameraModel

ROBOT = Param(str, "atrv_mini", "robot model or robot YAML (camera intrinsics and mount)")
WORLD = Param(str, "", "world to score the signs against (name or YAML; empty: do not score)",
              role="world")
IMAGE = Port(kind="image", dtype="uint8", shape=("H", "W", 3), frame="camera", doc="BGR frame")
DETECTIONS = Port.message(doc="list of PlateDetection, best first")
CAMERA_MODEL = Port.message(doc="CameraModel: the frame's pinhole intrinsics")
POSE = Port.array("float64", (3,), unit="m,m,rad",
                  doc="the robot's pose in the map frame (odometry)")
TRUTH = Port.array("float64", (3,), unit="m,m,rad", frame="world", required=False,
                   doc="true pose, only to score (optional)")
HEAD = {"pan": Port.scalar("float64", unit="rad", doc="the head's pan now"),
        "tilt": Port.scalar("float64", unit="rad", doc="the head's tilt now"),
        "zoom": Port.scalar("float64", doc="the head's zoom now")}


def _camera_spec(robot: str):
    from sim2d.blocks import camera_spec_of
    from sim2d.robot import load_robot
    return camera_spec_of(load_robot(robot))


@block("signs.detector", category="signs")
class Detector(Block):
    """The paper's textual sign detector: sign plates in each camera frame (OpenCV).

    Finds bordered, text-bearing quadrilaterals (light ones, and with
    ``looks: any`` outlined ones of any colour) and reports each one's
    corners, bearing and range (from its apparent height).  Trigger it with the
    camera's ``fresh`` event.  With the optional ground truth ``visible``
    connected (the camera's), it counts true and false detections into run.json
    and saves the first false-positive frames to ``DIR/signs/false_positives/``.
    """

    inputs = {"image": IMAGE,
              "zoom": Port.scalar("float64", doc="the frame's zoom"),
              "tilt": Port.scalar("float64", unit="rad", doc="the frame's tilt"),
              "visible": Port.message(required=False,
                                      doc="ground truth plates in view (scoring only)")}
    outputs = {"detections": DETECTIONS, "camera": CAMERA_MODEL,
               "count": Port.scalar("int64", doc="plates found in this frame")}
    params = {"robot": ROBOT,
              "min_score": Param(float, 0.5, "weaker plate candidates are dropped",
                                 min=0.0, max=1.0),
              "looks": Param(str, "standard", "plates looked for: standard (the light plate "
                                              "with dark text, as the paper's) or any (also "
                                              "outlined plates of any colour, light on dark or "
                                              "dark on light: blocks/signs/detect_any.py)",
                             choices=("any", "standard")),
              "inside_edges": Param(bool, False, "with looks: any, also find plates whose "
                                                 "outline touches other edges (a door "
                                                 "frame's, a wall corner's) inside them "
                                                 "(docs/signs.md)"),
              "keep_false_positives": Param(int, 5, "false-positive frames saved for "
                                                    "inspection (needs visible)", min=0)}

    def setup(self) -> None:
        from .detect import DetectorParams, detect_plates
        from .detect_any import AnyLookParams, detect_any_plates
        self._spec, _ = _camera_spec(self.p.robot)
        self._params = DetectorParams()
        self._detect = detect_plates
        if self.p.looks == "any":
            looks = AnyLookParams(inside_edges=self.p.inside_edges)
            self._detect = functools.partial(detect_any_plates, any_params=looks)

    def reset(self) -> None:
        self._frames = 0
        self._found = 0
        self._tp = self._fp = self._fn = 0
        self._fp_saved = 0

    def step(self, image: np.ndarray, zoom: float, tilt: float,
             visible: list | None = None) -> dict[str, Any]:
        camera = CameraModel.of(image.shape[1], image.shape[0], self._spec.hfov, float(zoom),
                                float(tilt))
        dets = [d for d in self._detect(image, camera, self._params) if d.score >= self.p.min_score]
        self._frames += 1
        self._found += len(dets)
        if visible is not None:
            from .detect import match_detections
            tp, fp, fn, _ = match_detections(dets, visible)
            self._tp, self._fp, self._fn = self._tp + tp, self._fp + fp, self._fn + fn
            if fp and self._fp_saved < self.p.keep_false_positives and self.ctx.out_dir:
                self._save_false_positive(image, dets)
        return {"detections": dets, "camera": camera, "count": len(dets)}

    def _save_false_positive(self, image: np.ndarray, dets: list) -> None:
        import cv2

        from blocks.core.atomic import atomic_write_bytes
        marked = image.copy()
        for d in dets:
            cv2.polylines(marked, [np.round(d.corners).astype(np.int32)], True, (0, 0, 255), 1)
        ok, png = cv2.imencode(".png", marked)
        if ok:
            path = self.output_path(f"signs/false_positives/tick{self.ctx.tick:06d}.png")
            atomic_write_bytes(path, png.tobytes())
            self._fp_saved += 1

    def finish(self) -> None:
        self.report("frames", self._frames)
        self.report("plates_detected", self._found)
        if self._tp + self._fp + self._fn:
            self.report("true_positives", self._tp)
            self.report("false_positives", self._fp)
            self.report("missed_detectable", self._fn)


@block("signs.seek", category="signs")
class Seek(Block):
    """Stop-and-zoom: tracks a detected plate, stops the robot at the best view, zooms, captures.

    Connect ``stop`` to the follower's stop input and ``pan``/``tilt``/``zoom``
    to the camera through a one-tick feedback delay.  ``captured`` fires on the
    tick a capture is taken; trigger the reader with it.  ``wanted`` lists the
    plates it could only see at a grazing angle (given up, or captured
    obliquely); a behaviour that brings the robot in front of one sends it
    back on ``look_again`` (through a one-tick delay), and the seeker chases
    it afresh.  Writes the behaviour's log to ``DIR/signs/seek_log.csv`` and
    its counts (stops, time stopped, captures, lost, rejected, timeouts) to
    run.json.
    """

    inputs = {"detections": DETECTIONS, "camera": CAMERA_MODEL,
              "fresh": Port.event(doc="the camera's new-frame event"),
              "image": IMAGE, "pose": POSE, **HEAD,
              "look_again": Port.message(required=False, default=None,
                                         doc="a wanted plate ({key, ...}) the robot now "
                                             "stands in front of, or None")}
    outputs = {"stop": Port.scalar("bool", doc="halt the robot while true"),
               "pan_cmd": Port.scalar("float64", unit="rad", doc="pan command"),
               "tilt_cmd": Port.scalar("float64", unit="rad", doc="tilt command"),
               "zoom_cmd": Port.scalar("float64", doc="zoom command"),
               "capture": Port.message(doc="Capture: the zoomed frame and where it was taken"),
               "captured": Port.event(doc="true on the tick a capture is taken"),
               "wanted": Port.message(doc="plates worth a better view: [{key, x, y, facing, "
                                          "top, why}] (odometry frame; top: of the plate "
                                          "above the camera, m)")}
    params = {"robot": ROBOT,
              "good_view": Param(float, 40.0, "stop once the plate is seen at most this far "
                                              "off its normal", unit="deg", min=0.0, max=89.0),
              "worst_view": Param(float, 70.0, "a plate never seen better than this is given up",
                                  unit="deg", min=0.0, max=89.0),
              "track_range": Param(float, 5.0, "plates farther away are not chased yet",
                                   unit="m", min=0.5),
              "max_stop_range": Param(float, 3.0, "stop only this close to the plate", unit="m",
                                      min=0.3),
              "target_height": Param(float, 60.0, "zoom until the plate is this tall",
                                     unit="px", min=8.0),
              "stop_timeout": Param(float, 5.0, "longest stop", unit="s", min=0.5),
              "scan_tilt": Param(float, 12.0, "head tilt while exploring", unit="deg",
                                 min=-30.0, max=30.0),
              "sweep": Param(float, 35.0, "the head sweeps this far either side while "
                                          "exploring (0: looks straight ahead)", unit="deg",
                             min=0.0, max=90.0),
              "plate_sizes": Param(str, "standard", "standard: every plate is the paper's "
                                   "0.6 x 0.2 m, placed from one image; any: a plate's size is "
                                   "unknown and found from the views on the way to it",
                                   choices=("standard", "any"))}

    def setup(self) -> None:
        from .seek import SeekParams, SignSeeker
        spec, _ = _camera_spec(self.p.robot)
        params = SeekParams(
            good_view_deg=self.p.good_view, worst_view_deg=self.p.worst_view,
            track_range=self.p.track_range, max_stop_range=self.p.max_stop_range,
            target_height_px=self.p.target_height, stop_timeout=self.p.stop_timeout,
            scan_tilt_deg=self.p.scan_tilt, sweep_deg=self.p.sweep,
            aspect=spec.width / spec.height,
            vfov_half_deg=math.degrees(math.atan(math.tan(spec.hfov / 2) * spec.height
                                                 / spec.width)),
            pan_limit_deg=min(-spec.pan_min_deg, spec.pan_max_deg),
            tilt_min_deg=spec.tilt_min_deg, tilt_max_deg=spec.tilt_max_deg,
            zoom_max=spec.zoom_max, plate_sizes=self.p.plate_sizes)
        self.seeker = SignSeeker(params, mount=(spec.mount_x, spec.mount_y))

    def reset(self) -> None:
        self.seeker.reset()

    def step(self, detections: list | None, camera: CameraModel | None, fresh: bool,
             image: np.ndarray | None, pose: np.ndarray, pan: float, tilt: float,
             zoom: float, look_again: dict | None = None) -> dict[str, Any]:
        if look_again is not None:
            self.seeker.look_again(int(look_again["key"]))
        cmd = self.seeker.step(self.ctx.time, pose, bool(fresh), list(detections or []), camera,
                               float(pan), float(tilt), float(zoom))
        out: dict[str, Any] = {"stop": cmd.stop, "pan_cmd": cmd.pan, "tilt_cmd": cmd.tilt,
                               "zoom_cmd": cmd.zoom, "captured": cmd.capture is not None,
                               "wanted": list(self.seeker.wanted)}
        if cmd.capture is not None:
            out["capture"] = Capture(image=np.array(image), detection=cmd.capture, camera=camera,
                                     robot_pose=np.array(pose[:3], dtype=np.float64),
                                     pan=float(pan), tilt=float(tilt), zoom=float(zoom),
                                     tick=self.ctx.tick, time=self.ctx.time,
                                     scale=cmd.target.scale if cmd.target else 1.0)
        return out

    def finish(self) -> None:
        for key, value in self.seeker.summary().items():
            self.report(key, value)
        if self.ctx.out_dir is None:
            return
        from blocks.core.atomic import atomic_write_text
        buf = io.StringIO()
        writer = csv.writer(buf, lineterminator="\n")
        writer.writerow(["time", "event"])
        writer.writerows(self.seeker.stats.events)
        atomic_write_text(self.output_path("signs/seek_log.csv"), buf.getvalue())


@block("signs.reader", category="signs")
class Reader(Block):
    """The paper's textual sign reader: OCR of a capture, matched to the place vocabulary.

    Trigger it with the seek block's ``captured`` event: it never runs on
    ordinary frames.  The plate is rectified from its detected corners, read
    with RapidOCR (models from its wheel; nothing is downloaded), normalised
    (case, spacing, O/0-style confusions) and matched to the vocabulary.
    Saves each captured frame to ``DIR/signs/captures/``, named by tick and reading.
    """

    inputs = {"capture": Port.message(doc="Capture from the seek block")}
    outputs = {"sighting": Port.message(doc="{'capture': Capture, 'reading': Reading}"),
               "read": Port.event(doc="true on the ticks a capture was read")}
    params = {"vocabulary": Param(str, "", "place vocabulary YAML (empty: the packaged one)"),
              "save_captures": Param(bool, True, "save each capture as a PNG")}

    def setup(self) -> None:
        from semantic.vocabulary import load_vocabulary

        from .read import SignReader
        self.vocabulary = load_vocabulary(self.p.vocabulary or None)
        self.reader = SignReader(self.vocabulary)

    def reset(self) -> None:
        self._count = 0
        self._ms: list[float] = []

    def step(self, capture: Capture | None) -> dict[str, Any]:
        if capture is None:
            return {"read": False}
        reading = self.reader.read(capture.image, capture.detection.corners,
                                   vocabulary=self.vocabulary)
        self._count += 1
        if "ocr_ms" in reading.extra:
            self._ms.append(float(reading.extra["ocr_ms"]))
        if self.p.save_captures and self.ctx.out_dir is not None:
            self._save(capture, reading)
        return {"sighting": {"capture": capture, "reading": reading}, "read": True}

    def _save(self, capture: Capture, reading: Any) -> None:
        import cv2

        from blocks.core.atomic import atomic_write_bytes
        label = "".join(ch if ch.isalnum() else "_" for ch in (reading.text or "unread"))
        ok, png = cv2.imencode(".png", capture.image)
        if ok:
            atomic_write_bytes(self.output_path(f"signs/captures/tick{capture.tick:06d}_{label}.png"),
                               png.tobytes())

    def finish(self) -> None:
        self.report("captures_read", self._count)
        if self._ms:
            self.report("ocr_ms_mean", round(float(np.mean(self._ms)), 1))


@block("signs.correlate", category="signs")
class Correlate(Block):
    """The paper's sign labeling and correlation: read signs placed on the map (hybrid map).

    Each reading is placed from the robot's pose when it was captured, the
    head's pan and tilt and the plate's range; repeated sightings of one
    plate merge (readings within half a metre facing the same way are one
    plate whatever they say, readings of one text within 3 m too, placed
    where most of them agree), the plate named by the text its confident
    readings' confidences add up most for; run.json ``disputed`` counts the
    plates whose confident readings disagreed.  Connect the offline map's handle
    to ``map`` and the signs are re-placed on its drift-corrected path, each
    plate where the camera's ray to it meets the map's wall (a plate's size
    is unknown, so the image alone says only how far a standard plate would
    be), and drawn on it.  Writes ``DIR/signs.json``, every reading with the
    plate it went to in ``DIR/signs/sightings.csv``, and ``DIR/maps/hybrid.png``;
    with ``world`` set, scores the signs against the world's into run.json (with
    ``truth`` connected, also against the signs the run passed).

    The ``signs`` output is this block: ``current()`` gives the signs read so
    far and ``version`` counts the sightings merged, so a knowledge base can
    update as each sign is read; after :meth:`finish`, ``current()`` gives the
    final, drift-corrected list that ``signs.json`` holds.
    """

    inputs = {"sighting": Port.message(required=False, default=None,
                                       doc="{'capture', 'reading'} from the reader"),
              "pose": POSE,
              "map": Port(kind="handle", required=False, default=None,
                          doc="the map to draw on (snapshot()); corrected_pose(tick) if any"),
              "truth": TRUTH}
    outputs = {"signs": Port(kind="handle", doc="the signs read so far: current() gives "
                             "{text, x, y, facing, ...} dicts, version counts the sightings")}
    params = {"robot": ROBOT, "world": WORLD,
              "min_confidence": Param(float, 0.5, "weaker readings stay out of signs.json",
                                      min=0.0, max=1.0),
              "merge_radius": Param(float, 1.0, "sightings closer than this are one plate",
                                    unit="m", min=0.0),
              "on_walls": Param(bool, True, "place each plate where its ray meets a wall of "
                                "the map (its size unknown), not where a standard plate would be")}

    def setup(self) -> None:
        spec, _ = _camera_spec(self.p.robot)
        self._mount = (spec.mount_x, spec.mount_y)

    def reset(self) -> None:
        from .correlate import SignMap
        self.signs = SignMap(merge_radius=self.p.merge_radius)
        self._seen_ticks: set[int] = set()
        self._map: Any = None
        self._path: list[np.ndarray] = []
        self._truth: dict[int, np.ndarray] = {}  # tick -> true pose (scoring only)
        self.version = 0
        self._final: list[dict] | None = None

    def current(self) -> list[dict]:
        """The signs read so far (final and drift-corrected once the run has finished)."""
        if self._final is not None:
            return self._final
        return self.signs.signs(min_confidence=self.p.min_confidence)

    def step(self, pose: np.ndarray, sighting: dict | None = None, map: Any = None,  # noqa: A002
             truth: np.ndarray | None = None) -> dict[str, Any]:
        self._path.append(np.array(pose[:3], dtype=np.float64))
        if truth is not None:
            self._truth[self.ctx.tick] = np.array(truth[:3], dtype=np.float64)
        if map is not None:
            self._map = map
        if sighting is None:
            return {"signs": self}
        capture, reading = sighting["capture"], sighting["reading"]
        if capture.tick in self._seen_ticks:
            return {"signs": self}  # the reader's outputs hold between captures
        self._seen_ticks.add(capture.tick)
        from .correlate import sighting_from_capture
        s = sighting_from_capture(capture, reading, mount=self._mount)
        if s is not None:
            self.signs.add(s)
            self.version += 1
        return {"signs": self}

    def finish(self) -> None:
        corrected = getattr(self._map, "corrected_pose", None)
        if corrected is not None:
            self.signs.replace_poses(corrected)
        snapshot = getattr(self._map, "snapshot", None)
        occupancy = snapshot() if snapshot is not None and self.p.on_walls else None
        if occupancy is not None:
            self.report("placed_on_walls", self.signs.place_on_walls(occupancy))
        signs = self.signs.signs(min_confidence=self.p.min_confidence)
        self._final = signs
        self.version += 1
        self.report("signs", len(signs))
        self.report("sightings", sum(s["sightings"] for s in signs))
        # plates read confidently as different texts: one text won the vote
        self.report("disputed", sum(c.disputed for c in self.signs.clusters))
        if self.ctx.out_dir is not None:
            from .correlate import write_signs_json, write_sightings_csv
            write_signs_json(self.output_path("signs.json"), signs)
            write_sightings_csv(self.output_path("signs/sightings.csv"),
                                self.signs.sighting_rows(self.p.min_confidence))
            self._draw(signs)
        if self.p.world:
            self._score(signs)

    def _world(self):
        """The world being scored against, loaded once (drawing and scoring both use it)."""
        if getattr(self, "_loaded_world", None) is None:
            from sim2d.blocks import resolve_world
            from sim2d.world import load_world
            self._loaded_world = load_world(resolve_world(self.p.world))
        return self._loaded_world

    def _draw(self, signs: list[dict]) -> None:
        from .correlate import draw_hybrid_map
        snapshot = getattr(self._map, "snapshot", None)
        occupancy = snapshot() if snapshot is not None else None
        if occupancy is None:
            return
        path = np.array(self._path) if self._path else None
        corrected_path = getattr(self._map, "corrected_path", None)
        if corrected_path is not None:
            path = corrected_path()
        true_signs = self._world().signs if self.p.world else None
        draw_hybrid_map(occupancy, signs, self.output_path("maps/hybrid.png"),
                        trajectory=path, true_signs=true_signs, title="hybrid map: signs on the map")

    def _score(self, signs: list[dict]) -> None:
        """Scores against the world's signs: false signs against all of them; found and
        read against those the run passed (with ``truth``), which exploration could reach.
        With the true path known, the signs are also placed from the true poses, which
        separates the correlation's own error from the odometry's."""
        import copy

        from .correlate import score_signs
        from .coverage import signs_along_path
        world = self._world()
        score = score_signs(signs, world.signs)
        for key, value in score.items():
            if key != "per_sign":
                self.report(key, value)
        if not self._truth:
            return
        along = {id(s) for s in signs_along_path(world, np.array(list(self._truth.values())))}
        per_true = score["per_sign"][:len(world.signs)]
        passed = [rec for sign, rec in zip(world.signs, per_true) if id(sign) in along]
        self.report("signs_along_path", len(passed))
        self.report("found_along_path", sum(r["status"] != "missed" for r in passed))
        self.report("read_exactly_along_path", sum(r["status"] == "read" for r in passed))
        truth_at = self._truth
        placed = copy.deepcopy(self.signs)
        placed.replace_poses(lambda tick, pose: truth_at.get(tick, pose))
        on_truth = score_signs(placed.signs(min_confidence=self.p.min_confidence), world.signs)
        self.report("position_error_mean_true_pose", on_truth["position_error_mean"])
        self.report("position_error_max_true_pose", on_truth["position_error_max"])
