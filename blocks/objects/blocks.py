"""The object recogniser block: a thin adapter over :mod:`semantic.recognise`.

It runs on camera frames (trigger it with the camera's ``fresh``), places
each recognised object on the map from the robot's pose and the head's pan,
and keeps a merged list of the objects seen (same label within
``merge_radius`` is one object). With the camera's ground truth
``objects_visible`` connected it scores the recognitions into run.json.
"""
from __future__ import annotations

import math
from typing import Any

import numpy as np

from blocks.core import Block, Param, Port, block


@block("objects.recognizer", category="objects")
class Recognizer(Block):
    """Recognises catalogue objects (shredder, printer, ...) in camera frames and places them.

    A cheap early reject (``early_reject``) first rules out the frames that
    cannot show an object (blank walls, corridors, most door signs: over 90 %
    of the frames of the office and hospital runs); the frames it lets through
    give the same recognitions as without it.

    Output ``objects``: this frame's observations, a list of dicts {label, x, y
    (map frame, from ``pose``), confidence, tick, bearing (rad), range (m)}.
    With the offline map's handle on ``map``, the objects are re-placed at the
    end from the drift-corrected poses, as the signs are; ``current()`` then
    gives those.  At the end it reports the merged objects (label, position, count) and,
    with ``visible`` connected, true/false recognitions, precision and
    recall; it saves up to ``keep_frames`` annotated frames to ``DIR/objects/``,
    and how many examined frames the early reject ruled out (``frames_rejected_early``).
    """

    inputs = {
        "image": Port(kind="image", dtype="uint8", shape=("H", "W", 3), frame="camera",
                      doc="BGR frame"),
        "camera": Port.message(doc="CameraModel of the frame (signs.detector's camera output)"),
        "pose": Port.array("float64", (3,), unit="m,m,rad",
                           doc="the robot's pose in the map frame (odometry)"),
        "pan": Port.scalar("float64", unit="rad", doc="the head's pan for this frame"),
        "visible": Port.message(required=False,
                                doc="ground truth objects in view (scoring only)"),
        "map": Port(kind="handle", required=False, default=None,
                    doc="the offline map: at the end, objects are re-placed on its "
                        "drift-corrected path (corrected_pose(tick, pose))"),
    }
    outputs = {"objects": Port.message(doc="list of observations {label, x, y, confidence, "
                                           "tick, bearing, range} of this frame"),
               "count": Port.scalar("int64", doc="objects recognised in this frame"),
               "seen": Port(kind="handle", doc="this block: current() gives the objects seen "
                                               "so far (merged), version counts the updates")}
    params = {
        "catalogue": Param(str, "", "object catalogue YAML (empty: the packaged one)"),
        "robot": Param(str, "atrv_mini", "robot model or robot YAML (camera mount)"),
        "min_inliers": Param(int, 10, "fewer feature matches is no recognition", min=4),
        "every_nth": Param(int, 1, "look at every n-th frame only (bounds the cost)", min=1),
        "merge_radius": Param(float, 1.0, "sightings of one label closer than this are one "
                                          "object", unit="m", min=0.0),
        "keep_frames": Param(int, 10, "annotated frames saved to DIR/objects/", min=0),
        "early_reject": Param(bool, True, "rule out frames that cannot show an object before "
                                          "SIFT on the whole frame (same recognitions)"),
    }

    def setup(self) -> None:
        from dataclasses import replace

        from semantic.objects import load_catalogue
        from semantic.recognise import ObjectRecogniser, RecogniserParams
        from sim2d.blocks import camera_spec_of
        from sim2d.robot import load_robot
        catalogue = load_catalogue(self.p.catalogue or None)
        params = replace(RecogniserParams(), min_inliers=int(self.p.min_inliers),
                         early_reject=bool(self.p.early_reject))
        self.recogniser = ObjectRecogniser(catalogue, params)
        spec, _ = camera_spec_of(load_robot(self.p.robot))
        self._mount = (spec.mount_x, spec.mount_y)

    def reset(self) -> None:
        self._frames = self._looked = 0
        self._merged: list[dict[str, Any]] = []
        self._sightings: list[tuple[int, np.ndarray, float, Any]] = []  # tick, pose, pan, s
        self._map: Any = None
        self._tp = self._fp = self._fn = 0
        self._saved = 0
        self._ms: list[float] = []
        self.version = 0
        if self.recogniser.gate is not None:
            self.recogniser.gate.reset_counts()

    def current(self) -> list[dict[str, Any]]:
        """The objects seen so far, merged: {label, x, y, count, confidence, first_tick}."""
        return self.merged

    def step(self, image: np.ndarray, camera: Any, pose: np.ndarray, pan: float,
             visible: list | None = None, map: Any = None) -> dict[str, Any]:  # noqa: A002
        import time

        from semantic.recognise import match_sightings, object_world_position
        if map is not None:
            self._map = map
        self._frames += 1
        if camera is None or (self._frames - 1) % self.p.every_nth:
            return {"objects": [], "count": 0, "seen": self}
        self._looked += 1
        t0 = time.perf_counter()
        sightings = self.recogniser.recognise(image, camera)
        self._ms.append(1000.0 * (time.perf_counter() - t0))
        observations = []
        for s in sightings:
            x, y = object_world_position(s, pose, float(pan), self._mount)
            obs = {"label": s.label, "x": x, "y": y, "confidence": s.score,
                   "tick": self.ctx.tick, "bearing": s.bearing, "range": s.range}
            observations.append(obs)
            self._sightings.append((self.ctx.tick, np.array(pose[:3], dtype=np.float64),
                                    float(pan), s))
            self._merge(obs)
            self.version += 1
        if visible is not None:
            m = match_sightings(sightings, [v for v in visible if "label" in v])
            self._tp += m.true_positives
            self._fp += m.false_positives
            self._fn += m.false_negatives
        if sightings and self._saved < self.p.keep_frames and self.ctx.out_dir is not None:
            self._save(image, sightings)
        return {"objects": observations, "count": len(observations), "seen": self}

    def _merge(self, obs: dict[str, Any]) -> None:
        """Fold an observation into the merged objects (running mean position, count)."""
        for m in self._merged:
            if m["label"] == obs["label"] and math.hypot(m["x"] - obs["x"],
                                                         m["y"] - obs["y"]) <= self.p.merge_radius:
                n = m["count"]
                m["x"] = (m["x"] * n + obs["x"]) / (n + 1)
                m["y"] = (m["y"] * n + obs["y"]) / (n + 1)
                m["count"] = n + 1
                m["confidence"] = max(m["confidence"], obs["confidence"])
                return
        self._merged.append({"label": obs["label"], "x": obs["x"], "y": obs["y"], "count": 1,
                             "confidence": obs["confidence"], "first_tick": obs["tick"]})

    def _save(self, image: np.ndarray, sightings: list) -> None:
        import cv2

        from blocks.core.atomic import atomic_write_bytes
        marked = image.copy()
        for s in sightings:
            pts = np.round(s.corners).astype(np.int32)
            cv2.polylines(marked, [pts], True, (0, 255, 0), 1, cv2.LINE_AA)
            x0, y0 = s.bbox[0], max(8, s.bbox[1] - 2)
            cv2.putText(marked, f"{s.label} {s.range:.1f}m", (x0, y0), cv2.FONT_HERSHEY_SIMPLEX,
                        0.35, (0, 255, 0), 1, cv2.LINE_AA)
        ok, png = cv2.imencode(".png", marked)
        if ok:
            labels = "_".join(sorted({s.label for s in sightings}))
            atomic_write_bytes(self.output_path(f"objects/tick{self.ctx.tick:06d}_{labels}.png"),
                               png.tobytes())
            self._saved += 1

    @property
    def merged(self) -> list[dict[str, Any]]:
        """The objects seen so far (label, x, y, count, confidence, first_tick)."""
        return [dict(m) for m in self._merged]

    def _replace_on_corrected_path(self) -> None:
        """Re-place every sighting from its drift-corrected pose and merge them again."""
        from semantic.recognise import object_world_position
        corrected = getattr(self._map, "corrected_pose", None)
        if corrected is None or not self._sightings:
            return
        self._merged = []
        for tick, pose, pan, s in self._sightings:
            x, y = object_world_position(s, corrected(tick, pose), pan, self._mount)
            self._merge({"label": s.label, "x": x, "y": y, "confidence": s.score, "tick": tick})
        self.version += 1

    def finish(self) -> None:
        self._replace_on_corrected_path()
        self.report("frames", self._frames)
        self.report("frames_examined", self._looked)
        gate = self.recogniser.gate
        if gate is not None:
            self.report("frames_rejected_early",
                        sum(n for k, n in gate.counts.items() if k != "passed"))
        self.report("objects", len(self._merged))
        self.report("objects_by_label", {m["label"]: sum(1 for k in self._merged
                                                         if k["label"] == m["label"])
                                         for m in self._merged})
        self.report("merged", [{"label": m["label"], "x": round(m["x"], 3),
                                "y": round(m["y"], 3), "count": m["count"]}
                               for m in self._merged])
        if self._ms:
            self.report("ms_per_frame", round(float(np.mean(self._ms)), 2))
        if self._tp + self._fp + self._fn:
            self.report("true_positives", self._tp)
            self.report("false_positives", self._fp)
            self.report("missed", self._fn)
            self.report("precision", round(self._tp / max(1, self._tp + self._fp), 4))
            self.report("recall", round(self._tp / max(1, self._tp + self._fn), 4))
