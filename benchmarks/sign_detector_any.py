"""Sign detectors on generated buildings: the white-plate detector against plates of any look.

Views are sampled as in ``benchmarks/sign_detector.py`` (wall-following
poses, tilt 0-25 deg, zoom 1-3), but on generated buildings, whose plates
vary in size, colours, polarity and font (``sim2d/worlds/looks.py``): a share
``aimed`` of the views stands within 10 m in front of a sign and pans to it,
the rest pan at random. The detectors see the same frames:
``detect_plates`` (the white-plate detector), ``detect_any_plates``
(``blocks/signs/detect_any.py``) and ``any+inside``, the latter with plates
inside other edges found too (``AnyLookParams.inside_edges``). Scored with
``match_detections``: recall
over plates at least 6 px tall and 60 % visible, and the strict recall over
those at least 12 px tall seen within 70 deg of head-on.

Families: ``--worlds gen:any:0-39`` (the default) is where the any-look
detector was tuned; ``--worlds gen:any:1000-1059`` is the evaluation family,
which no tuning may look at. Also run it on the shipped worlds' views:
``python benchmarks/sign_detector.py`` (the white detector's own benchmark).

Usage::

    .venv/bin/python benchmarks/sign_detector_any.py [--worlds gen:any:0-39] [--per-world 5]
"""
from __future__ import annotations

import argparse
import functools
import math
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from sign_detector import STRICT, _aimed_pan, _wall_pose  # noqa: E402

from blocks.signs.detect import detect_plates, match_detections  # noqa: E402
from blocks.signs.detect_any import AnyLookParams, detect_any_plates  # noqa: E402
from blocks.signs.types import CameraModel  # noqa: E402
from sim2d.camera import CameraSpec, camera_pose, render, visible_signs  # noqa: E402
from sim2d.world import load_world  # noqa: E402
from sim2d.worlds.family import expand_worlds, generated_world  # noqa: E402

DETECTORS = {"white": detect_plates, "any": detect_any_plates,
             # the any-look detector with plates inside other edges found too (docs/signs.md)
             "any+inside": functools.partial(detect_any_plates,
                                             any_params=AnyLookParams(inside_edges=True))}


def sample_views(worlds: str, per_world: int, seed: int = 0, aimed: float = 0.7) -> list[dict]:
    """``per_world`` deterministic views in each building of the ``gen:`` family ``worlds``."""
    spec = CameraSpec()
    rng = np.random.default_rng(seed)
    views = []
    for ref in expand_worlds(worlds):
        world = load_world(generated_world(ref.spec))
        for _ in range(per_world):
            for _ in range(200):
                if rng.random() < aimed and world.signs:
                    sign = world.signs[int(rng.integers(len(world.signs)))]
                    pose = _wall_pose(world, rng, near=(sign.x, sign.y, 10.0))
                    pan = None if pose is None else _aimed_pan(world, pose, spec, rng)
                else:
                    pose, pan = _wall_pose(world, rng), float(rng.uniform(-1.75, 1.75))
                if pose is not None and pan is not None:
                    break
            else:
                continue
            views.append({"world": world, "name": ref.name, "pose": pose, "pan": pan,
                          "tilt": float(rng.uniform(0.0, math.radians(25))),
                          "zoom": float(rng.uniform(1.0, 3.0)), "seed": int(rng.integers(2**31))})
    return views


def measure(views: list[dict]) -> dict:
    """Counts, recalls and ms per frame of each detector on the same rendered frames."""
    spec = CameraSpec()
    counts = {name: np.zeros(5, np.int64) for name in DETECTORS}
    per_world: dict[str, dict[str, np.ndarray]] = {}  # building -> detector -> (tp, fn)
    seconds = dict.fromkeys(DETECTORS, 0.0)
    for view in views:
        cam = camera_pose(view["pose"], spec, view["pan"])
        img = render(view["world"], cam, view["tilt"], view["zoom"], spec,
                     np.random.default_rng(view["seed"]))
        model = CameraModel.of(spec.width, spec.height, spec.hfov, view["zoom"], view["tilt"])
        truth = visible_signs(view["world"], cam, view["tilt"], view["zoom"], spec)
        for name, detect in DETECTORS.items():
            start = time.perf_counter()
            dets = detect(img, model)
            seconds[name] += time.perf_counter() - start
            tp, fp, fn, _ = match_detections(dets, truth)
            s_tp, _, s_fn, _ = match_detections(dets, truth, **STRICT)
            counts[name] += (tp, fp, fn, s_tp, s_fn)
            per_world.setdefault(view["name"], {n: np.zeros(2, np.int64) for n in DETECTORS})
            per_world[view["name"]][name] += (tp, fn)
    out = {"views": len(views)}
    for name, (tp, fp, fn, s_tp, s_fn) in counts.items():
        out[name] = {"true_positives": int(tp), "false_positives": int(fp),
                     "false_negatives": int(fn),
                     "recall": round(tp / (tp + fn), 3) if tp + fn else None,
                     "recall_strict": round(s_tp / (s_tp + s_fn), 3) if s_tp + s_fn else None,
                     "ms_per_frame": round(1000 * seconds[name] / max(len(views), 1), 3)}
        # per building with at least 3 detectable plates in its views: median and worst recall
        recalls = sorted((tp_fn[name][0] / tp_fn[name].sum(), building)
                         for building, tp_fn in per_world.items() if tp_fn[name].sum() >= 3)
        if recalls:
            out[name]["building_recall_median"] = round(float(np.median([r for r, _ in recalls])), 3)
            out[name]["building_recall_worst"] = [round(float(recalls[0][0]), 3), recalls[0][1]]
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0])
    parser.add_argument("--worlds", default="gen:any:0-39", help="a gen: family (default: %(default)s)")
    parser.add_argument("--per-world", type=int, default=5, help="views per building")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args(argv)
    result = measure(sample_views(args.worlds, args.per_world, args.seed))
    print(f"{result['views']} views of {args.worlds}")
    print(f"{'detector':11s} {'TP':>5s} {'FP':>5s} {'FN':>5s} {'recall':>7s} {'strict':>7s} {'ms':>7s}"
          "  per building: median recall, worst")
    for name in DETECTORS:
        r = result[name]
        print(f"{name:11s} {r['true_positives']:5d} {r['false_positives']:5d} "
              f"{r['false_negatives']:5d} {r['recall']!s:>7s} {r['recall_strict']!s:>7s} "
              f"{r['ms_per_frame']:7.3f}  {r.get('building_recall_median')!s:>6s}, "
              f"{r.get('building_recall_worst')}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
