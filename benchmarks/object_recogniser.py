"""Object recogniser: recognition rate, false positives and cost per frame on sampled views.

Two sets of views, rendered by ``sim2d.camera.render`` (seeded, deterministic):

* *recognition*: each catalogue object alone in a hall, 1.5-4 m from the
  camera, 0-15 deg off the optical axis, seen 0-40 deg off its front, the
  camera tilted to centre it and zoomed so that its smaller side is 70 px
  (at most 4x), as a camera head would frame it;
* *false-positive hunt*: wall-following poses in the office and hospital
  worlds with their objects removed, panning at random in [-100, 100] deg,
  tilt 0-25 deg, zoom 1-3 (the sign detector benchmark's views): every
  recognition there is false.

The reference cost is the rendering of one frame in the same run, so the
ratio says how much a recognised frame adds to a simulated camera tick.
Targets: recognition >= 0.95, 0 false positives, range error <= 20 %.
"""
from __future__ import annotations

import argparse
import math
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from blocks.signs.types import CameraModel  # noqa: E402
from results_io import write_results  # noqa: E402
from semantic.objects import default_catalogue  # noqa: E402
from semantic.recognise import ObjectRecogniser  # noqa: E402
from sim2d.camera import CameraSpec, camera_pose, render  # noqa: E402
from sim2d.world import make_world  # noqa: E402

RESULTS_JSON = Path(__file__).resolve().parent / "results" / "object_recogniser.json"
MIN_RATE = 0.95
MAX_FP = 0
HALL = [[-3, -8, 10, -8], [10, -8, 10, 8], [10, 8, -3, 8], [-3, 8, -3, -8]]


@dataclass(frozen=True)
class _Thing:
    label: str
    x: float
    y: float
    facing: float | None = None


def _time(fn, *args):
    t0 = time.perf_counter()
    out = fn(*args)
    return out, time.perf_counter() - t0


def measure(per_object: int = 12, fp_frames: int = 200, seed: int = 0) -> dict:
    spec = CameraSpec()
    rec = ObjectRecogniser()
    cat = default_catalogue()
    f1 = (spec.width / 2) / math.tan(spec.hfov / 2)
    rng = np.random.default_rng(seed)
    render_s, rec_times = 0.0, []
    hits = views = wrong = 0
    range_err, bearing_err, misses = [], [], []
    for entry in cat.entries:
        for _ in range(per_object):
            d = float(rng.uniform(1.5, 4.0))
            b = math.radians(float(rng.uniform(-15, 15)))
            view = float(rng.uniform(0, 40)) * (1 if rng.random() < 0.5 else -1)
            facing = math.pi + b + math.radians(view)
            world = make_world(HALL)
            world.objects = [_Thing(entry.label, d * math.cos(b), d * math.sin(b), facing)]
            tilt = max(-0.5, min(0.5, math.atan2(entry.elevation + entry.height / 2
                                                 - spec.mount_z, d)))
            zoom = min(4.0, max(1.0, 70.0 / (f1 * min(entry.width, entry.height) / d)))
            img, dt = _time(render, world, (0.0, 0.0, 0.0), tilt, zoom, spec,
                            np.random.default_rng(int(rng.integers(2**31))))
            render_s += dt
            model = CameraModel.of(spec.width, spec.height, spec.hfov, zoom, tilt)
            found, dt = _time(rec.recognise, img, model)
            rec_times.append(dt)
            views += 1
            right = [s for s in found if s.label == entry.label]
            wrong += len(found) - len(right)
            if right:
                hits += 1
                range_err.append(abs(right[0].range / d - 1))
                bearing_err.append(abs(math.degrees(right[0].bearing - b)))
            else:
                misses.append({"label": entry.label, "distance": round(d, 2),
                               "view_deg": round(view, 1)})
    from sign_detector import sample_views
    fp, fp_views = 0, []
    n_fp = 0
    for v in sample_views(fp_frames, seed, aimed=0.0, spec=spec):
        world = v["world"]
        world.objects = []
        cam = camera_pose(v["robot_pose"], spec, v["pan"])
        img, dt = _time(render, world, cam, v["tilt"], v["zoom"], spec,
                        np.random.default_rng(v["seed"]))
        render_s += dt
        model = CameraModel.of(spec.width, spec.height, spec.hfov, v["zoom"], v["tilt"])
        found, dt = _time(rec.recognise, img, model)
        rec_times.append(dt)
        n_fp += 1
        if found:
            fp += len(found)
            fp_views.append({"world": v["world_name"], "labels": [s.label for s in found]})
    frames = views + n_fp
    rec_s = float(np.sum(rec_times))
    return {
        "objects": len(cat), "recognition_views": views, "recognised": hits,
        "recognition_rate": round(hits / max(views, 1), 4),
        "wrong_label_in_recognition_views": wrong,
        "range_error_mean": round(float(np.mean(range_err)), 4) if range_err else None,
        "range_error_max": round(float(np.max(range_err)), 4) if range_err else None,
        "bearing_error_max_deg": round(float(np.max(bearing_err)), 3) if bearing_err else None,
        "false_positive_views": n_fp, "false_positives": fp,
        "recognise_ms_per_frame": round(1000 * rec_s / frames, 3),
        "recognise_ms_p95": round(1000 * float(np.percentile(rec_times, 95)), 3),
        "render_ms_per_frame": round(1000 * render_s / frames, 3),
        "recognise_x_render": round(rec_s / render_s, 3) if render_s > 0 else None,
        "feature": rec.params.feature, "seed": seed,
        "misses": misses[:20], "false_positive_examples": fp_views[:20],
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0])
    parser.add_argument("--quick", action="store_true", help="3 views per object, 40 bare views")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--json", type=Path, nargs="?", const=RESULTS_JSON, default=RESULTS_JSON)
    args = parser.parse_args(argv)
    r = measure(3 if args.quick else 12, 40 if args.quick else 200, args.seed)
    print(f"object recogniser ({r['feature']}): {r['objects']} catalogue objects, seed {args.seed}")
    print(f"reference: rendering one frame: {r['render_ms_per_frame']:.2f} ms\n")
    rows = [("recognition views", r["recognition_views"]),
            ("recognition rate", r["recognition_rate"]),
            ("wrong labels in those views", r["wrong_label_in_recognition_views"]),
            ("range error mean / max", f"{r['range_error_mean']} / {r['range_error_max']}"),
            ("bearing error max (deg)", r["bearing_error_max_deg"]),
            ("bare views (no objects)", r["false_positive_views"]),
            ("false positives", r["false_positives"]),
            ("recogniser ms per frame (mean)", r["recognise_ms_per_frame"]),
            ("recogniser ms per frame (p95)", r["recognise_ms_p95"]),
            ("recogniser / render", r["recognise_x_render"])]
    width = max(len(k) for k, _ in rows)
    for k, v in rows:
        print(f"{k:>{width}}  {v}")
    checks = [("recognition", r["recognition_rate"] >= MIN_RATE),
              ("false positives", r["false_positives"] + r["wrong_label_in_recognition_views"]
               <= MAX_FP),
              ("range", (r["range_error_max"] or 1.0) <= 0.2)]
    print()
    for name, ok in checks:
        print(f"{'PASS' if ok else 'MISS'} {name}")
    write_results(args.json, r)
    return 0 if args.quick or all(ok for _, ok in checks) else 1


if __name__ == "__main__":
    sys.exit(main())
