"""Object recogniser's early reject: does it ever rule out a frame the recogniser would accept, and what does it save?

Frames: the object recogniser benchmark's views (each catalogue object alone
in a hall, framed as a camera head would: "object views"; and wall-following
views of the office and hospital worlds with their objects: "world views",
which are more like a run's frames). Each frame goes
through the recogniser with and without the early reject
(:mod:`semantic.object_gate`), interleaved, and the two lists of recognitions
must be identical. For the frames with a recognition it reports the smallest
value of each quantity the gate tests next to the gate's threshold (the
margins), and the cost per frame of both.

``--runs`` also runs ``graphs/semantic_mapping.yaml`` on the office and
hospital worlds with and without the early reject (``--set
objects.early_reject=false``, ~6 minutes) and compares run.json's
``metrics.objects`` (objects, labels, merged positions, true and false
recognitions).

Targets: 0 frames whose recognitions differ; the early-reject runs' objects
metrics equal to the plain runs'.
"""
from __future__ import annotations

import argparse
import json
import math
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import cv2
import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from blocks.signs.types import CameraModel  # noqa: E402
from results_io import write_results  # noqa: E402
from semantic.objects import default_catalogue  # noqa: E402
from semantic.recognise import ObjectRecogniser, RecogniserParams  # noqa: E402
from sim2d.camera import CameraSpec, camera_pose, render  # noqa: E402
from sim2d.world import make_world  # noqa: E402

RESULTS_JSON = Path(__file__).resolve().parent / "results" / "object_gate.json"
HALL = [[-3, -8, 10, -8], [10, -8, 10, 8], [10, 8, -3, 8], [-3, 8, -3, -8]]
OBJECT_KEYS = ("objects", "objects_by_label", "merged", "true_positives", "false_positives",
               "missed")


class _Thing:
    def __init__(self, label: str, x: float, y: float, facing: float) -> None:
        self.label, self.x, self.y, self.facing = label, x, y, facing


def frames(per_object: int, world_views: int, seed: int, spec: CameraSpec):
    """(kind, image, CameraModel): catalogue objects in a hall ("object"), then world views."""
    rng = np.random.default_rng(seed)
    f1 = (spec.width / 2) / math.tan(spec.hfov / 2)
    for entry in default_catalogue().entries:
        for _ in range(per_object):
            d = float(rng.uniform(1.5, 4.0))
            b = math.radians(float(rng.uniform(-15, 15)))
            view = float(rng.uniform(0, 40)) * (1 if rng.random() < 0.5 else -1)
            world = make_world(HALL)
            world.objects = [_Thing(entry.label, d * math.cos(b), d * math.sin(b),
                                    math.pi + b + math.radians(view))]
            tilt = max(-0.5, min(0.5, math.atan2(entry.elevation + entry.height / 2
                                                 - spec.mount_z, d)))
            zoom = min(4.0, max(1.0, 70.0 / (f1 * min(entry.width, entry.height) / d)))
            img = render(world, (0.0, 0.0, 0.0), tilt, zoom, spec,
                         np.random.default_rng(int(rng.integers(2**31))))
            yield "object", img, CameraModel.of(spec.width, spec.height, spec.hfov, zoom, tilt)
    from sign_detector import sample_views
    for v in sample_views(world_views, seed, aimed=0.0, spec=spec):
        cam = camera_pose(v["robot_pose"], spec, v["pan"])
        img = render(v["world"], cam, v["tilt"], v["zoom"], spec, np.random.default_rng(v["seed"]))
        yield "world", img, CameraModel.of(spec.width, spec.height, spec.hfov, v["zoom"],
                                           v["tilt"])


def _same(a: list, b: list) -> bool:
    return len(a) == len(b) and all(
        x.label == y.label and x.bbox == y.bbox and np.array_equal(x.corners, y.corners)
        and (x.inliers, x.score, x.bearing, x.range) == (y.inliers, y.score, y.bearing, y.range)
        for x, y in zip(a, b))


def measure(per_object: int = 12, world_views: int = 300, seed: int = 0) -> dict:
    spec = CameraSpec()
    plain = ObjectRecogniser(params=RecogniserParams(early_reject=False))
    gated = ObjectRecogniser()
    gate = gated.gate
    times = {kind: [0, 0.0, 0.0] for kind in ("object", "world")}  # frames, plain s, gated s
    n = differ = recognised = 0
    margins: dict[str, float] = {"corners": math.inf, "region_corners": math.inf,
                                 "region_cells": math.inf, "votes": math.inf}
    for kind, img, model in frames(per_object, world_views, seed, spec):
        t0 = time.perf_counter()
        a = plain.recognise(img, model)
        t1 = time.perf_counter()
        b = gated.recognise(img, model)
        t2 = time.perf_counter()
        times[kind][0] += 1
        times[kind][1] += t1 - t0
        times[kind][2] += t2 - t1
        n += 1
        differ += not _same(a, b)
        if a:
            recognised += 1
            e = gate.evidence(cv2.cvtColor(img, cv2.COLOR_BGR2GRAY))
            best = e.regions[0] if e.regions else None
            for key, value in (("corners", e.corners),
                               ("region_corners", best.corners if best else 0),
                               ("region_cells", max((r.cells for r in e.regions), default=0)),
                               ("votes", max(e.votes, default=0))):
                margins[key] = min(margins[key], value)
    thresholds = {"corners": gate.min_corners, "region_corners": gate.min_inliers,
                  "region_cells": gate.params.min_cells, "votes": gate.min_votes}
    return {
        "frames": n, "frames_with_recognitions": recognised, "frames_that_differ": differ,
        "gate_counts": dict(gate.counts),
        "smallest_on_recognised_frames": {k: (int(v) if v != math.inf else None)
                                          for k, v in margins.items()},
        "gate_thresholds": thresholds,
        "ms_per_frame": {kind: {"frames": k, "plain": round(1000 * a / max(k, 1), 3),
                                "early_reject": round(1000 * b / max(k, 1), 3)}
                         for kind, (k, a, b) in times.items()},
        "seed": seed,
    }


def compare_runs(worlds: tuple[str, ...] = ("office", "hospital")) -> dict:
    """Run the main graph with and without the early reject; compare metrics.objects."""
    out: dict[str, dict] = {}
    with tempfile.TemporaryDirectory() as tmp:
        for world in worlds:
            metrics = {}
            for name, extra in (("early_reject", []),
                                ("plain", ["--set", "objects.early_reject=false"])):
                d = Path(tmp) / f"{world}_{name}"
                subprocess.run([sys.executable, "-m", "blocks.cli", "run",
                                str(ROOT / "graphs/semantic_mapping.yaml"), "--world", world,
                                "--out", str(d), "-q", *extra], check=True, cwd=ROOT,
                               stdout=subprocess.DEVNULL)
                run = json.loads((d / "run.json").read_text())
                objects = run["metrics"]["objects"]
                node = next(p for p in run["profile"] if p["node"] == "objects")
                metrics[name] = {"objects": {k: objects.get(k) for k in OBJECT_KEYS},
                                 "block_s": node["total_s"],
                                 "ms_per_frame": objects.get("ms_per_frame"),
                                 "frames_rejected_early": objects.get("frames_rejected_early")}
            out[world] = {**metrics, "same_objects": metrics["early_reject"]["objects"]
                          == metrics["plain"]["objects"]}
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0])
    parser.add_argument("--quick", action="store_true", help="3 views per object, 40 world views")
    parser.add_argument("--runs", action="store_true",
                        help="also run the main graph on office and hospital, with and without")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--json", type=Path, nargs="?", const=RESULTS_JSON, default=RESULTS_JSON)
    args = parser.parse_args(argv)
    r = measure(3 if args.quick else 12, 40 if args.quick else 300, args.seed)
    if args.runs:
        r["runs"] = compare_runs()
    print(f"object recogniser early reject: {r['frames']} frames, "
          f"{r['frames_with_recognitions']} with recognitions, seed {args.seed}")
    print(f"frames whose recognitions differ: {r['frames_that_differ']}")
    print(f"gate outcomes: {r['gate_counts']}")
    for key, low in r["smallest_on_recognised_frames"].items():
        print(f"  {key:>15}: smallest on recognised frames {low}, gate needs {r['gate_thresholds'][key]}")
    for kind, t in r["ms_per_frame"].items():
        print(f"ms per {kind} view ({t['frames']}): {t['plain']} without, {t['early_reject']} with "
              "the early reject")
    ok = r["frames_that_differ"] == 0
    for world, run in r.get("runs", {}).items():
        print(f"{world}: objects metrics {'equal' if run['same_objects'] else 'DIFFER'}; block "
              f"{run['plain']['block_s']} s -> {run['early_reject']['block_s']} s")
        ok = ok and run["same_objects"]
    print(f"\n{'PASS' if ok else 'MISS'} same recognitions")
    write_results(args.json, r)
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
